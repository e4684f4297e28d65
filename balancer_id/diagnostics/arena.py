"""One arena of explanations: every explanation is a fitted model scored by one criterion.

An explanation of what the current model misses is a model fitted to the same trials:
a library effect added (the candidate refits of :mod:`~balancer_id.diagnostics.diagnosis`),
one parameter split at a run boundary (a payload hooked on, a setting changed), one
parameter drifting linearly over the runs (oil warming), the sensor's own low-pass filter
(its cut-off started from the resting noise's spectrum), or a pair (the best effect plus
the best split or drift refitted on top of it). Each is scored by the same criterion:
the fall of BIC against the current fit, scaled by the effective share of independent
samples (:func:`~balancer_id.diagnostics.diagnosis.independence`). The verdict comes
from the best; a close runner-up of another kind, or a split that coincides with the
direction or the thrust level of the runs, is said with it.

The arena is open: :data:`GENERATORS` is a list of functions ``(ArenaInput) ->
list[Explanation]``; another generator (the discovered terms of ``discovery``) joins by
appending itself.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from balancer_id.identify.data import FitData, TrialData
from balancer_id.identify.matching import MatchResult
from balancer_id.model.spec import Model

#: Kinds of explanation, and the verdict each leads to.
VERDICT_OF = {
    "effect": "effect missing",
    "discovered": "effect missing",
    "split": "parameter changed",
    "drift": "parameter drift",
    "sensor": "sensor effect",
    "pair": "parameter changed",
}
#: Parameters of the split and drift explanations must move by at least this share.
MIN_RELATIVE_CHANGE = 0.03
#: Function evaluations of a refinement (:attr:`Explanation.refine`); the first fits of
#: the arena stop at 60, enough to rank them, not always to tell two close ones apart.
REFINE_NFEV = 300


@dataclass
class Explanation:
    """One fitted explanation of what the current model misses.

    Attributes
    ----------
    kind : str
        ``effect``, ``split``, ``drift``, ``sensor``, ``pair`` or ``discovered``.
    label : str
        Short name (``+karnopp``, ``m_a split after run 3``, ``D0 drifting over the runs``,
        ``sensor low-pass 6.1 Hz``).
    delta_bic : float
        Fall of BIC against the current fit, scaled by the share of independent samples
        (positive: better).
    rmse : float
        RMSE of its fit (m/s^2).
    effects : list of str
        Library effects it adds.
    parameters : list of str
        Parameters it lets change (split, drift).
    detail : dict
        Its fitted values (``before``/``after``, ``start``/``end``, ``cutoff_hz`` ...).
    excess_drop : float
        Share of the error above the noise floor it removes.
    null : bool
        Its added parameter sits at the value that does nothing (dead time 0, friction 0):
        no benefit, never a verdict nor a step of ``improve``.
    """

    kind: str
    label: str
    delta_bic: float
    rmse: float
    effects: list[str] = field(default_factory=list)
    parameters: list[str] = field(default_factory=list)
    detail: dict[str, object] = field(default_factory=dict)
    excess_drop: float = 0.0
    null: bool = False
    #: Share of the BIC fall a perfect model would bring (:meth:`ArenaInput.available`).
    share: float | None = None
    #: Refits it from where it ended with more iterations (the arena's fits are capped
    #: for speed); None when it cannot be refined. Returns the refined explanation.
    refine: Callable[[], Explanation] | None = field(default=None, repr=False, compare=False)

    @property
    def verdict(self) -> str:
        """The verdict this explanation leads to."""
        if self.kind == "pair" and self.detail.get("drift"):
            return "parameter drift"
        return VERDICT_OF.get(self.kind, "effect missing")

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md ``diagnose`` ``explanations`` record."""
        return {
            "kind": self.kind,
            "label": self.label,
            "verdict": self.verdict,
            "delta_bic": self.delta_bic,
            "rmse_after": self.rmse,
            "excess_error_drop": self.excess_drop,
            "share_of_excess": self.share,
            "effects": list(self.effects),
            "parameters": list(self.parameters),
            "detail": self.detail,
        }


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

    def available(self) -> float | None:
        """The BIC fall a perfect model would bring (the current whitened excess), or None."""
        if not self.rest_innovation or self.rest_innovation <= 0:
            return None
        rss0, n, _ = _current(self)
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


class _Trials:
    """The trials simulated one by one (each may have its own parameter vector)."""

    def __init__(self, trials: Sequence[TrialData]) -> None:
        self.data = [FitData.build([td]) for td in trials]
        self.n = int(sum(d.y.size for d in self.data))

    def outputs(self, model: Model, pvecs: Sequence[np.ndarray]) -> list[np.ndarray]:
        return [d.packed.run(model, p)[:, 0] for d, p in zip(self.data, pvecs, strict=True)]


def _fit_varying(
    model: Model,
    sims: _Trials,
    start: dict[str, float],
    fixed: dict[str, float],
    name: str,
    design: np.ndarray,
    post: Callable[[int, np.ndarray], np.ndarray] | None = None,
    extra: tuple[float, float, float] | None = None,
    c_start: np.ndarray | None = None,
    max_nfev: int = 60,
) -> tuple[list[np.ndarray], dict[str, float], np.ndarray, float | None]:
    """Least squares of ``model`` where ``name = base + c * design[i]`` in trial ``i``.

    ``post(i, y)`` (optional) transforms each trial's simulated output, with one extra
    parameter ``extra = (start, lo, hi)`` passed as ``post.param``. Returns the RSS, the
    fitted base values, the coefficient(s) and the extra parameter.
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
            outs = [post(i, o) for i, o in enumerate(outs)]
        r = np.concatenate([y - o for y, o in zip(ys, outs, strict=True)])
        return np.nan_to_num(r, nan=1e3, posinf=1e3, neginf=-1e3)

    sol = least_squares(resid, xs, bounds=(lo_all, hi_all), x_scale=xscale, max_nfev=max_nfev)
    r = resid(sol.x)
    cuts = np.cumsum([y.size for y in ys])[:-1]
    base = dict(fixed)
    base.update(zip(names, sol.x[: len(names)], strict=True))
    ex = float(sol.x[-1]) if extra is not None else None
    return np.split(r, cuts), base, sol.x[len(names) : len(names) + q], ex


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
    rss, n = 0.0, 0
    for r in parts:
        if r.size < 3:
            continue
        e = r[2:] - p1 * r[1:-1] - p2 * r[:-2]
        rss += float(e @ e)
        n += e.size
    return rss, n


def _current(inp: ArenaInput) -> tuple[float, int, int]:
    """Whitened RSS, samples and fitted parameters of the current fit."""
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
    rss0, n, k = _current(inp)
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


def split_and_drift(inp: ArenaInput) -> list[Explanation]:
    """Each parameter split at each run boundary, and drifting linearly over the runs.

    Parameters
    ----------
    inp : ArenaInput
        The current fit and its trials.

    Returns
    -------
    list of Explanation
        One per (parameter, boundary) with two runs at least on each side, and one drift
        per parameter; needs four runs.
    """
    return _split_and_drift(inp, inp.match.model, inp.match.values(), "", [])


def _split_and_drift(
    inp: ArenaInput,
    model: Model,
    start: dict[str, float],
    prefix: str,
    effects: list[str],
    k_base: int = 0,
    bic_base: float = 0.0,
) -> list[Explanation]:
    run = run_index(inp.runs)
    n_runs = int(run.max()) + 1 if run.size else 0
    if n_runs < 4:
        return []
    sims = _Trials(inp.trials)
    fixed = {k: v for k, v in held(inp.match).items() if k in model.param_names}
    free = [n for n in model.param_names if n not in fixed]

    def fit_one(
        name: str,
        k: int | None,
        begin: dict[str, float],
        c_start: np.ndarray | None,
        nfev: int,
    ) -> Explanation:
        """The split of ``name`` after run ``k`` (None: its drift), fitted from ``begin``."""
        if k is None:
            design = (run / max(n_runs - 1, 1)).astype(float)[:, None]
        else:
            design = (run >= k).astype(float)[:, None]
        parts, base, c, _ = _fit_varying(
            model, sims, begin, fixed, name, design, c_start=c_start, max_nfev=nfev
        )
        one, two = base[name], base[name] + float(c[0])
        rel = abs(two - one) / max(abs(one), abs(two), 1e-300)
        d, rmse = score(inp, parts, 1 + k_base)
        if k is None:
            e = Explanation(
                "pair" if prefix else "drift",
                f"{prefix}{name} drifting over the runs",
                d + bic_base,
                rmse,
                list(effects),
                [name],
                {"first_run": one, "last_run": two, "relative_change": rel, "drift": True},
                null=rel < MIN_RELATIVE_CHANGE,
            )
        else:
            e = Explanation(
                "pair" if prefix else "split",
                f"{prefix}{name} changes after run {k}",
                d + bic_base,
                rmse,
                list(effects),
                [name],
                {
                    "split_after_run": k,
                    "before": one,
                    "after": two,
                    "relative_change": rel,
                    "group_by": f"runs:1-{k},{k + 1}-{n_runs}",
                    "n_samples": sims.n,
                },
                null=rel < MIN_RELATIVE_CHANGE,
            )
        e.refine = lambda: fit_one(name, k, base, c, REFINE_NFEV)
        return e

    jobs: list[tuple[str, int | None]] = [
        (name, k) for name in free for k in [*range(2, n_runs - 1), None]
    ]
    if not jobs:
        return []
    # the first in this thread (it loads the kernel), the rest in threads: the kernels
    # release the GIL, and each fit allocates its own outputs (results in the jobs' order)
    first = fit_one(*jobs[0], start, None, 60)
    threads = min(len(jobs) - 1, inp.threads or os.cpu_count() or 1)
    if threads <= 1:
        return [first, *(fit_one(name, k, start, None, 60) for name, k in jobs[1:])]
    with ThreadPoolExecutor(threads, thread_name_prefix="balancer-id-arena") as pool:
        rest = list(pool.map(lambda job: fit_one(*job, start, None, 60), jobs[1:]))
    return [first, *rest]


def _butter2(cutoff: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients of a 2nd-order Butterworth low-pass (bilinear, prewarped)."""
    w = np.tan(np.pi * min(cutoff, 0.45 * fs) / fs)
    k = np.sqrt(2.0)
    a0 = 1 + k * w + w * w
    b = np.array([w * w, 2 * w * w, w * w]) / a0
    a = np.array([1.0, (2 * w * w - 2) / a0, (1 - k * w + w * w) / a0])
    return b, a


def lowpass(y: np.ndarray, cutoff: float, fs: float) -> np.ndarray:
    """``y`` through a 2nd-order Butterworth low-pass, started at rest on its first value.

    Parameters
    ----------
    y : numpy.ndarray
        A signal sampled at ``fs``.
    cutoff : float
        -3 dB frequency (Hz).
    fs : float
        Sample rate (Hz).

    Returns
    -------
    numpy.ndarray
    """
    from scipy.signal import lfilter, lfilter_zi

    b, a = _butter2(cutoff, fs)
    return lfilter(b, a, y, zi=lfilter_zi(b, a) * y[0])[0]


#: A rest spectrum is a sensor filter's when a 2nd-order low-pass fits its log this many
#: times better (sum of squares) than AR(1) colour does.
FILTER_EVIDENCE = 4.0


def rest_spectrum(trials: Sequence[TrialData], fs: float) -> dict[str, float] | None:
    """The resting noise's averaged spectrum against two shapes: a filter's and AR(1)'s.

    The resting samples before each onset are cut into 64-sample segments (a step of 16;
    slope removed, Hann window); the log of their averaged periodogram (0 < f <= 0.45 fs)
    is fitted, up to a level, by a 2nd-order Butterworth low-pass (flat, then falling by
    40 dB per decade beyond its cut-off: a sensor's filter) and by AR(1) noise (falling
    gently, by at most 20 dB per decade: colour that is not a filter of the signal, such
    as the environment's), each over a grid of its one parameter.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials.
    fs : float
        Sample rate (Hz).

    Returns
    -------
    dict or None
        ``cutoff_hz`` and ``sse_filter`` of the low-pass, ``phi`` and ``sse_ar1`` of the
        AR(1), ``segments``; None with fewer than 4 segments.
    """
    n_seg = 64
    segs = []
    x = np.arange(n_seg) - (n_seg - 1) / 2
    for td in trials:
        t = td.time - td.t_step
        y = np.asarray(td.accel)[t < -0.02]
        for j in range(0, y.size - n_seg + 1, 16):
            seg = y[j : j + n_seg]
            segs.append(seg - np.polyval(np.polyfit(x, seg, 1), x))
    if len(segs) < 4:
        return None
    w = np.hanning(n_seg)
    p = np.mean(np.abs(np.fft.rfft(np.array(segs) * w, axis=1)) ** 2, axis=0)
    f = np.fft.rfftfreq(n_seg, 1.0 / fs)
    keep = (f > 0) & (f <= 0.45 * fs) & (p > 0)
    if keep.sum() < 6:
        return None
    lp, ff = np.log(p[keep]), f[keep]

    def sse(shape: np.ndarray) -> float:
        r = lp - shape
        r = r - r.mean()
        return float(r @ r)

    tf = np.tan(np.pi * ff / fs)
    cuts = np.geomspace(0.01 * fs, 0.45 * fs, 240)
    filt = [sse(-np.log1p((tf / np.tan(np.pi * c / fs)) ** 4)) for c in cuts]
    om = 2 * np.pi * ff / fs
    phis = np.linspace(0.0, 0.99, 199)
    ar = [sse(-np.log(1 + q * q - 2 * q * np.cos(om))) for q in phis]
    i, j = int(np.argmin(filt)), int(np.argmin(ar))
    return {
        "cutoff_hz": float(cuts[i]),
        "sse_filter": filt[i],
        "phi": float(phis[j]),
        "sse_ar1": ar[j],
        "segments": float(len(segs)),
    }


def rest_cutoff(trials: Sequence[TrialData], fs: float) -> float | None:
    """The cut-off of the sensor's low-pass the resting noise shows, or None.

    The resting noise is a filter's when a 2nd-order low-pass fits its spectrum
    :data:`FILTER_EVIDENCE` times better than AR(1) colour does and its cut-off lies
    below 0.3 fs (:func:`rest_spectrum`). White noise (no roll-off) and gently
    coloured noise give None.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials.
    fs : float
        Sample rate (Hz).

    Returns
    -------
    float or None
        The cut-off (Hz).
    """
    spec = rest_spectrum(trials, fs)
    if spec is None:
        return None
    steep = spec["sse_filter"] * FILTER_EVIDENCE < spec["sse_ar1"]
    return spec["cutoff_hz"] if steep and spec["cutoff_hz"] < 0.3 * fs else None


def sensor_lowpass(inp: ArenaInput) -> list[Explanation]:
    """The sensor's low-pass filter on the measured acceleration, when the rest noise shows one.

    The current model's output is passed through a 2nd-order Butterworth low-pass whose
    cut-off starts at the resting noise's and is fitted with the model's parameters; the
    same with the cut-off held at the resting noise's (no parameter added) is scored too,
    and the better by BIC is the explanation (``detail["cutoff_fitted"]`` says which).

    Parameters
    ----------
    inp : ArenaInput
        The current fit; ``rest_cutoff_hz`` None gives no explanation.

    Returns
    -------
    list of Explanation
    """
    fc0 = inp.rest_cutoff_hz
    if fc0 is None:
        return []
    model = inp.match.model
    sims = _Trials(inp.trials)
    dts = [float(np.median(np.diff(td.time))) for td in inp.trials]
    fss = [1.0 / dt for dt in dts]

    def post(i: int, y: np.ndarray) -> np.ndarray:
        return lowpass(y, post.param, fss[i])  # type: ignore[attr-defined]

    def measured(i: int, y: np.ndarray) -> np.ndarray:
        return lowpass(y, fc0, fss[i])

    fixed = held(inp.match)
    names = [n for n in model.param_names if n not in fixed]
    none = np.zeros((len(inp.trials), 0))
    parts, base, _, fc = _fit_varying(
        model,
        sims,
        inp.match.values(),
        fixed,
        names[0],
        none,
        post=post,
        extra=(fc0, 0.3 * fc0, min(4 * fc0, 0.45 * min(fss))),
    )
    d, rmse = score(inp, parts, 1)
    # the cut-off as measured at rest (no parameter fitted): when the response cannot
    # place the cut-off itself, the resting noise's is the estimate
    parts0, base0, _, _ = _fit_varying(
        model, sims, inp.match.values(), fixed, names[0], none, post=measured
    )
    d0, rmse0 = score(inp, parts0, 0)
    fitted = d > d0
    if not fitted:
        d, rmse, base, fc = d0, rmse0, base0, fc0
    return [
        Explanation(
            "sensor",
            f"sensor low-pass at {fc:.1f} Hz",
            d,
            rmse,
            [],
            [],
            {
                "cutoff_hz": fc,
                "rest_noise_cutoff_hz": fc0,
                "cutoff_fitted": fitted,
                "values": base,
            },
        )
    ]


def library_effects(inp: ArenaInput) -> list[Explanation]:
    """The library candidates' refits as explanations (scored as every other).

    Parameters
    ----------
    inp : ArenaInput
        The fit, its trials and the candidates' refits.

    Returns
    -------
    list of Explanation
        One per refitted library effect.
    """
    out = []
    for name, refit in inp.effect_fits:
        r = refit.residual
        k = len([n for n in refit.model.param_names if n not in held(refit)])
        _, _, k0 = _current(inp)
        d, rmse = score(inp, [r[sl] for sl in refit.data.slices()], k - k0)
        out.append(
            Explanation(
                "effect",
                f"+{name}",
                d,
                rmse,
                [name],
                [],
                {"values": refit.values()},
                null=is_null(refit, name),
            )
        )
    return out


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


def pairs(inp: ArenaInput, best_effect: Explanation, refit: MatchResult) -> list[Explanation]:
    """The best effect plus each split or drift, refitted on top of it.

    Parameters
    ----------
    inp : ArenaInput
        The current fit.
    best_effect : Explanation
        The best library effect.
    refit : MatchResult
        Its refit (the start of the pairs' fits).

    Returns
    -------
    list of Explanation
    """
    return _split_and_drift(
        inp,
        refit.model,
        refit.values(),
        f"{best_effect.label} and ",
        list(best_effect.effects),
        k_base=len(refit.model.param_names) - len(inp.match.model.param_names),
    )


def polish(inp: ArenaInput, best_effect: Explanation, refit: MatchResult) -> Explanation:
    """The best effect alone, refitted from its refit by the optimiser the pairs use.

    A pair counts only when it beats its effect alone; the pairs' fits start from the
    effect's refit and may end in a better optimum of the shared parameters than the
    refit found, a gain the split or drift did not bring. Fitted the same way, with more
    iterations and nothing split, the effect alone is the fair part to beat.

    Parameters
    ----------
    inp : ArenaInput
        The current fit.
    best_effect : Explanation
        The best library effect.
    refit : MatchResult
        Its refit (the start).

    Returns
    -------
    Explanation
        The effect alone, as fitted here.
    """
    model = refit.model
    fixed = {k: v for k, v in held(inp.match).items() if k in model.param_names}
    free = [n for n in model.param_names if n not in fixed]
    parts, base, _, _ = _fit_varying(
        model,
        _Trials(inp.trials),
        refit.values(),
        fixed,
        free[0],
        np.zeros((len(inp.trials), 0)),
        max_nfev=REFINE_NFEV,
    )
    d, rmse = score(inp, parts, len(model.param_names) - len(inp.match.model.param_names))
    return Explanation(
        "effect",
        best_effect.label,
        d,
        rmse,
        list(best_effect.effects),
        [],
        {"values": base},
        null=best_effect.null,
    )


#: Explanation generators: each takes the :class:`ArenaInput` and returns fitted
#: explanations. ``discovery`` (sparse regression on the residual) joins by appending.
GENERATORS: list[Callable[[ArenaInput], list[Explanation]]] = [
    library_effects,
    split_and_drift,
    sensor_lowpass,
]


def confound(e: Explanation, trials: Sequence[TrialData], runs: Sequence[str]) -> str | None:
    """How the recording confounds a split with the direction or the thrust level.

    Parameters
    ----------
    e : Explanation
        A split (or a pair with a split).
    trials : sequence of TrialData
        The trials.
    runs : sequence of str
        Each trial's run label.

    Returns
    -------
    str or None
        ``"direction"`` when every run before the split goes one way and every run after
        the other, ``"thrust level"`` when the two groups share no thrust level; None.
    """
    k = e.detail.get("split_after_run")
    if k is None:
        return None
    run = run_index(runs)
    before = [td for td, r in zip(trials, run, strict=True) if r < int(k)]
    after = [td for td, r in zip(trials, run, strict=True) if r >= int(k)]
    sb = {np.sign(td.thrust_N) for td in before}
    sa = {np.sign(td.thrust_N) for td in after}
    if len(sb) == 1 and len(sa) == 1 and sb != sa:
        return "direction"
    lb = {round(abs(td.thrust_N), 1) for td in before}
    la = {round(abs(td.thrust_N), 1) for td in after}
    if not (lb & la) and len(lb) == 1 and len(la) == 1:
        return "thrust level"
    return None


def record_hint(e: Explanation, how: str, trials: Sequence[TrialData]) -> str:
    """The trial to record that tells a confounded split from the effect it mimics.

    Parameters
    ----------
    e : Explanation
        The split (or drift) that is confounded.
    how : str
        ``"direction"`` or ``"thrust"``: what the split coincides with.
    trials : sequence of TrialData
        The trials, in recording order.

    Returns
    -------
    str
        The advice, one sentence.
    """
    if how == "direction":
        first = "up" if trials[0].thrust_N > 0 else "down"
        other = "down" if first == "up" else "up"
        return (
            f"record one {other} step before the {first} steps (or alternate up and down): "
            "a direction-dependent effect then shows in every group, a change between "
            "runs only after it"
        )
    return (
        "record the thrust levels in another order (or repeat the first level at the end): "
        "a thrust-dependent effect then shows at every time, a change between runs only "
        "after it"
    )
