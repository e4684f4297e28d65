"""Detect thrust steps in one recording: from the force channel, or from the acceleration.

Force: a difference of means over ``force_window_s`` before/after each sample of the
despiked force flags candidate steps above ``max(min_step_N, k * noise)``; each is placed
by a least-squares single change point and kept when the force is steady on both sides
(a step, not a catch's transient) and abrupt. The acceleration then confirms it (see
:func:`measure_responses`): its clipped mean over ``response_s`` after the onset must
differ from the level before by ``response_k_sigma`` times its noise; the sign of that
change is the motion's direction.

Without a force channel, :mod:`balancer_id.segment.accel_steps` finds the onsets.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from balancer_id.read.recording import Recording
from balancer_id.segment.robust import (
    before_after_means,
    block_noise,
    block_range,
    changepoint,
    clipped_mean,
    fill_nan,
    find_peaks,
    level,
    n_samples,
    odd,
    rate_of,
    spread,
)

#: A force step this many times the force channel's noise (measured on the log) stands
#: out of it: smaller ones are never reported, larger ones always are (issue 17: a light
#: balancer's small steps, tens of times the noise, are trials).
STEP_K_NOISE = 4.0
#: ... and at least this fraction of the run's largest change: a hand's force wandering
#: under a big step (a few tenths of it) is no step of its own.
STEP_FRACTION_OF_LARGEST = 0.1


@dataclass(frozen=True)
class StepSettings:
    """Tunable constants of the step detector (durations in s).

    Attributes
    ----------
    min_step_N : float
        Smallest force step reported (N) on top of the noise rule (0: the noise decides:
        a step of :data:`STEP_K_NOISE` times the force's noise is a trial).
    force_window_s : float
        Difference-of-means window on the force.
    despike_s : float
        Median pre-filter and smoothing kernel.
    level_window_s : float
        Windows before/after the onset over which step sizes and rest are measured.
    guard_before_s, guard_after_s : float
        Transients left out of those windows next to the onset.
    max_transition_s : float
        Longest time the force may spend between its two levels (a step is abrupt).
    accel_window_s : float
        Moving-mean window of the acceleration (logs without force).
    accel_k_sigma : float
        Activity threshold, in noise standard deviations of that mean.
    min_accel_step : float
        Smallest acceleration departure reported (m/s^2), logs without force.
    merge_s : float
        Active stretches closer than this are one (logs without force).
    min_trial_s : float
        Shortest active stretch taken as a trial (logs without force).
    max_catch_s : float
        Longest opposite stretch after a trial taken as its catch (logs without force).
    response_s : float
        Window after the onset over which the motion confirms a force step.
    response_k_sigma : float
        Confirmation threshold, in noise standard deviations of the level difference.
    response_weak_k_sigma : float
        Lower threshold for a response in the direction the run's other steps predict.
    noise_block_s : float
        Block length of the noise estimate.
    bridge_gap_s : float
        Gaps in the time column up to this long (a few dropped wireless samples) are
        bridged; longer ones split the run (no window, no filter crosses them).
    """

    min_step_N: float = 0.0
    force_window_s: float = 0.3
    despike_s: float = 0.05
    level_window_s: float = 0.5
    guard_before_s: float = 0.02
    guard_after_s: float = 0.1
    max_transition_s: float = 0.1
    accel_window_s: float = 0.5
    accel_k_sigma: float = 5.0
    min_accel_step: float = 0.02
    merge_s: float = 0.3
    min_trial_s: float = 0.6
    max_catch_s: float = 1.5
    response_s: float = 2.0
    response_k_sigma: float = 3.0
    response_weak_k_sigma: float = 2.0
    noise_block_s: float = 0.5
    bridge_gap_s: float = 0.1


@dataclass(frozen=True)
class Step:
    """One thrust step found in a recording.

    Attributes
    ----------
    onset : int
        Sample index of the onset.
    size : float
        Force step (N) in the sensor's sign, NaN when found from the acceleration.
    response : float
        Change of the vertical acceleration after the onset (m/s^2), NaN without accel.
    response_z : float
        ``|response|`` over its noise standard deviation (NaN without accel).
    source : str
        ``"force"`` or ``"accel"``.
    """

    onset: int
    size: float
    response: float
    response_z: float
    source: str


@dataclass
class Detection:
    """The steps of one recording, and what the detector saw (for error messages).

    Attributes
    ----------
    steps : list of Step
        Steps kept, in time order.
    largest : float
        Largest change seen by the detector (N or m/s^2).
    threshold : float
        The detection threshold (same unit).
    unit : str
        ``"N"`` (force) or ``"m/s^2"`` (acceleration).
    rejected : dict
        Reason -> number of candidates dropped for it.
    """

    steps: list[Step]
    largest: float
    threshold: float
    unit: str
    rejected: dict[str, int] = field(default_factory=dict)

    def reject(self, reason: str) -> None:
        """Count one candidate dropped for ``reason``.

        Parameters
        ----------
        reason : str
            Why the candidate step was dropped; a key of :attr:`rejected`, reported in
            the error message when no step is kept.
        """
        self.rejected[reason] = self.rejected.get(reason, 0) + 1


def gap_breaks(rec: Recording, bridge_s: float = 0.0) -> np.ndarray:
    """Indices of the first sample after each gap of ``rec`` (sorted, unique).

    Parameters
    ----------
    rec : Recording
        The run and its gaps.
    bridge_s : float, optional
        Gaps lasting at most this long (s) are bridged: no break.

    Returns
    -------
    numpy.ndarray
        Integer indices.
    """
    gaps = [gp for gp in rec.gaps if gp.t_after - gp.t_before > bridge_s]
    if not gaps:
        return np.zeros(0, dtype=int)
    after = np.array([gp.t_after for gp in gaps], dtype=float)
    idx = np.searchsorted(rec.time, after - 1e-9 * np.maximum(1.0, np.abs(after)))
    idx = idx[(idx > 0) & (idx < rec.time.size)]
    return np.unique(idx)


def segment_bounds(i: int, breaks: np.ndarray, n: int) -> tuple[int, int]:
    """The gap-free stretch ``[lo, hi)`` that holds sample ``i``.

    Parameters
    ----------
    i : int
        Index of a sample.
    breaks : numpy.ndarray
        First sample after each gap, sorted (see :func:`gap_breaks`).
    n : int
        Number of samples of the recording.

    Returns
    -------
    lo, hi : int
        First sample of the stretch and the sample just past its end.
    """
    j = int(np.searchsorted(breaks, i, side="right"))
    lo = int(breaks[j - 1]) if j > 0 else 0
    hi = int(breaks[j]) if j < breaks.size else n
    return lo, hi


def detect_force_steps(
    time: np.ndarray, force: np.ndarray, breaks: np.ndarray, settings: StepSettings
) -> Detection:
    """Find the steps of the operating force.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s).
    force : numpy.ndarray
        Force (N), sensor sign.
    breaks : numpy.ndarray
        First sample after each gap (see :func:`gap_breaks`).
    settings : StepSettings
        Detector constants.

    Returns
    -------
    Detection
        Steps with ``source="force"``; their responses are not measured yet
        (see :func:`measure_responses`).
    """
    rate = rate_of(time)
    f = fill_nan(force)
    n = f.size
    w = n_samples(settings.force_window_s, rate, 3)
    fm = ndimage.median_filter(f, size=odd(n_samples(settings.despike_s, rate)), mode="nearest")
    before, after = before_after_means(fm, w)
    # |mean after - mean before|, in place: one signal-long array, not three
    size_of_step = np.abs(
        np.nan_to_num(np.subtract(after, before, out=after), copy=False), out=after
    )
    del before
    sigma = block_noise(f, n_samples(settings.noise_block_s, rate, 5), floor=1e-3)
    largest = float(np.max(size_of_step)) if n else 0.0
    thr = max(
        settings.min_step_N,
        STEP_K_NOISE * sigma,
        6.0 * sigma * np.sqrt(2.0 / w),
        STEP_FRACTION_OF_LARGEST * largest,
    )
    det = Detection([], largest, thr, "N")
    peaks = find_peaks(size_of_step, thr, w)
    del size_of_step
    win = n_samples(settings.level_window_s, rate, 3)
    gb = n_samples(settings.guard_before_s, rate)
    ga = n_samples(settings.guard_after_s, rate)
    short = n_samples(0.1, rate, 3)
    prev = -(10**9)
    for p in peaks:
        lo, hi = segment_bounds(int(p), breaks, n)
        a0, b0 = max(lo, p - w), min(hi, p + w)
        if b0 - a0 < 4:
            det.reject("too close to a gap or the run's edge")
            continue
        k = a0 + changepoint(f[a0:b0])
        pre = f[max(lo, k - win, prev + ga) : k - gb]
        post = f[k + ga : min(hi, k + ga + win)]
        if pre.size < short and max(lo, k - win, prev + ga) == lo and post.size >= short:
            det.reject(short_rest_reason(time, lo, k, short + gb))
            continue
        if pre.size < short or post.size < short:
            det.reject("too close to a gap, the run's edge or another step")
            continue
        size = level(post) - level(pre)
        mag = abs(size)
        if mag < thr:
            det.reject("smaller than the threshold once settled")
            continue
        steady_pre = (
            spread(pre) <= 0.15 * mag + 3 * sigma
            and np.max(np.abs(pre - level(pre))) <= 0.5 * mag + 6 * sigma
        )
        steady_post = (
            spread(post) <= 0.3 * mag + 3 * sigma
            and np.max(np.abs(post - level(post))) <= mag + 6 * sigma
        )
        if not (steady_pre and steady_post):
            det.reject("force not steady around the change (a transient, not a step)")
            continue
        # between the two levels: farther than a quarter of the step and than the noise
        # from both (a small step's noise alone would read as a slow change)
        near = fm[max(lo, k - w) : min(hi, k + w)]
        band = 0.25 * mag + 1.5 * sigma
        between = (np.abs(near - level(pre)) > band) & (np.abs(near - level(post)) > band)
        if np.count_nonzero(between) > n_samples(settings.max_transition_s, rate) + 2:
            det.reject("force changed too slowly (a transient, not a step)")
            continue
        det.steps.append(Step(int(k), float(size), float("nan"), float("nan"), "force"))
        prev = int(k)
    _steps_at_starts(det, time, fm, breaks, w, short + gb, sigma)
    return det


def _steps_at_starts(
    det: Detection,
    time: np.ndarray,
    fm: np.ndarray,
    breaks: np.ndarray,
    w: int,
    need: int,
    sigma: float,
) -> None:
    """A step within ``need`` samples of the run's start or of a gap is dropped too.

    The difference of means needs a full window before a sample, so such a step is no
    candidate at all; it is counted here (its rest too short) so that a refusal says so.
    """
    n = fm.size
    for lo in [0, *(int(b) for b in breaks)]:
        hi = min(n, lo + 2 * w, *(int(b) for b in breaks if b > lo))
        if hi - lo < 2 * need or any(lo <= st.onset < hi for st in det.steps):
            continue
        seg = fm[lo:hi]
        k = changepoint(seg)
        mag = abs(level(seg[k:]) - level(seg[:k]))
        if k < need and mag >= det.threshold and spread(seg[k:]) <= 0.3 * mag + 3 * sigma:
            det.reject(short_rest_reason(time, lo, lo + k, need))


#: The start of the reason a step too close after the run's start or a gap is dropped.
SHORT_REST = "rest before the step"


def short_rest_reason(time: np.ndarray, lo: int, k: int, need: int) -> str:
    """Why a step right after the run's start (or a gap) is no trial: its rest is too short.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s).
    lo : int
        First sample of the gap-free stretch holding the step.
    k : int
        The step's sample.
    need : int
        Resting samples a step needs before it (the level's shortest stretch and the
        guard before the change).

    Returns
    -------
    str
        The reason, with how long the rest is and how long it needs to be (s).
    """
    dt = float(np.median(np.diff(time))) if time.size > 1 else 0.0
    have = float(time[k] - time[lo])
    where = "the run's start" if lo == 0 else "a gap"
    need_s = need * dt
    return f"{SHORT_REST} {have:.2g} s long (from {where}), under the {need_s:.2g} s a step needs"


def rest_start(k: int, lo: int, prev_onset: int | None, rate: float, lookback_s: float) -> int:
    """First sample of the stretch that gives the level a step at ``k`` starts from.

    Up to ``lookback_s`` back, within the gap-free stretch from ``lo``; after a previous
    step, not before it has had 1 s to rise (unless that leaves under 0.25 s).

    Parameters
    ----------
    k : int
        Onset index.
    lo : int
        First index of the gap-free stretch holding ``k``.
    prev_onset : int or None
        Onset index of the previous step of the run.
    rate : float
        Sample rate (Hz).
    lookback_s : float
        Longest stretch (s).

    Returns
    -------
    int
        Start index (``<= k``).
    """
    start = max(lo, k - n_samples(lookback_s, rate))
    if prev_onset is not None:
        settle = min(prev_onset + n_samples(1.0, rate), k - n_samples(0.25, rate))
        start = max(start, prev_onset, settle)
    return min(start, k)


def measure_responses(
    time: np.ndarray,
    accel: np.ndarray,
    steps: list[Step],
    breaks: np.ndarray,
    settings: StepSettings,
    limits: list[tuple[int, int]] | None = None,
) -> list[Step]:
    """Measure the change of vertical acceleration that follows each step.

    The clipped mean over ``response_s`` after the onset minus the clipped mean of the
    rest before it, with its noise from the log's noise and the window lengths. Without
    ``limits`` the stretches run to the next step or gap, and back up to
    ``3 * level_window_s`` (not past the previous step).

    Parameters
    ----------
    time, accel : numpy.ndarray
        Sample times (s) and vertical acceleration (m/s^2).
    steps : list of Step
        Steps in time order.
    breaks : numpy.ndarray
        First sample after each gap.
    settings : StepSettings
        Detector constants.
    limits : list of (int, int), optional
        Per step, the sample range ``[start, stop)`` of its trial window.

    Returns
    -------
    list of Step
        The steps with ``response`` and ``response_z`` filled.
    """
    rate = rate_of(time)
    a = fill_nan(accel)
    n = a.size
    block = n_samples(settings.noise_block_s, rate, 5)
    sigma = block_noise(a, block, floor=1e-3)
    clip = max(5 * sigma, block_range(a, block))
    resp_n = n_samples(settings.response_s, rate, 3)
    pre_s = 3 * settings.level_window_s
    out = []
    for i, st in enumerate(steps):
        k = st.onset
        lo, hi = segment_bounds(k, breaks, n)
        if limits is None:
            nxt = steps[i + 1].onset if i + 1 < len(steps) else n
            prev = steps[i - 1].onset if i else None
            start, stop = rest_start(k, lo, prev, rate, pre_s), min(nxt, hi)
        else:
            start, stop = limits[i]
        pre = a[start:k]
        post = a[k + 1 : min(k + resp_n, stop)]
        if pre.size < 3 or post.size < 3:
            out.append(Step(k, st.size, float("nan"), 0.0, st.source))
            continue
        resp = clipped_mean(post, clip) - clipped_mean(pre, clip)
        noise = sigma * np.sqrt(1.0 / pre.size + 1.0 / post.size)
        out.append(Step(k, st.size, float(resp), float(abs(resp) / noise), st.source))
    return out
