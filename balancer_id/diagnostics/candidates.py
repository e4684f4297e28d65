"""Candidate effects: which models to try next, and the quick refit that ranks them."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from balancer_id.errors import BalancerIdError, ModelSpecError
from balancer_id.identify.classic import ClassicResult
from balancer_id.identify.data import TrialData
from balancer_id.identify.matching import MatchResult, match_trials
from balancer_id.identify.starts import fit_start
from balancer_id.model.effect import Effect
from balancer_id.model.spec import Model, parse_model


@dataclass
class Candidate:
    """A model one effect away from the current one."""

    effect: type[Effect]
    model: Model
    replaces: str | None = None

    @property
    def label(self) -> str:
        """``+karnopp`` or ``viscous -> variable_viscosity``."""
        if self.replaces:
            return f"{self.replaces} -> {self.effect.name}"
        return f"+{self.effect.name}"


def candidates(model: Model, *, with_trajectory: bool = False) -> list[Candidate]:
    """Every model that adds one registered effect to ``model`` (or swaps an exclusive one).

    Effects that need a robot reference (:meth:`Effect.needs_reference_move`, ``servo``)
    are only tried when a trajectory is known.

    Parameters
    ----------
    model : Model
        The current model; the candidates come from its registry.
    with_trajectory : bool
        Whether a robot reference is known. False leaves out effects that need one
        (``servo``).

    Returns
    -------
    list of Candidate
        One per effect that can be added, in registry order. A swap (the new effect
        excludes one already present) is kept only when it adds parameters.
    """
    out = []
    present = {e.name for e in model.effects}
    for effect in model.registry:
        if effect.name in present:
            continue
        if effect.needs_reference_move() and not with_trajectory:
            continue
        clash = [n for n in effect.excludes if n in present]
        base = model
        for name in clash:
            base = base.without(name)
        names = [e.name for e in base.effects] + [effect.name]
        try:
            cand = parse_model("+".join(names), model.registry)
        except ModelSpecError:
            continue
        if clash and len(cand.param_names) <= len(model.param_names):
            continue  # a swap must add freedom, not remove it
        out.append(Candidate(effect, cand, clash[0] if clash else None))
    return out


@dataclass
class Refit:
    """The outcome of refitting one candidate."""

    candidate: Candidate
    match: MatchResult | None
    error: str | None = None


def quick_refit(
    candidate: Candidate,
    trials: Sequence[TrialData],
    current: MatchResult,
    start: dict[str, float],
    fixed: dict[str, float] | None = None,
    classic: ClassicResult | None = None,
) -> Refit:
    """Fit a candidate model from the current fit and from a fresh start; keep the better.

    The first start is the current fit, then the effect's ``guess`` from the data (when
    it has one), then the signature's start values; a drive-lag parameter the current
    model lacks (``T_up`` added over ``T_a``) starts at the current drive lag. The second
    (when ``classic`` is given) starts where a fit of the candidate starts, at the data's
    own scale (:func:`~balancer_id.identify.starts.fit_start`: the paper's method and the
    response's own equation-error fit), and the effects' default start values, because a
    fit without the effect may have bent its parameters into a corner the effect's fit
    cannot leave. A user effect that raises or produces NaN gives a Refit with ``error``
    set, naming the effect, instead of stopping the others.

    Parameters
    ----------
    candidate : Candidate
        The model to refit.
    trials : sequence of TrialData
        The trials of the current fit.
    current : MatchResult
        The fit of the current model; its values start the first refit.
    start : dict of str to float
        Start values of the new effect's parameters (from its signature check); they
        override the current values. Values are clipped into the parameters' bounds.
    fixed : dict of str to float, optional
        Parameters held in the original fit; those the candidate has are held here too.
    classic : ClassicResult, optional
        The paper's method on the same trials, for the second start; None refits from
        the current fit only.

    Returns
    -------
    Refit
        The refit with the lower RMSE, or one with ``match=None`` and ``error`` set.
    """
    model = candidate.model
    names = model.param_names

    def clipped(values: dict[str, float]) -> dict[str, float]:
        out = {}
        for name, value in values.items():
            if name in names:
                p = model.param(name)
                out[name] = min(max(value, p.min), p.max)
        return out

    now = current.values()
    guessed: dict[str, float] = {}
    guess = candidate.effect.guess
    if callable(guess):
        try:
            guessed = {k: float(v) for k, v in dict(guess(trials, now)).items()}
        except Exception as exc:  # a user's guess must not stop the diagnosis
            return Refit(candidate, None, f"guess of '{candidate.effect.name}' failed: {exc!r}")
    first = clipped({**now, **guessed, **start})
    if current.model.drive_lag_names:
        for name in model.drive_lag_names:
            first.setdefault(name, current.model.drive_lag(now))
    starts = [first]
    fresh: dict[str, float] = {}
    if classic is not None:
        # at the data's own scale (the paper's method and the response), as a fit starts
        fresh, _ = fit_start(model, trials, classic)
        if fresh:
            starts.append(clipped({**fresh, **start}))
    fixed = {k: v for k, v in (fixed or {}).items() if k in names}
    best: MatchResult | None = None
    k = 0
    while k < len(starts):
        values = starts[k]
        k += 1
        match, failed = _refit_once(candidate, trials, values, fixed)
        if match is None:
            return failed
        if best is None or match.metrics["rmse"] < best.metrics["rmse"]:
            best = match
        if k == len(starts) == 2 and start and _far_from(best, fresh, "m_a"):
            # the best ended at a mass 3x away from the data's own: the effect's guessed
            # start may have led into another basin (a speed limit reached at once makes
            # a tiny mass with a long lag fit almost as well); one more start, from the
            # data's scale with the effect's own defaults
            starts.append(clipped(fresh))
    return Refit(candidate, best)


def _refit_once(
    candidate: Candidate,
    trials: Sequence[TrialData],
    values: dict[str, float],
    fixed: dict[str, float],
) -> tuple[MatchResult | None, Refit]:
    """One refit from ``values``; a failure (an error, NaN) as a Refit naming the effect."""
    try:
        match = match_trials(candidate.model, trials, start=values, fixed=fixed, max_nfev=400)
    except BalancerIdError as exc:
        return None, Refit(candidate, None, f"{candidate.effect.name}: {exc}")
    except Exception as exc:  # a user's effect must not stop the diagnosis
        return None, Refit(candidate, None, f"effect '{candidate.effect.name}' failed: {exc!r}")
    if not all(abs(v) < float("inf") for v in match.values().values()) or not (
        match.metrics["rmse"] == match.metrics["rmse"]
    ):
        return None, Refit(candidate, None, f"effect '{candidate.effect.name}' produced NaN")
    return match, Refit(candidate, match)


def _far_from(match: MatchResult | None, start: dict[str, float], name: str) -> bool:
    """Whether ``match`` ended with ``name`` more than a factor 3 from ``start``'s."""
    if match is None or name not in start or name not in match.values():
        return False
    a, b = float(match.values()[name]), float(start[name])
    return a > 0 and b > 0 and not (1 / 3 < a / b < 3)
