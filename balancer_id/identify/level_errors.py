"""The thrust levels' errors in the standard errors: errors in variables (issue 31).

A step trial is driven by its measured force, held between changes: each hold's level is
the mean of a noisy force over the hold, less the force's zero, read in the rest before
the first step of its chain (:attr:`~balancer_id.identify.data.TrialData.zero_se_N`).
Both are uncertain, and the model, driven by them as if exact, bends its values to
follow a level that is a little off: ``A``, read from how the viscosity changes between
nearby levels, most (``bench_universe``: force noise 1.7 % of the thrust, levels 5 %
apart, D0 and A 5-6 standard errors off, trusted; the zero's error was three times the
held level's). The fit's own standard errors hold for the accelerometer's noise only.

To first order a level error ``delta`` moves the simulated acceleration by ``S delta``
(``S``: the output's sensitivity to the hold's level), and the fitted values by
``(J^T J)^-1 J^T S delta``. With the holds' errors independent and each chain's zero
shared by its holds, the values' covariance from the levels is

    C = sum_h var_h a_h a_h^T + sum_c var_c (sum_{h in c} a_h)(sum_{h in c} a_h)^T,
    a_h = (J^T J)^-1 J^T S_h,

added to the fit's own (its square roots in quadrature to each standard error).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from balancer_id.identify.data import FitData, TrialData
from balancer_id.identify.matching import MatchResult
from balancer_id.identify.trial_scatter import widen_stderrs
from balancer_id.notes import Note
from balancer_id.simulation.engine import TrialInput
from balancer_id.simulation.inputs import Thrust

#: The level perturbation (N) per unit of the trials' largest thrust.
LEVEL_STEP = 1e-4

#: Rows simulated per block (as the fit's).
BLOCK_ROWS = 1 << 16

#: Most simulations spent (one per hold of the longest chain, plus the base).
MAX_SIMULATIONS = 64

def _chains(trials: Sequence[TrialData]) -> list[list[int]]:
    """The trials that carry their state over (a session's), as lists of indices."""
    out: list[list[int]] = []
    for i, td in enumerate(trials):
        prev = trials[i - 1] if i else None
        if (
            prev is not None
            and td.continues
            and td.previous is not None
            and td.previous.time[-1] == prev.time[-1]
            and prev.source == td.source
        ):
            out[-1].append(i)
        else:
            out.append([i])
    return out


def _pushed(td: TrialData, step: float) -> TrialData:
    """The trial with its held level raised by ``step`` N from its onset on."""
    thrust = td.input.thrust
    times = np.asarray(thrust.times, dtype=float)
    values = np.array(thrust.values, dtype=float, copy=True)
    dt = float(np.median(np.diff(td.time))) if td.time.size > 1 else 0.0
    values[times >= td.t_step - 0.75 * dt] += step
    inp = td.input
    moved = TrialInput(inp.time, Thrust(times, values), inp.z_ref, inp.v_ref, inp.x0)
    return dataclasses.replace(td, input=moved)


def _level_sources(match: MatchResult) -> tuple[list[list[int]], np.ndarray, np.ndarray] | None:
    """The chains, each trial's hold variance and each chain's zero variance (N^2);
    None where a trial is not driven by a held measured force."""
    trials = match.data.trials
    if not trials or any(td.level_se_N is None for td in trials):
        return None
    chains = _chains(trials)
    hold = np.array([float(td.level_se_N or 0.0) ** 2 for td in trials])
    zero = np.array([float(trials[c[0]].zero_se_N or 0.0) ** 2 for c in chains])
    if not (np.all(np.isfinite(hold)) and np.all(np.isfinite(zero))):
        return None
    return chains, hold, zero


def level_error_covariance(match: MatchResult) -> tuple[list[str], np.ndarray] | None:
    """The fitted values' covariance from the errors of the thrust levels.

    Parameters
    ----------
    match : MatchResult
        A converged fit.

    Returns
    -------
    (list of str, numpy.ndarray) or None
        The fitted parameters' names and their covariance; None when the trials are not
        step trials driven by a held measured force, nothing is fitted, the chains are
        too long to simulate hold by hold, or ``J^T J`` is singular.
    """
    sources = _level_sources(match)
    if sources is None:
        return None
    chains, hold, zero = sources
    model = match.model
    names = [p.name for p in model.params if match.parameters[p.name].vary]
    free = [model.param_names.index(n) for n in names]
    longest = max(len(c) for c in chains)
    if not free or longest + 1 > MAX_SIMULATIONS:
        return None
    trials = match.data.trials
    pvec = np.array([match.parameters[p.name].value for p in model.params], dtype=float)
    step = LEVEL_STEP * max(max(abs(td.thrust_N) for td in trials), 1e-9)
    slices = match.data.slices()
    with np.errstate(all="ignore"):
        base = match.data.packed.run(model, pvec)[:, 0]
        # S: one column per trial's hold, each only over its chain's rows from that hold
        # on; the w-th hold of every chain is pushed in the same simulation (chains share
        # no state)
        cols: list[tuple[int, np.ndarray]] = [(0, np.zeros(0))] * len(trials)
        for w in range(longest):
            pushed = {c[w] for c in chains if len(c) > w}
            moved = [_pushed(td, step) if i in pushed else td for i, td in enumerate(trials)]
            out = FitData.build(moved).packed.run(model, pvec)[:, 0]
            for c in chains:
                if len(c) > w:
                    a, b = slices[c[w]].start, slices[c[-1]].stop
                    cols[c[w]] = (a, (out[a:b] - base[a:b]) / step)
        jtj = np.zeros((len(free), len(free)))
        jts = np.zeros((len(free), len(trials)))
        for first, _, jac in match.data.packed.stream_sens(model, pvec, free, BLOCK_ROWS):
            stop = first + jac.shape[0]
            jtj += jac.T @ jac
            for h, (a, col) in enumerate(cols):
                lo, hi = max(a, first), min(a + col.size, stop)
                if hi > lo:
                    jts[:, h] += jac[lo - first : hi - first].T @ col[lo - a : hi - a]
    if not (np.all(np.isfinite(jtj)) and np.all(np.isfinite(jts))):
        return None
    try:
        a = np.linalg.solve(jtj, jts)  # (k, trials): each hold's error's move of the values
    except np.linalg.LinAlgError:
        return None
    cov = (a * hold) @ a.T
    for c, var in zip(chains, zero, strict=True):
        shared = a[:, c].sum(axis=1)
        cov += var * np.outer(shared, shared)
    return names, cov


def widen_by_level_errors(match: MatchResult) -> list[Note]:
    """Add the thrust levels' errors to each fitted value's standard error.

    Parameters
    ----------
    match : MatchResult
        The fit (its estimates' ``stderr`` and ``scatter_ratio`` changed in place; the
        largest ratio goes into ``metrics["level_error_ratio"]``).

    Returns
    -------
    list of Note
        A ``fit.correlated_residual`` note (severity ``info``) when a standard error
        grew by more than :data:`~balancer_id.identify.trial_scatter.NOTE_RATIO`.
    """
    found = level_error_covariance(match)
    if found is None:
        return []
    names, cov = found
    widened = {}
    for j, name in enumerate(names):
        se, extra = match.parameters[name].stderr, float(np.sqrt(max(cov[j, j], 0.0)))
        if se is not None and np.isfinite(extra):
            widened[name] = float(np.hypot(se, extra))
    return widen_stderrs(
        match,
        widened,
        "level_error_ratio",
        lambda ratio, worst: (
            f"the thrust levels are read from a noisy force (each hold's mean, less the "
            f"force's zero read at rest): their errors are in the standard errors (up to "
            f"{ratio:.1f}x, {worst})"
        ),
    )


#: A force rising over its zero's rest by this many standard errors ...
ZERO_DRIFT_Z = 4.0

#: ... and by this share of the trial's step is no rest: its zero is unknown.
ZERO_DRIFT_SHARE = 0.1


def unsteady_zero(match: MatchResult) -> Note | None:
    """A ``fit.force_zero`` note (severity ``error``) when the force moves over the rest
    where its zero is read (:attr:`~balancer_id.identify.data.TrialData.zero_drift_N`)
    by :data:`ZERO_DRIFT_Z` standard errors and :data:`ZERO_DRIFT_SHARE` of the step,
    else None.

    The zero is the force's mean there, subtracted from every level after it. A force
    that rises there is already pushing (a person's smooth push read as steps, a preload
    let go, a tension): every level is then off by an unknown amount, and the values
    bend to follow it (``bench_universe`` clean world 12757897038: a guided move read as
    four steps, m_a 1.7 times the truth, T_a a quarter of it, 10-20 standard errors off,
    trusted).

    Parameters
    ----------
    match : MatchResult
        The fit.

    Returns
    -------
    Note or None
    """
    worst: tuple[float, TrialData] | None = None
    for td in match.data.trials:
        if td.zero_drift_N is None or td.thrust_N == 0:
            continue
        rise, se = td.zero_drift_N
        if not (se > 0 and np.isfinite(rise)):
            continue
        z = abs(rise) / se
        if z >= ZERO_DRIFT_Z and abs(rise) >= ZERO_DRIFT_SHARE * abs(td.thrust_N):
            if worst is None or z > worst[0]:
                worst = (z, td)
    if worst is None:
        return None
    z, td = worst
    rise = td.zero_drift_N[0] if td.zero_drift_N else float("nan")
    return Note(
        "fit.force_zero",
        f"trial {td.index}: the force moves by {rise:+.3g} N ({z:.0f} standard errors, "
        f"{abs(rise / td.thrust_N):.0%} of its step) over the rest before its step, where "
        "its zero is read: something already pushed (a smooth push read as steps, a "
        "preload, a tension), so every level read against that zero is off and the values "
        "bend with it; check the trials with 'balancer-id inspect --plot' and give "
        "stretches where only the measured force acts with --window",
        severity="error",
        subject=f"trial {td.index}",
    )
