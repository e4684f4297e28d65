"""The search, stage by stage: library, forward rounds, pruning, friction settled."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.discovery.linear import (
    _bootstrap,
    _final_inclusion,
    _linearize,
    _ranked,
    held_out_gain,
    select,
    term_price,
)
from balancer_id.diagnostics.discovery.result import DiscoveredTerm, Discovery
from balancer_id.diagnostics.discovery.settings import (
    CLOSE,
    CLOSE_BIC,
    COULOMB,
    LEFT_OVER,
    MAX_TERMS,
    PERIOD_SAMPLES,
    PERIODIC,
    REFITTED,
    STRIBECK,
    TERM_BIC,
)
from balancer_id.diagnostics.discovery.terms import Term, default_terms, library_effect
from balancer_id.errors import BalancerIdError
from balancer_id.identify.matching import MatchResult, match_trials
from balancer_id.identify.starts import fit_start
from balancer_id.model.registry import Registry
from balancer_id.model.spec import Model

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput, Explanation
    from balancer_id.diagnostics.context import DiagnosisContext, TrialView


# ---- the period over position -----------------------------------------------------------


def position_period(ctx_trials: Sequence[TrialView], m_a: float) -> float | None:
    """The period over position of the residual force, from its Lomb-Scargle spectrum.

    The moving samples' residual force (m_a times the acceleration residual) against the
    simulated position; periods from 1/20 to 1/1.5 of the distance covered are searched.
    A peak that is not clearly above the spectrum's median gives None.

    Parameters
    ----------
    ctx_trials : sequence of TrialView
        The diagnosis's trials.
    m_a : float
        The fitted mass (kg).

    Returns
    -------
    float or None
        The period (m).
    """
    from scipy.signal import lombscargle

    zs, rs = [], []
    for tv in ctx_trials:
        moving = (tv.t > 0) & (np.abs(tv.v) > 1e-4)
        if moving.sum() < 20:
            continue
        r = m_a * tv.residual[moving]
        zm = np.asarray(tv.z[moving], dtype=float)
        trend = np.polynomial.Polynomial.fit(zm, r, 2)(zm) if np.ptp(zm) > 0 else np.mean(r)
        zs.append(zm)
        rs.append(r - trend)
    if not zs:
        return None
    z, r = np.concatenate(zs), np.concatenate(rs)
    span = float(np.ptp(z))
    if span <= 0 or z.size < 50:
        return None
    periods = np.geomspace(span / 20.0, span / 1.5, 200)
    # the shortest period searched spans hundreds of samples: every few is enough
    stride = max(1, z.size // PERIOD_SAMPLES)
    z, r = z[::stride], r[::stride]
    power = lombscargle(z, r - r.mean(), 2 * np.pi / periods)
    k = int(np.argmax(power))
    if not power[k] > 8.0 * float(np.median(power)):
        return None
    return float(periods[k])


@dataclass
class Library:
    """The candidate terms as one library effect added to the current model.

    Attributes
    ----------
    terms : list of Term
        The candidates (the defaults or the caller's, and the user's extra ones).
    skip : set of str
        Terms not tried (the periodic ones without a period over position).
    stick : bool
        Dry-friction terms act with a stick band (the model has no friction effect).
    model : Model
        The current model plus the library.
    q_names : list of str
        The terms' coefficients, in order.
    fixed : dict
        What every refit holds: the current fit's held values and the shape constants.
    """

    terms: list[Term]
    skip: set[str]
    stick: bool
    model: Model
    q_names: list[str]
    fixed: dict[str, float]

    def holding(self, support: Sequence[int]) -> dict[str, float]:
        """What a refit with the terms ``support`` holds: the rest at 0.

        Parameters
        ----------
        support : sequence of int
            The indices of the terms taken.

        Returns
        -------
        dict of str to float
        """
        off = {self.q_names[k]: 0.0 for k in range(len(self.terms)) if k not in support}
        return {**self.fixed, **off}


@dataclass
class Pursuit:
    """Where the forward search stands: the terms taken, the refit and its BIC fall."""

    current: dict[str, float]
    support: list[int] = field(default_factory=list)
    refit: MatchResult | None = None
    d_best: float = 0.0
    alternatives: list[dict[str, object]] = field(default_factory=list)
    inclusion: np.ndarray | None = None


def search(
    inp: ArenaInput,
    ctx: DiagnosisContext,
    rival: Explanation | None,
    command: str,
    terms: Sequence[Term] | None,
    extra_terms: Sequence[Term],
    seed: int,
    margin: float,
) -> Discovery | None:
    """:func:`~balancer_id.diagnostics.discover.discover` without the floating-point
    warnings: the library, the forward rounds, the pruning, the friction settled, the
    result scored against ``rival``.

    Parameters
    ----------
    inp : ArenaInput
        The current fit.
    ctx : DiagnosisContext
        The diagnosis's views of the trials (states, residual).
    rival : Explanation or None
        The best other explanation, which a discovery must beat.
    command : str
        The command that writes the discovery as an effect.
    terms : sequence of Term or None
        The candidate terms (None: the default library).
    extra_terms : sequence of Term
        Terms added to the library.
    seed : int
        Seed of the bootstrap of the terms' inclusion.
    margin : float
        BIC by which a discovery must beat ``rival``.

    Returns
    -------
    Discovery or None
    """
    lib = library(inp, ctx, terms, extra_terms)
    if lib is None:
        return None
    path = Pursuit({**inp.match.values(), **dict.fromkeys(lib.q_names, 0.0), **_shapes(lib.terms)})
    for round_ in range(MAX_TERMS):
        if not forward_round(inp, lib, path, seed if round_ == 0 else None):
            break
    if path.refit is None or not path.support:
        return None
    prune(inp, lib, path)
    hold = lib.holding(path.support)
    refit, hold, freed, support = _settle_friction(
        inp, lib.model, path.refit, hold, lib.terms, path.support
    )
    parts = [refit.residual[sl] for sl in refit.data.slices()]
    d_bic, rmse = arena.score(inp, parts, len(support) + len(freed))
    if d_bic <= TERM_BIC or (rival is not None and d_bic <= rival.delta_bic + margin):
        return None
    final = _final_inclusion(lib.model, inp, refit, hold, freed, lib.terms, support, seed)
    inclusion = final if final is not None else path.inclusion
    found = _discovered_terms(lib, refit, support, freed, inclusion)
    return Discovery(
        terms=found,
        delta_bic=d_bic,
        rmse=rmse,
        command=command,
        refit=refit,
        rival={"label": rival.label, "delta_bic": rival.delta_bic} if rival is not None else None,
        fixed=hold,
        stick=lib.stick and any(t.term.is_friction for t in found),
        alternatives=[
            a for a in path.alternatives if a["instead_of"] in {t.expression for t in found}
        ],
        states=_states(refit, found),
    )


def _discovered_terms(
    lib: Library, refit: MatchResult, support: list[int], freed: dict[str, float], inclusion: Any
) -> list[DiscoveredTerm]:
    """The kept terms with their refitted coefficients, their shapes where freed, and their
    share of the bootstrap resamples."""
    found = []
    for j in support:
        est = refit.parameters[lib.q_names[j]]
        term = lib.terms[j]
        if term.shapes and all(key in freed for key, _ in term.shapes):
            term = replace(term, shapes=tuple((key, freed[key]) for key, _ in term.shapes))
        share = float(inclusion[j]) if inclusion is not None else 0.0
        found.append(DiscoveredTerm(term, float(est.value), est.stderr, share))
    return found


def _shapes(terms: Sequence[Term]) -> dict[str, float]:
    return {key: val for t in terms for key, val in t.shapes}


def library(
    inp: ArenaInput,
    ctx: DiagnosisContext,
    terms: Sequence[Term] | None,
    extra_terms: Sequence[Term],
) -> Library | None:
    """The candidate terms (the defaults from the trials' speed and period over position
    unless given) as one library effect added to the current model; None when the trials
    never move.

    Parameters
    ----------
    inp : ArenaInput
        The current fit.
    ctx : DiagnosisContext
        The diagnosis's views of the trials.
    terms : sequence of Term or None
        The candidate terms (None: the defaults).
    extra_terms : sequence of Term
        Terms added to them.

    Returns
    -------
    Library or None
    """
    match = inp.match
    skip: set[str] = set()
    if terms is None:
        views = list(ctx.trials)
        v_top = max((float(np.max(np.abs(tv.v))) for tv in views), default=0.0)
        if v_top <= 0:
            return None
        period = position_period(views, float(match.values().get("m_a", 1.0)))
        terms = default_terms(v_top, period)
        skip = set(PERIODIC) if period is None else set()
    every = [*terms, *extra_terms]
    # dry friction with a stick band, unless the model has a friction effect already
    stick = not any("friction" in e.hooks() for e in match.model.effects)
    effect = library_effect(every, stick)
    registry = Registry(list(match.model.registry))
    if effect.name not in registry:
        registry.add(effect, origin="discovery")
    model = Model((*match.model.effects, effect), registry)
    q_names = [f"q{j}" for j in range(len(every))]
    return Library(every, skip, stick, model, q_names, {**arena.held(match), **_shapes(every)})


def forward_round(inp: ArenaInput, lib: Library, path: Pursuit, seed: int | None) -> bool:
    """One round of the forward search: the linear step ranks the terms left, the few
    best are refitted whole (nonlinear: ``v|v|`` and ``v^3`` look alike to the linear
    step) and the one that lowers BIC most is taken when it pays :data:`TERM_BIC`.

    Parameters
    ----------
    inp : ArenaInput
    lib : Library
    path : Pursuit
        Updated in place.
    seed : int or None
        The bootstrap's seed on the first round (its inclusion probabilities); None after.

    Returns
    -------
    bool
        Whether a term was taken (False ends the search).
    """
    terms = lib.terms
    rest = [j for j in range(len(terms)) if j not in path.support and terms[j].name not in lib.skip]
    lin = _linearize(
        lib.model, inp.match.data, path.current, lib.fixed, lib.q_names, path.support, rest, inp.ar
    )
    if lin is None or not rest:
        return False
    every = list(range(len(lin.r)))
    if not select(lin, every, range(len(rest))):
        return False
    if seed is not None:
        path.inclusion = _bootstrap(lin, rest, len(terms), seed)
    r, p, q = lin.rows(every)
    groups = _groups_to_try(lin, terms, rest, _ranked(r, p, q))
    tried = []
    for group in groups:
        cols = [rest.index(k) for k in group]
        step, *_ = np.linalg.lstsq(np.hstack([p, q[:, cols]]), r, rcond=None)
        got = _try_group(inp, lib, path, group, step[-len(group) :])
        if got is not None:
            tried.append(got)
    if not tried:
        return False
    best = max(tried, key=lambda t: t[0])  # the first of equals, as the rounds took it
    if best[0] - path.d_best <= TERM_BIC:
        return False
    _take(lib, path, best, tried)
    return True


def _groups_to_try(
    lin: Any, terms: Sequence[Any], rest: list[int], ranked: list[tuple[int, float]]
) -> list[tuple[int, ...]]:
    """The best-ranked terms that gain on held-out trials, each alone, and a Stribeck term
    with its Coulomb level too."""
    top = ranked[0][1] if ranked else 0.0
    tries = [rest[c] for c, gain in ranked[:REFITTED] if gain > max(TERM_BIC, CLOSE * top)]
    tries = [j for j in tries if held_out_gain(lin, [rest.index(j)])[0] > 1.0]
    # a Stribeck term comes with its Coulomb level: the pair is tried too
    coulomb = next((k for k in rest if terms[k].name == COULOMB), None)
    groups: list[tuple[int, ...]] = [(j,) for j in tries]
    groups += [
        (coulomb, j)
        for j in tries
        if coulomb is not None and terms[j].name.startswith(STRIBECK) and coulomb != j
    ]
    return groups


def _try_group(
    inp: ArenaInput, lib: Library, path: Pursuit, group: tuple[int, ...], step: np.ndarray
) -> tuple[float, tuple[int, ...], MatchResult] | None:
    """The whole model refitted with ``group`` added, started at its linear step.

    A group is one law (a term, or Coulomb with Stribeck): it pays :data:`TERM_BIC`
    once, its second parameter counted in the BIC like any other.
    """
    start = {
        **path.current,
        **{lib.q_names[k]: float(x) for k, x in zip(group, step, strict=True)},
    }
    support = [*path.support, *group]
    fitted = _refit_group(inp, lib, start, support)
    if fitted is not None and _leaves_error(inp, fitted) and inp.fit is not None:
        # the current fit, bent by the force it lacks, may sit in another basin (a light
        # mass with a long lag): the group refitted from the data's own scale too
        fresh, _ = fit_start(inp.match.model, inp.trials, inp.fit.classic)
        again = _refit_group(inp, lib, {**start, **fresh}, support) if fresh else None
        if again is not None and again.metrics["rmse"] < fitted.metrics["rmse"]:
            fitted = again
    if fitted is None:
        return None
    gain, _ = arena.score(inp, [fitted.residual[sl] for sl in fitted.data.slices()], len(support))
    return gain, group, fitted


def _refit_group(
    inp: ArenaInput, lib: Library, start: dict[str, float], support: list[int]
) -> MatchResult | None:
    """The model with the terms ``support`` refitted from ``start`` (None when it fails)."""
    try:
        return match_trials(
            lib.model, list(inp.trials), start=start, fixed=lib.holding(support), max_nfev=200
        )
    except BalancerIdError:
        return None


def _leaves_error(inp: ArenaInput, fitted: MatchResult) -> bool:
    """Whether a refit leaves more error above the noise floor than :data:`LEFT_OVER` x
    the noise (the share discovery is tried for)."""
    floor = inp.noise_floor
    left = float(np.sqrt(max(fitted.metrics["rmse"] ** 2 - floor**2, 0.0)))
    return floor > 0 and left > LEFT_OVER * floor


def _take(
    lib: Library,
    path: Pursuit,
    best: tuple[float, tuple[int, ...], MatchResult],
    tried: list[tuple[float, tuple[int, ...], MatchResult]],
) -> None:
    """``best`` taken into the path; the single terms that fit about as well this round
    (within :data:`CLOSE_BIC`) said as its alternatives."""
    d, chosen, refit = best
    new = chosen[-1]
    for d_alt, group, alt in tried:
        j = group[-1]
        if len(group) == 1 and j != new and d_alt >= d - CLOSE_BIC:
            path.alternatives.append(
                {
                    "instead_of": lib.terms[new].concrete(),
                    "expression": lib.terms[j].concrete(),
                    "coefficient": float(alt.parameters[lib.q_names[j]].value),
                    "bic_drop": float(d_alt),
                }
            )
    path.support = [*path.support, *chosen]
    path.refit, path.d_best = refit, d
    path.current = {**path.current, **refit.values()}


def prune(inp: ArenaInput, lib: Library, path: Pursuit) -> None:
    """Terms that no longer pay removed, the worst first.

    A term taken while an earlier one's refit had not settled may not pay at the end:
    each must still cost more than :func:`term_price` when the whole model is refitted
    without it.

    Parameters
    ----------
    inp : ArenaInput
        The current fit.
    lib : Library
        The library effect and its terms.
    path : Pursuit
        The search so far; its support and refit are updated in place.
    """
    trials = list(inp.trials)
    while len(path.support) > 1:
        drops = []
        for j in path.support:
            keep = [k for k in path.support if k != j]
            try:
                fitted = match_trials(
                    lib.model,
                    trials,
                    start={**path.current, lib.q_names[j]: 0.0},
                    fixed=lib.holding(keep),
                    max_nfev=200,
                )
            except BalancerIdError:
                continue
            d, _ = arena.score(inp, [fitted.residual[sl] for sl in fitted.data.slices()], len(keep))
            excess = path.d_best - d - term_price(lib.terms, path.support, j)
            drops.append((excess, j, fitted, d))
        if not drops:
            return
        excess, j, fitted, d = min(drops, key=lambda x: x[0])
        if excess > 0:
            return
        path.support = [k for k in path.support if k != j]
        path.refit, path.d_best = fitted, d
        path.current = {**path.current, **fitted.values()}


def _settle_friction(
    inp: ArenaInput,
    model: Model,
    refit: MatchResult,
    hold: dict[str, float],
    terms: Sequence[Term],
    support: Sequence[int],
) -> tuple[MatchResult, dict[str, float], dict[str, float], list[int]]:
    """The chosen dry-friction terms settled: their Stribeck velocity fitted, the Coulomb
    level beside a Stribeck term.

    The grid of Stribeck velocities only starts the search: each chosen one is freed in a
    whole refit, and a Stribeck term chosen alone is tried with its Coulomb level too
    (Coulomb with Stribeck is the physical law). The chosen Stribeck term has paid
    :data:`TERM_BIC` as a term; its law's other parameters (the velocity, whose grid value
    is arbitrary, and the Coulomb level) are then fitted like any model's parameters: each
    is counted in the BIC, and the settled law is kept when its BIC is the lowest.

    Returns
    -------
    refit : MatchResult
    hold : dict
        What the refit held (the freed constants and the added level left out).
    freed : dict
        The fitted shape constants.
    support : list of int
        The terms kept (the Coulomb level added or not).
    """
    chosen = [terms[j] for j in support]
    keys = [key for t in chosen if t.is_friction for key, _ in t.shapes]
    if not keys:
        return refit, hold, {}, list(support)
    coulomb = next((j for j, t in enumerate(terms) if t.name == COULOMB), None)
    options: list[list[int]] = [list(support)]
    if coulomb is not None and coulomb not in support:
        options.append([*support, coulomb])
    best: tuple[float, MatchResult, dict[str, float], dict[str, float], list[int]] = (
        arena.score(inp, [refit.residual[sl] for sl in refit.data.slices()], len(support))[0],
        refit,
        hold,
        {},
        list(support),
    )
    for option in options:
        loose = {k: v for k, v in hold.items() if k not in keys}
        if coulomb is not None:
            loose.pop(f"q{coulomb}", None)
            if coulomb not in option:
                loose[f"q{coulomb}"] = 0.0
        try:
            fitted = match_trials(
                model, list(inp.trials), start=refit.values(), fixed=loose, max_nfev=200
            )
        except BalancerIdError:
            continue
        parts = [fitted.residual[sl] for sl in fitted.data.slices()]
        d, _ = arena.score(inp, parts, len(option) + len(keys))
        if d > best[0]:
            values = fitted.values()
            best = (d, fitted, loose, {k: float(values[k]) for k in keys}, option)
    _, refit, hold, freed, kept = best
    return refit, hold, freed, kept


def _states(refit: MatchResult, found: Sequence[DiscoveredTerm]) -> dict[str, np.ndarray]:
    """The refit's states and the force the terms were fitted to (for the report's plot)."""
    values = refit.values()
    pvec = np.array([values[n] for n in refit.model.param_names])
    out = refit.data.packed.run(refit.model, pvec)
    f, v, z, h = out[:, 3], out[:, 1], out[:, 2], out[:, 4]
    force = np.zeros_like(v)
    for t in found:
        force += t.coefficient * t.term.evaluate(f, v, z, h)
    m_a = float(values.get("m_a", 1.0))
    t_rel = np.concatenate([td.time - td.t_step for td in refit.data.trials])
    return {
        "f": f,
        "v": v,
        "z": z,
        "h": h,
        "t": t_rel,
        "term_force": force,
        "residual_force": m_a * (refit.data.y - out[:, 0]) + force,
    }
