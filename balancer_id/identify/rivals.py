"""Rival explanations of a trusted fit: does a model that fits as well move a value? (issue 31)

A fit's interval assumes its model. An effect the model lacks can be mimicked by the
model's own parameters: at steady speed a friction ``f`` slows the load as a viscosity
that is larger at small thrusts does (``v = (h - f) / D`` against ``v = h / (D0 exp(-A
|h|))``), so a friction below the noise comes out as ``D0`` and ``A`` too large, with a
residual as white as the noise. A speed limit the trials reach bends ``A`` the other way;
a dead time lengthens ``T_a``.

So each trusted fit is refitted once per *rival*: the model with one library effect it
lacks (:func:`rival_effects`), warm-started at the fit with the effect switched on at a
strength the data could hide (:func:`rival_start`). A rival is *as well supported* when
its BIC, counted on the residual's independent samples (``n / tau``, as the standard
errors are), is no more than :data:`RIVAL_BIC` above the fit's: the data prefer the fit
by less than Kass and Raftery's "bare mention" (odds under e to 1), or prefer the rival;
and so again without the trial it gains most on (an error shared by one whole trial, its
thrust level or its zero, is no noise the correlation time sees). A rival whose one-step
prediction (:func:`predicted_gap`) is far from support is not refitted.
A trusted parameter that such a rival moves outside its 95 % interval is no longer
trusted: its value depends on whether the effect is present, and the range it spans under
the rivals is said. The others keep their trust. A rival that does not fit as well (the
data reject the effect, as on a clean log, where its BIC is about ``ln(n / tau)`` worse)
changes nothing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from balancer_id.errors import BalancerIdError
from balancer_id.identify.matching import MatchResult, match_trials
from balancer_id.model.effect import Effect
from balancer_id.model.spec import Model, parse_model
from balancer_id.notes import Note

__all__ = ["RIVAL_BIC", "Rival", "check_rivals", "rival_effects", "rival_start"]

#: A rival whose BIC (on independent samples) is at most this much above the fit's is as
#: well supported: the data prefer the fit by odds under e to 1 (Kass and Raftery's "not
#: worth more than a bare mention"). On a log without the effect its BIC is about
#: ``ln(n / tau)`` (8-12) worse; docs/DECISIONS.md.
RIVAL_BIC = 2.0
#: A speed limit starts at this share of the fastest the fit's model goes: it clips the
#: peaks only, so one Gauss-Newton step from there says which way the data pull it.
SPEED_SHARE = 0.98
#: Model evaluations of one rival's refit (it starts at the fit: a few steps suffice).
RIVAL_NFEV = 150
#: Effects tried as rivals whose kernel needs its own compilation are tried only on models
#: whose own such effects are among these (the paper's viscosities): their rival kernels
#: are the ones the diagnosis's candidates compile anyway.
PAPER_STRUCTURAL = frozenset({"viscous", "variable_viscosity"})


@dataclass(frozen=True)
class Rival:
    """A rival explanation that fits as well as the fit and moves a trusted value.

    Attributes
    ----------
    effect : str
        The library effect added (``karnopp``).
    summary : str
        What it is, in words.
    delta_bic : float
        Its BIC on independent samples minus the fit's (negative: the rival fits better),
        the larger of it over all trials and without the trial the rival gains most on.
    values : dict of str to float
        Its fitted values.
    ranges : dict of str to (float, float)
        Each moved parameter's range under the fit and its rivals (95 %).
    record : str or None
        The step trial that tells the fit from the rival, in words.
    """

    effect: str
    summary: str
    delta_bic: float
    values: Mapping[str, float]
    ranges: Mapping[str, tuple[float, float]]
    record: str | None = None

    @property
    def label(self) -> str:
        """``+karnopp``."""
        return f"+{self.effect}"


def _structural(cls: type[Effect]) -> bool:
    from balancer_id.simulation.kernel_source import _is_structural

    return _is_structural(cls)


def rival_effects(model: Model) -> list[type[Effect]]:
    """The library effects a fit of ``model`` is checked against.

    Every built-in effect the model lacks that can be added to it (no effect it excludes
    is present), needs no robot reference and adds at least one parameter. Effects whose
    kernel is compiled apart (a friction, a speed limit: :data:`PAPER_STRUCTURAL`) only
    when the model's own such effects are the paper's viscosities: a model with a user's
    effect or a friction already chosen is left to ``diagnose``.

    Parameters
    ----------
    model : Model
        The fitted model.

    Returns
    -------
    list of type
        The rival effects, in registry order.
    """
    present = {e.name for e in model.effects}
    own_structural = {e.name for e in model.effects if _structural(e)} - {"base"}
    plain = own_structural <= PAPER_STRUCTURAL and all(
        model.registry.origin(e.name) == "built-in" for e in model.effects if e.name != "base"
    )
    out = []
    for effect in model.registry:
        if effect.name in present or effect.needs_reference_move():
            continue
        if model.registry.origin(effect.name) != "built-in":
            continue
        if any(n in present for n in effect.excludes) or not effect.parameters:
            continue
        if any(effect.name in e.excludes for e in model.effects):
            continue
        if _structural(effect) and not plain:
            continue
        out.append(effect)
    return out


def rival_start(match: MatchResult, model: Model, effect: type[Effect]) -> dict[str, float]:
    """Where a rival's refit starts: the fit's values, the effect on at a strength the
    data could hide.

    A force (``N``: a friction) at a tenth of the smallest thrust; a speed (``m/s``: a
    limit) at :data:`SPEED_SHARE` of the fastest the fit's model goes, so that it acts; a
    time (``s``: a delay) at two samples; any other at the effect's default. A drive lag the model
    lacks (``T_up`` over ``T_a``) starts at the fit's drive lag.

    Parameters
    ----------
    match : MatchResult
        The fit.
    model : Model
        The rival model (the fit's with ``effect``).
    effect : type
        The effect added.

    Returns
    -------
    dict of str to float
        Start values of every parameter of the rival model the fit has or the effect adds.
    """
    now = match.values()
    start = {k: v for k, v in now.items() if k in model.param_names}
    trials = match.data.trials
    thrusts = [abs(t.thrust_N) for t in trials if t.thrust_N]
    speed = float(np.nanmax(np.abs(match.data.packed.run(
        match.model, np.asarray(match.model.vector(now), float))[:, 1])))  # fmt: skip
    dt = float(np.median([1.0 / t.rate_hz for t in trials]))
    for p in effect.parameters:
        value = p.value
        if p.unit == "N" and thrusts:
            value = 0.1 * min(thrusts)
        elif p.unit == "m/s" and math.isfinite(speed) and speed > 0:
            value = SPEED_SHARE * speed
        elif p.unit == "s":
            value = match.model.drive_lag(now) if p.name in model.drive_lag_names else 2 * dt
        start[p.name] = float(min(max(value, p.min), p.max))
    return start


#: A rival is refitted only when one Gauss-Newton step from its start predicts a BIC gap
#: within this much more than :data:`RIVAL_BIC`: the step's quadratic model is rough
#: where the effect is far from linear (a limit, a friction's kink), so the margin is
#: wide; a rival the data reject by more (a clean log's: about ``ln(n / tau)``) costs one
#: simulation, not a refit.
SCREEN_MARGIN = 4.0
#: Rows simulated per block by the screen.
BLOCK_ROWS = 1 << 16


def _n_eff(match: MatchResult) -> float:
    """The fit's independent samples ``n / tau``."""
    return match.y.size / max(float(match.metrics.get("residual_tau", 1.0)), 1.0)


def predicted_gap(
    match: MatchResult, model: Model, start: Mapping[str, float], fixed: Mapping[str, float]
) -> float:
    """The BIC gap one bounded Gauss-Newton step from ``start`` predicts for a rival.

    One simulation of the rival model with its sensitivities at ``start`` gives the
    residual ``r`` and Jacobian ``J``; the step minimises ``|r + J d|^2`` with every
    parameter inside its bounds (:func:`scipy.optimize.lsq_linear`), and that minimum
    stands for the rival's residual sum of squares.

    Parameters
    ----------
    match : MatchResult
        The fit.
    model : Model
        The rival model.
    start : mapping
        Its start values (:func:`rival_start`).
    fixed : mapping
        Values held.

    Returns
    -------
    float
        The predicted BIC gap (rival minus fit, on independent samples); ``inf`` when the
        simulation fails.
    """
    from scipy.optimize import lsq_linear

    free = [
        i for i, p in enumerate(model.params)
        if p.name not in fixed and (p.name not in match.parameters or match.parameters[p.name].vary)
    ]  # fmt: skip
    values = {**{p.name: p.value for p in model.params}, **start, **fixed}
    pvec = np.asarray(model.vector(values), float)
    k = len(free)
    hess, grad, rss = np.zeros((k, k)), np.zeros(k), 0.0
    y = match.y
    with np.errstate(all="ignore"):
        for first, out, sens in match.data.packed.stream_sens(model, pvec, free, BLOCK_ROWS):
            r = out[:, 0] - y[first : first + out.shape[0]]
            if not (np.isfinite(r).all() and np.isfinite(sens).all()):
                return math.inf
            hess += sens.T @ sens
            grad += sens.T @ r
            rss += float(r @ r)
    scale = np.sqrt(np.maximum(np.diag(hess), 1e-300))
    h = hess / np.outer(scale, scale)
    w, v = np.linalg.eigh(h)
    keep = w > w.max() * 1e-12
    # |r + J d|^2 = rss + 2 g'd + d'Hd, as the least squares |R e - b|^2 (R'R = H, e = d*scale)
    root = (v[:, keep] * np.sqrt(w[keep])).T
    b = -(v[:, keep].T @ (grad / scale)) / np.sqrt(w[keep])
    lo = np.array([model.params[i].min for i in free]) - pvec[free]
    hi = np.array([model.params[i].max for i in free]) - pvec[free]
    step = lsq_linear(root, b, bounds=(lo * scale, hi * scale), method="bvls").x
    d = step / scale
    predicted = max(rss + 2 * float(grad @ d) + float(d @ hess @ d), 0.0)
    n_eff = _n_eff(match)
    rss0 = float(np.sum(match.residual**2))
    k0 = sum(p.vary for p in match.parameters.values())
    return float(
        n_eff * math.log(max(predicted, 1e-300) / max(rss0, 1e-300)) + (k - k0) * math.log(n_eff)
    )


def _gap(n_eff: float, rss0: float, rss1: float, extra: int) -> float:
    return float(n_eff * math.log(max(rss1, 1e-300) / max(rss0, 1e-300)) + extra * math.log(n_eff))


def _bic_gap(match: MatchResult, rival: MatchResult) -> float:
    """The rival's BIC minus the fit's, on the fit's independent samples ``n / tau``, and
    without the trial it gains most on (the larger of the two).

    An error shared by a whole trial (its thrust level read from a noisy force, its own
    zero) is no noise the correlation time sees; a rival that follows it gains on that
    trial alone. Support must hold without it (with three trials or more).
    """
    n_eff = _n_eff(match)
    k0 = sum(p.vary for p in match.parameters.values())
    extra = sum(p.vary for p in rival.parameters.values()) - k0
    r0, r1 = match.residual, rival.residual
    gap = _gap(n_eff, float(np.sum(r0**2)), float(np.sum(r1**2)), extra)
    slices = match.data.slices()
    if len(slices) < 3:
        return gap
    parts0 = np.array([float(np.sum(r0[sl] ** 2)) for sl in slices])
    parts1 = np.array([float(np.sum(r1[sl] ** 2)) for sl in slices])
    best = int(np.argmax(parts0 - parts1))
    keep = np.arange(len(slices)) != best
    share = float(sum(sl.stop - sl.start for k, sl in enumerate(slices) if keep[k])) / r0.size
    rest = _gap(n_eff * share, float(parts0[keep].sum()), float(parts1[keep].sum()), extra)
    return max(gap, rest)


def _refit(
    match: MatchResult, effect: type[Effect], fixed: Mapping[str, float]
) -> MatchResult | None:
    """The fit's model with ``effect``, refitted from :func:`rival_start` (None: failed)."""
    try:
        model = parse_model(f"{match.model.spec}+{effect.name}", match.model.registry)
        held = {k: v for k, v in fixed.items() if k in model.param_names}
        start = rival_start(match, model, effect)
        if predicted_gap(match, model, start, held) > RIVAL_BIC + SCREEN_MARGIN:
            return None  # the data reject it by more than the screen's margin
        rival = match_trials(
            model, match.data.trials, start=start, fixed=held, n_starts=1, max_nfev=RIVAL_NFEV
        )
    except (BalancerIdError, ValueError, FloatingPointError):
        return None
    if not rival.success or not np.isfinite(rival.metrics["rmse"]):
        return None
    return rival


def trusted_names(match: MatchResult) -> list[str]:
    """The fitted parameters nothing distrusts yet, with a finite 95 % interval.

    Parameters
    ----------
    match : MatchResult

    Returns
    -------
    list of str
    """
    return [
        name
        for name, p in match.parameters.items()
        if p.vary and not p.distrust and p.not_reached is None and p.ci95 is not None
        and all(math.isfinite(x) for x in p.ci95)
    ]  # fmt: skip


def _moved(
    match: MatchResult, rival: MatchResult, names: Sequence[str]
) -> dict[str, tuple[float, float]]:
    """Each of ``names`` the rival puts outside the fit's 95 % interval, with the range
    (the fit's interval joined with the rival's). A drive lag the rival replaces (an
    asymmetric lag's ``T_up``, ``T_down`` for ``T_a``) is moved where the 95 % interval
    of any of the rival's lags misses its interval: an up-then-down log read T_a 0.15 s,
    trusted, where the rival's lags were 0.59 and 1.63 s (truth 0.69 and 1.72)."""
    out = {}
    for name in names:
        lo, hi = match.parameters[name].ci95 or (math.nan, math.nan)
        if name not in rival.parameters:
            # a drive lag the rival replaces (T_a by T_up and T_down): its value holds
            # only where each of the rival's lags may lie in its interval (each of the
            # split lags is known less well than the one it replaces: its own interval)
            lags = [
                rival.parameters[n]
                for n in rival.model.drive_lag_names
                if n in rival.parameters and name in match.model.drive_lag_names
            ]
            spans = [lag.ci95 or (lag.value, lag.value) for lag in lags]
            if all(a <= hi and b >= lo for a, b in spans):
                continue
            ends = [x for x in (lo, hi, *(lag.value for lag in lags)) if math.isfinite(x)]
            out[name] = (min(ends), max(ends))
            continue
        r = rival.parameters[name]
        if lo <= r.value <= hi:
            continue
        ends = [lo, hi, r.value, *(r.ci95 or ())]
        ends = [x for x in ends if math.isfinite(x)]
        out[name] = (min(ends), max(ends))
    return out


def find_rivals(match: MatchResult, fixed: Mapping[str, float] | None = None) -> list[Rival]:
    """The rivals that fit as well as ``match`` and move one of its trusted values.

    Parameters
    ----------
    match : MatchResult
        The fit.
    fixed : mapping, optional
        Values the fit held (held in the rivals too).

    Returns
    -------
    list of Rival
        Best supported first (lowest BIC gap).
    """
    names = trusted_names(match)
    if not names or match.model.needs_reference_move:
        return []
    out = []
    for effect in rival_effects(match.model):
        rival = _refit(match, effect, fixed or {})
        if rival is None:
            continue
        gap = _bic_gap(match, rival)
        if gap > RIVAL_BIC:
            continue
        ranges = _moved(match, rival, names)
        if not ranges:
            continue
        from balancer_id.identify.separating import separating_trial

        out.append(
            Rival(
                effect.name,
                effect.summary,
                gap,
                dict(rival.values()),
                ranges,
                separating_trial(match, rival),
            )
        )
    return sorted(out, key=lambda r: r.delta_bic)


def _effect_values(rival: Rival, match: MatchResult) -> str:
    extra = {k: v for k, v in rival.values.items() if k not in match.parameters}
    return ", ".join(f"{k} = {v:.3g}" for k, v in extra.items())


def rival_note(rival: Rival, match: MatchResult) -> Note:
    """The ``fit.rival`` note: the rival, how well it fits, what it moves, what to record.

    Parameters
    ----------
    rival : Rival
    match : MatchResult
        The fit.

    Returns
    -------
    Note
        Severity ``error`` (the values it moves are not trusted); subject the effect.
    """
    bic = f"BIC {rival.delta_bic:+.1f} on independent samples, its best trial left out"
    how = (
        f"fits better ({bic})"
        if rival.delta_bic < 0
        else f"fits as well ({bic}, within {RIVAL_BIC:g})"
    )
    moved = "; ".join(f"{k} {lo:.3g} .. {hi:.3g}" for k, (lo, hi) in rival.ranges.items())
    text = (
        f"the model with {rival.effect} ({rival.summary}; {_effect_values(rival, match)}) "
        f"{how} and moves {', '.join(rival.ranges)} outside their 95 % intervals: under "
        f"the rivals {moved}, so those values are not trusted"
    )
    if rival.record:
        text += f"; to tell them apart, {rival.record}"
    return Note("fit.rival", text, subject=rival.effect, severity="error")


def check_rivals(match: MatchResult, fixed: Mapping[str, float] | None = None) -> list[Note]:
    """Check a fit's trusted values against its rivals and mark what they move.

    Each parameter a rival moves gets a reason in its
    :attr:`~balancer_id.identify.matching.ParameterEstimate.distrust` ("D0 depends on
    whether a karnopp friction is present: 0.041 .. 0.122 under the rivals"); the rivals
    are kept on the match (``match.rivals``) for the diagnosis.

    Parameters
    ----------
    match : MatchResult
        The fit (changed in place).
    fixed : mapping, optional
        Values the fit held.

    Returns
    -------
    list of Note
        One ``fit.rival`` note per rival that moves a value.
    """
    found = find_rivals(match, fixed)
    match.rivals = found
    notes = []
    for rival in found:
        for name, (lo, hi) in rival.ranges.items():
            match.parameters[name].distrust.append(
                f"{name} depends on whether {rival.effect} is present: {lo:.4g} .. {hi:.4g} "
                "under the rivals"
            )
        notes.append(rival_note(rival, match))
    return notes
