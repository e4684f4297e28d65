"""The arena's criterion and tools: every explanation is a fitted model scored alike.

An explanation of what the current model misses is a model fitted to the same trials
(its kinds are listed once in :data:`balancer_id.diagnostics.explanations.KINDS`: a
library effect added, a parameter split at a run boundary or drifting over the runs or
in time, a sensor's effect, a pair, a discovered force). Each is scored by the same
criterion (:func:`score`): the fall of BIC against the current fit on residuals
prewhitened with the resting noise's AR(2) colour.
:func:`~balancer_id.diagnostics.explanations.run_arena` fits every kind, stage by stage;
:func:`standing` keeps those with a benefit, best first.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from scipy.optimize import least_squares

from balancer_id.diagnostics.explanations.base import Explanation, Stage, Verdict
from balancer_id.identify.data import FitData, TrialData
from balancer_id.identify.matching import MatchResult, residual_around_steps
from balancer_id.model.spec import Model

if TYPE_CHECKING:
    from balancer_id.diagnostics.context import DiagnosisContext
    from balancer_id.identify.result import FitResult

__all__ = ["ArenaInput", "Explanation", "Stage", "Verdict", "score", "standing"]

#: One fit's arguments (:func:`fit_in_threads`).
Job = TypeVar("Job")

#: BIC improvement an explanation needs before it is a verdict. Calibrated on simulated
#: logs with nothing hidden (benchmarks/bench_diagnose.py, false alarms <= 5 %).
BIC_THRESHOLD = 30.0
#: ... and the share of the error above the noise floor it must remove.
MIN_EXCESS_DROP = 0.1
#: A runner-up naming other effects or parameters within this many BIC units is "close"
#: whatever its kind: a likelihood ratio under e^3 ~ 20 (Kass and Raftery's "positive"
#: evidence, short of "strong"), so the recording cannot tell the two apart.
CLOSE_BIC = 6.0
#: A best removing this share of the error above the noise floor reaches the floor.
FLOOR_DROP = 0.9

#: Parameters of the split and drift explanations must move by at least this share.
MIN_RELATIVE_CHANGE = 0.03
#: Function evaluations of a refinement (:attr:`Explanation.refine`); the first fits of
#: the arena stop at 60, enough to rank them, not always to tell two close ones apart.
REFINE_NFEV = 300


@dataclass
class ArenaInput:
    """What every explanation generator sees.

    Attributes
    ----------
    match : MatchResult
        The current fit.
    trials : list of TrialData
        Its trials, in recording order.
    runs : list of str
        Each trial's run label (file and run).
    noise_floor : float
        Acceleration noise (m/s^2).
    independence : float
        Effective share of independent samples of the current residual.
    effect_fits : list of tuple
        ``(effect name, refitted MatchResult)`` of the library candidates.
    rest_cutoff_hz : float or None
        The resting noise's -3 dB frequency when its spectrum rolls off, else None.
    ar : tuple of float
        AR(2) coefficients of the resting noise: every residual is prewhitened with them
        before its BIC (the likelihood of coloured noise); ``(0, 0)`` for white noise.
    threads : int or None
        Fits run at once (the splits and drifts); None: one per core.
    """

    match: MatchResult
    trials: list[TrialData]
    runs: list[str]
    noise_floor: float
    independence: float
    effect_fits: list[tuple[str, MatchResult]] = field(default_factory=list)
    rest_cutoff_hz: float | None = None
    ar: tuple[float, float] = (0.0, 0.0)
    #: Mean square of the resting noise prewhitened alike: what a perfect model leaves.
    rest_innovation: float | None = None
    threads: int | None = None
    #: The explanations fitted so far (the earlier stages'), best first.
    found: list[Explanation] = field(default_factory=list)
    #: Named failures of the kinds' fits (a failed fit must not stop the others).
    failures: list[str] = field(default_factory=list)
    #: Whether a test an adequate verdict must pass failed (the last stage's condition).
    tests_failed: bool = False
    #: The fit diagnosed and its context (for the kinds that need its command or states).
    fit: FitResult | None = None
    context: DiagnosisContext | None = None
    #: Whether the last stage may search a discovered force, and the user's extra terms.
    discover: bool = False
    extra_terms: tuple[object, ...] = ()
    #: Resting acceleration magnitudes (m/s^2) before each trial, for the gain check.
    rest_magnitude: list[float] = field(default_factory=list)

    def polish(self, e: Explanation) -> Explanation:
        """``e`` with its share of the excess error and of the available BIC fall set.

        Parameters
        ----------
        e : Explanation

        Returns
        -------
        Explanation
            ``e`` itself.
        """
        e.excess_drop = excess_drop(self.match.metrics["rmse"], e.rmse, self.noise_floor)
        available = self.available()
        e.share = e.delta_bic / available if available else None
        return e

    def available(self) -> float | None:
        """The BIC fall a perfect model would bring (the current whitened excess), or None."""
        if not self.rest_innovation or self.rest_innovation <= 0:
            return None
        rss0, n, _ = current(self)
        return max(bic(rss0, n, 0) - bic(n * self.rest_innovation, n, 0), 0.0)


def bic(rss: float, n: int, k: int) -> float:
    """``n ln(rss / n) + k ln n`` (as the fit's metrics).

    Parameters
    ----------
    rss : float
        Residual sum of squares.
    n : int
        Samples.
    k : int
        Fitted parameters.

    Returns
    -------
    float
    """
    return float(n * np.log(max(rss, 1e-300) / n) + k * np.log(n))


class Trials:
    """The trials simulated one by one (each may have its own parameter vector)."""

    def __init__(self, trials: Sequence[TrialData], data: Sequence[FitData] | None = None) -> None:
        self.data = list(data) if data is not None else [FitData.build([td]) for td in trials]
        self.n = int(sum(d.y.size for d in self.data))

    def outputs(self, model: Model, pvecs: Sequence[np.ndarray]) -> list[np.ndarray]:
        """Each trial's simulated output (acceleration) with its own parameter vector.

        Parameters
        ----------
        model : Model
            The model simulated.
        pvecs : sequence of numpy.ndarray
            One parameter vector per trial, in the trials' order.

        Returns
        -------
        list of numpy.ndarray
        """
        return [d.packed.run(model, p)[:, 0] for d, p in zip(self.data, pvecs, strict=True)]


def fit_varying(
    model: Model,
    sims: Trials,
    start: dict[str, float],
    fixed: dict[str, float],
    name: str,
    design: np.ndarray,
    post: Callable[[int, np.ndarray], np.ndarray] | None = None,
    extra: tuple[float, float, float] | None = None,
    c_start: np.ndarray | None = None,
    max_nfev: int = 60,
    solution: list[object] | None = None,
) -> tuple[list[np.ndarray], dict[str, float], np.ndarray, float | None]:
    """Least squares of ``model`` where ``name = base + c * design[i]`` in trial ``i``.

    ``post(i, y)`` (optional) transforms each trial's simulated output, with one extra
    parameter ``extra = (start, lo, hi)`` passed as ``post.param``. Returns the RSS, the
    fitted base values, the coefficient(s) and the extra parameter; ``solution`` (a list)
    receives the optimizer's result (its Jacobian gives the standard errors).

    Parameters
    ----------
    model : Model
        The model fitted.
    sims : Trials
        The trials, packed for simulation.
    start : dict of str to float
        Start values of the free parameters.
    fixed : dict of str to float
        Parameters held.
    name : str
        The parameter that varies across trials.
    design : numpy.ndarray
        Its design: one row per trial, one column per coefficient ``c``.
    post : callable, optional
        ``post(i, y)``: each trial's output transformed (a sensor's gain, delay).
    extra : (float, float, float), optional
        ``(start, lo, hi)`` of ``post``'s own parameter.
    c_start : numpy.ndarray, optional
        Start values of the coefficients (default 0).
    max_nfev : int
        Budget of model evaluations.
    solution : list, optional
        Receives the optimizer's result.

    Returns
    -------
    (list of numpy.ndarray, dict of str to float, numpy.ndarray, float or None)
        The residual of each trial, the fitted base values, the coefficients and the
        extra parameter.
    """
    names = [n for n in model.param_names if n not in fixed]
    lo = np.array([model.param(n).min for n in names])
    hi = np.array([model.param(n).max for n in names])
    x0 = np.clip(np.array([start[n] for n in names]), lo, hi)
    x0 = np.where(x0 <= lo, lo + 1e-6 * np.maximum(np.abs(hi - lo), 1e-9), x0)
    x0 = np.minimum(x0, hi)
    scale = np.maximum(np.abs(x0), 1e-3)
    q = design.shape[1] if design.ndim == 2 else 0
    c0 = np.zeros(q) if c_start is None else np.asarray(c_start, dtype=float).reshape(q)
    e0 = [] if extra is None else [extra[0]]
    lo_all = np.r_[lo, -np.inf * np.ones(q), [] if extra is None else [extra[1]]]
    hi_all = np.r_[hi, np.inf * np.ones(q), [] if extra is None else [extra[2]]]
    xs = np.r_[x0, c0, e0]
    xscale = np.r_[
        scale,
        scale[names.index(name)] * np.ones(q) if name in names else np.ones(q),
        [] if extra is None else [max(abs(extra[0]), 1e-3)],
    ]
    ys = [d.y for d in sims.data]
    k_name = names.index(name) if name in names else None
    full_names = model.param_names

    def pvecs(x: np.ndarray) -> list[np.ndarray]:
        base = dict(fixed)
        base.update(zip(names, x[: len(names)], strict=True))
        out = []
        for i in range(len(ys)):
            vals = dict(base)
            if k_name is not None and q:
                p = model.param(name)
                v = vals[name] + float(design[i] @ x[len(names) : len(names) + q])
                vals[name] = min(max(v, p.min), p.max)
            out.append(np.array([vals[n] for n in full_names]))
        return out

    def resid(x: np.ndarray) -> np.ndarray:
        outs = sims.outputs(model, pvecs(x))
        if post is not None:
            post.param = float(x[-1])  # type: ignore[attr-defined]
            outs = mapped_outputs(post, outs)
        r = np.concatenate([y - o for y, o in zip(ys, outs, strict=True)])
        return np.nan_to_num(r, nan=1e3, posinf=1e3, neginf=-1e3)

    sol = least_squares(resid, xs, bounds=(lo_all, hi_all), x_scale=xscale, max_nfev=max_nfev)
    if solution is not None:
        solution.append(sol)
    r = resid(sol.x)
    cuts = np.cumsum([y.size for y in ys])[:-1]
    base = dict(fixed)
    base.update(zip(names, sol.x[: len(names)], strict=True))
    ex = float(sol.x[-1]) if extra is not None else None
    return np.split(r, cuts), base, sol.x[len(names) : len(names) + q], ex


def session_chains(trials: Sequence[TrialData]) -> list[list[int]]:
    """The trials in chains: each trial that continues a session joins the one before it.

    A sensor's map with a memory (a filter, a channel's delay) runs over a session as over
    one record: a trial that continues one starts on its thrust step, and what the sensor
    shows there depends on what came just before.

    Parameters
    ----------
    trials : sequence of TrialData
        In recording order.

    Returns
    -------
    list of list of int
        Trial indices, each chain in order; a trial that starts at rest is a chain's head.
    """
    out: list[list[int]] = []
    for k, td in enumerate(trials):
        if out and td.continues and trials[k - 1].source == td.source:
            out[-1].append(k)
        else:
            out.append([k])
    return out


def mapped_outputs(
    post: Callable[[int, np.ndarray], np.ndarray], outs: list[np.ndarray]
) -> list[np.ndarray]:
    """Each trial's simulated output through the sensor's map ``post(i, y)``.

    A map with a ``chains`` attribute (:func:`session_chains`) is given each chain's
    outputs joined, as ``post(head, y)``, and its result is cut back into the trials'.

    Parameters
    ----------
    post : callable
        The map.
    outs : list of numpy.ndarray
        Each trial's output.

    Returns
    -------
    list of numpy.ndarray
    """
    chains = getattr(post, "chains", None)
    if chains is None:
        return [post(i, o) for i, o in enumerate(outs)]
    mapped: list[np.ndarray] = list(outs)
    for chain in chains:
        joined = post(chain[0], np.concatenate([outs[j] for j in chain]))
        cuts = np.cumsum([outs[j].size for j in chain])[:-1]
        for j, part in zip(chain, np.split(joined, cuts), strict=True):
            mapped[j] = part
    return mapped


def held(match: MatchResult) -> dict[str, float]:
    """The parameters a fit held (not fitted).

    Parameters
    ----------
    match : MatchResult
        A fit.

    Returns
    -------
    dict of str to float
    """
    return {n: p.value for n, p in match.parameters.items() if not p.vary}


def ar_coefficients(acf: Sequence[float], n: int) -> tuple[float, float]:
    """AR(2) coefficients from the lag-1 and lag-2 autocorrelation (Yule-Walker).

    Parameters
    ----------
    acf : sequence of float
        Autocorrelation at lags 1, 2, ... of the resting noise.
    n : int
        Samples it was measured on; a lag-one correlation within 3 / sqrt(n) of 0 is
        taken as white noise.

    Returns
    -------
    tuple of float
    """
    if len(acf) < 2 or n <= 0 or abs(acf[0]) < 3.0 / np.sqrt(n):
        return 0.0, 0.0
    r1, r2 = float(acf[0]), float(acf[1])
    den = 1.0 - r1 * r1
    if den <= 1e-6:
        return min(r1, 0.99), 0.0
    return r1 * (1.0 - r2) / den, (r2 - r1 * r1) / den


def whitened_rss(parts: Sequence[np.ndarray], ar: tuple[float, float]) -> tuple[float, int]:
    """RSS and samples of residuals prewhitened trial by trial with AR(2) coefficients.

    Every sample counts, a trial's first two by the exact start of the AR(2) likelihood
    (:func:`_startup_weights`): a trial that continues a session starts on its step, and
    a late channel shows in those samples first.

    Parameters
    ----------
    parts : sequence of numpy.ndarray
        Residuals, one array per trial.
    ar : tuple of float
        ``(phi1, phi2)``.

    Returns
    -------
    tuple
    """
    p1, p2 = ar
    start = _startup_weights(p1, p2)
    rss, n = 0.0, 0
    for r in parts:
        if r.size < 3:
            continue
        e = r[2:] - p1 * r[1:-1] - p2 * r[:-2]
        rss += float(e @ e)
        n += e.size
        if start is not None:
            # a trial's first two samples, whitened exactly (those of a trial that
            # continues a session sit on its step: its timing is read there)
            w0, rho1, w1 = start
            rss += float((w0 * r[0]) ** 2 + (w1 * (r[1] - rho1 * r[0])) ** 2)
            n += 2
    return rss, n


def _startup_weights(p1: float, p2: float) -> tuple[float, float, float] | None:
    """How an AR(2) series' first two samples are whitened: ``e0 = w0 r0`` and
    ``e1 = w1 (r1 - rho1 r0)`` (the exact Gaussian likelihood's start, the Cholesky
    factor of the stationary covariance of ``r0, r1`` in innovation units).

    Returns None for a non-stationary pair (those samples are then left out).
    """
    den = (1.0 + p2) * ((1.0 - p2) ** 2 - p1 * p1)
    if abs(p2) >= 1.0 or den <= 1e-9:
        return None
    gamma0 = (1.0 - p2) / den  # the marginal variance over the innovation's
    rho1 = p1 / (1.0 - p2)
    if gamma0 <= 0 or abs(rho1) >= 1.0:
        return None
    return float(np.sqrt(1.0 / gamma0)), float(rho1), float(np.sqrt(1.0 / (gamma0 * (1 - rho1**2))))


def current(inp: ArenaInput) -> tuple[float, int, int]:
    """Whitened RSS, samples and fitted parameters of the current fit.

    Parameters
    ----------
    inp : ArenaInput
        The current fit and the resting noise's colour.

    Returns
    -------
    (float, int, int)
    """
    r = inp.match.residual
    parts = [r[sl] for sl in inp.match.data.slices()]
    rss, n = whitened_rss(parts, inp.ar)
    k = len([n for n in inp.match.model.param_names if n not in held(inp.match)])
    return rss, n, k


def score(inp: ArenaInput, parts: Sequence[np.ndarray], k_extra: int) -> tuple[float, float]:
    """The arena's criterion: the fall of BIC on prewhitened residuals, and the RMSE.

    Every generator scores its fits with this (a discovered term too).

    Parameters
    ----------
    inp : ArenaInput
        The current fit (its residual is the reference).
    parts : sequence of numpy.ndarray
        The explanation's residuals, one array per trial, in the trials' order.
    k_extra : int
        Parameters it fits beyond the current model.

    Returns
    -------
    delta_bic : float
        Positive when the explanation is better.
    rmse : float
        Its RMSE (m/s^2).
    """
    rss0, n, k = current(inp)
    rss, _ = whitened_rss(parts, inp.ar)
    raw = float(sum(float(p @ p) for p in parts))
    size = int(sum(p.size for p in parts))
    d = bic(rss0, n, k) - bic(rss, n, k + k_extra)
    return float(d), float(np.sqrt(raw / max(size, 1)))


def run_index(runs: Sequence[str]) -> np.ndarray:
    """Each trial's run number (0, 1, ...), in order of first appearance.

    Parameters
    ----------
    runs : sequence of str
        Each trial's run (its source).

    Returns
    -------
    numpy.ndarray
        Integer run numbers.
    """
    order: dict[str, int] = {}
    return np.array([order.setdefault(r, len(order)) for r in runs])


def is_null(refit: MatchResult, effect: str) -> bool:
    """Whether an added effect's own parameters sit where the effect does nothing.

    A parameter whose lower bound is 0 (dead time, friction, a rate) and that ended
    within 1e-6 of its own scale from 0 does nothing; so does a ``bias`` of 0. The scale
    is the parameter's default start value (its range when that is 0), never the range
    alone: bounds are wide to fit any balancer (friction up to 1e5 N), and 1e-6 of them
    (0.1 N) is a light balancer's whole friction.

    Parameters
    ----------
    refit : MatchResult
        The fit with the effect.
    effect : str
        The effect's name.

    Returns
    -------
    bool
    """
    try:
        cls = refit.model.registry[effect]
    except Exception:
        return False
    own = [p for p in cls.parameters]
    if not own:
        return False
    values = refit.values()
    for p in own:
        v = values.get(p.name)
        if v is None:
            return False
        span = max(abs(p.max - p.min), 1e-12) if np.isfinite(p.max - p.min) else 1.0
        scale = abs(p.value) if p.value != 0 and np.isfinite(p.value) else span
        at_zero = abs(v) <= 1e-6 * scale
        if not (at_zero and (p.min == 0.0 or p.min < 0 < p.max)):
            return False
    return True


#: An added offset of the measured acceleration is no finding within this many standard
#: errors of the zero it is measured against (its own and the resting level's).
ZERO_Z = 3.0


def zero_stderr(match: MatchResult) -> float:
    """The standard error of the acceleration's zero: the level removed at rest.

    Gravity (or the local level at rest) is removed as read over the log's first
    stretch of rest; its error stays in every sample as an offset. Estimated from the
    residual at rest before each run's first step: its spread over the resting samples
    (widened by the fit's residual correlation time), the runs' levels averaged.

    Parameters
    ----------
    match : MatchResult
        The fit.

    Returns
    -------
    float
        0 when no trial starts from rest.
    """
    tau = max(float(match.metrics.get("residual_tau", 1.0)), 1.0)
    seen: dict[str, float] = {}
    for td, rest, _ in residual_around_steps(match):
        if td.source in seen:
            continue
        if rest.size >= 5:
            seen[td.source] = float(np.var(rest)) * tau / rest.size
    if not seen:
        return 0.0
    return float(np.sqrt(sum(seen.values())) / len(seen))


def within_sensor_zero(refit: MatchResult, effect: str, se_zero: float) -> bool:
    """Whether an added effect is an offset of the measured acceleration (its parameters
    in m/s^2) that stays within :data:`ZERO_Z` standard errors of the zero: the
    resting level's error, not a finding (a clean log's local gravity read over a
    second of rest is off by about 0.001 m/s^2, which a long precise log's refit
    separates from 0 by 7 of its own standard errors).

    Parameters
    ----------
    refit : MatchResult
        The fit with the effect.
    effect : str
        The effect's name.
    se_zero : float
        The zero's standard error (:func:`zero_stderr`).

    Returns
    -------
    bool
    """
    try:
        own = list(refit.model.registry[effect].parameters)
    except Exception:
        return False
    if not own or any(p.unit != "m/s^2" for p in own):
        return False
    for p in own:
        est = refit.parameters.get(p.name)
        if est is None:
            return False
        se = est.stderr if est.stderr is not None and np.isfinite(est.stderr) else 0.0
        if abs(est.value) > ZERO_Z * float(np.hypot(se, se_zero)):
            return False
    return True


def fit_in_threads(
    jobs: Sequence[Job], fit_one: Callable[[Job], Explanation], threads: int | None
) -> list[Explanation]:
    """``fit_one`` over ``jobs``, the first in this thread (it loads the kernel), the rest in
    threads (the kernels release the GIL); results in the jobs' order.

    Parameters
    ----------
    jobs : sequence
        The fits' arguments.
    fit_one : callable
        Fits one job.
    threads : int or None
        Fits at once; None: one per core.

    Returns
    -------
    list of Explanation
    """
    if not jobs:
        return []
    first = fit_one(jobs[0])
    n = min(len(jobs) - 1, threads or os.cpu_count() or 1)
    if n <= 1:
        return [first, *(fit_one(job) for job in jobs[1:])]
    with ThreadPoolExecutor(n, thread_name_prefix="balancer-id-arena") as pool:
        return [first, *pool.map(fit_one, jobs[1:])]


def independence(match: MatchResult) -> float:
    """Effective share of independent samples in a fit's residual, ``(1 - r1) / (1 + r1)``.

    Parameters
    ----------
    match : MatchResult
        A fit; ``r1`` is the lag-one autocorrelation of its residual, averaged over trials.

    Returns
    -------
    float
        1 for a white residual, smaller for a correlated one (at least 0.05).
    """
    r1s, weights = [], []
    for sl in match.data.slices():
        r = match.residual[sl]
        r = r - np.mean(r)
        denom = float(r @ r)
        if r.size > 10 and denom > 0:
            r1s.append(float(r[:-1] @ r[1:]) / denom)
            weights.append(r.size)
    if not r1s:
        return 1.0
    r1 = max(float(np.average(r1s, weights=weights)), 0.0)
    return float(min(max((1.0 - r1) / (1.0 + r1), 0.05), 1.0))


def excess_drop(rmse_before: float, rmse_after: float, noise_floor: float) -> float:
    """Share of the error above the noise floor that a change removes.

    ``(rmse_before^2 - rmse_after^2) / (rmse_before^2 - min(floor, rmse_after)^2)``: the
    floor is capped at the new RMSE, so a floor estimated a little too high (it is itself
    noisy) cannot hide a real improvement.

    Parameters
    ----------
    rmse_before : float
        RMSE of the acceleration before the change (m/s^2).
    rmse_after : float
        RMSE after the change (m/s^2).
    noise_floor : float
        White noise level of the acceleration (m/s^2).

    Returns
    -------
    float
        The share removed, at most 1 and at least -10 (a change for the worse); 0 when
        there is no error above the floor.
    """
    floor = min(noise_floor, rmse_after)
    denom = rmse_before**2 - floor**2
    if denom <= 0:
        return 0.0
    return float(max(min((rmse_before**2 - rmse_after**2) / denom, 1.0), -10.0))


def valid(e: Explanation, tests_failed: bool = False) -> bool:
    """Whether an explanation has a benefit, by its kind's rule
    (:meth:`~balancer_id.diagnostics.explanations.base.ExplanationKind.valid`).

    Parameters
    ----------
    e : Explanation
    tests_failed : bool
        Whether a test an adequate verdict must pass failed.

    Returns
    -------
    bool
    """
    return e.explainer.valid(e, tests_failed, BIC_THRESHOLD, MIN_EXCESS_DROP)


def standing(explanations: Sequence[Explanation], tests_failed: bool) -> list[Explanation]:
    """The valid explanations, best first; a pair only when it beats both its parts by
    :data:`BIC_THRESHOLD`.

    Parameters
    ----------
    explanations : sequence of Explanation
    tests_failed : bool

    Returns
    -------
    list of Explanation
    """
    by_label = {e.label: e for e in explanations}
    out = []
    for e in explanations:
        if not valid(e, tests_failed):
            continue
        parts = e.explainer.parts(e, by_label)
        if parts and min(e.delta_bic - p for p in parts) <= BIC_THRESHOLD:
            continue
        out.append(e)
    out = [e for e in out if not any(x.explainer.absorbs(x, e) for x in out if x is not e)]
    return sorted(out, key=lambda e: -e.delta_bic)
