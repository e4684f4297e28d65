"""Thrust onsets from the vertical acceleration alone (logs without a force channel).

The acceleration is split into rest and activity: a ``accel_window_s`` moving mean that
leaves the resting level by more than ``max(min_accel_step, accel_k_sigma * noise)`` is
active. The resting level is a long running median of the moving mean, refined by a
running median inside each rest stretch (so slow drift is followed). Active stretches
closer than ``merge_s`` are one. A trial is an active stretch that starts from rest and
lasts at least ``min_trial_s``; the stretch that follows it with the opposite sign and
lasts under ``max_catch_s`` is its catch (the person stopping the load), not a trial.
The onset is the start of the first-order rise that best fits the acceleration there.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from balancer_id.segment.robust import (
    block_noise,
    block_range,
    clipped_mean,
    fill_nan,
    n_samples,
    odd,
    rate_of,
)
from balancer_id.segment.steps import Detection, Step, StepSettings

#: Window (s) of the running median that gives the first resting baseline.
BASELINE_S = 30.0

#: Time constants (s) tried when placing the onset of a first-order rise.
_RISE_T = np.geomspace(0.1, 1.0, 25)

#: Highest rate (Hz) of the onset search; faster logs are searched on block means first.
SEARCH_HZ = 200


@dataclass(frozen=True)
class _Stretch:
    """An active stretch ``[start, stop)`` and the sign of its first part."""

    start: int
    stop: int
    sign: int
    reverses: bool


def detect_accel_steps(
    time: np.ndarray, accel: np.ndarray, breaks: np.ndarray, settings: StepSettings
) -> Detection:
    """Find thrust onsets from the vertical acceleration alone.

    Parameters
    ----------
    time, accel : numpy.ndarray
        Sample times (s) and vertical acceleration (m/s^2).
    breaks : numpy.ndarray
        First sample after each gap.
    settings : StepSettings
        Detector constants.

    Returns
    -------
    Detection
        Steps with ``source="accel"``, ``size`` NaN and ``response`` the change of the
        acceleration over the first ``response_s`` after the onset.
    """
    rate = rate_of(time)
    a = fill_nan(accel)
    n = a.size
    block = n_samples(settings.noise_block_s, rate, 5)
    sigma = block_noise(a, block, floor=1e-3)
    clip = max(5 * sigma, block_range(a, block))
    w = odd(n_samples(settings.accel_window_s, rate, 3))
    # a plain moving mean: a median filter would undo the dithering of a quantized signal
    mean = ndimage.uniform_filter1d(a, w, mode="nearest")
    noise = max(block_noise(mean, block, floor=1e-4), sigma / np.sqrt(w))
    thr = max(settings.min_accel_step, settings.accel_k_sigma * noise)
    rest = _resting_level(mean, thr, rate)
    det = Detection([], float(np.max(np.abs(mean - rest))) if n else 0.0, thr, "m/s^2")
    edges = np.concatenate([[0], breaks, [n]]).astype(int)
    for lo, hi in itertools.pairwise(edges):
        if hi - lo < 2 * w:
            continue
        stretches = _active(mean[lo:hi] - rest[lo:hi], thr, n_samples(settings.merge_s, rate))
        awaiting = 0  # sign of a trial not yet caught
        for st in stretches:
            start, stop = lo + st.start, lo + st.stop
            length = (stop - start) / rate
            if awaiting and st.sign == -awaiting and length < settings.max_catch_s:
                awaiting = 0
                det.reject("a catch")
                continue
            if start - lo < w or length < settings.min_trial_s:
                det.reject("too short or too close to a gap or the run's edge")
                continue  # a short stretch of an uncaught trial's sign is its motion
            # the mean leaves rest up to ~1 s after a slow, small rise begins
            k = rise_onset(time, a, lo, hi, start, n_samples(1.0, rate, 3))
            pre = a[max(lo, k - w) : k]
            post = a[k : min(hi, k + n_samples(settings.response_s, rate))]
            if pre.size < 3 or post.size < 3:
                det.reject("too close to a gap or the run's edge")
                continue
            dep = clipped_mean(post, clip) - clipped_mean(pre, clip)
            z = abs(dep) / (sigma * np.sqrt(1.0 / pre.size + 1.0 / post.size))
            det.steps.append(Step(int(k), float("nan"), float(dep), float(z), "accel"))
            awaiting = 0 if st.reverses else st.sign
    return det


def _resting_level(mean: np.ndarray, thr: float, rate: float) -> np.ndarray:
    """Resting level at every sample.

    A first baseline is the running median of the moving mean over ``BASELINE_S`` (on a
    10 Hz copy), which trials of a few seconds do not move. Quiet samples lie within
    ``thr`` of it; inside each quiet stretch the level is a running median over 5 s
    (drift is followed); an active sample keeps the level of the rest before it.
    """
    step = max(1, round(rate / 10))
    coarse = mean[::step]
    base = ndimage.median_filter(coarse, size=odd(max(3, round(BASELINE_S * 10))), mode="reflect")
    base = np.interp(np.arange(mean.size), np.arange(coarse.size) * step, base)
    labels, _ = ndimage.label(np.abs(mean - base) <= thr)
    out = np.full(mean.size, np.nan)
    span = n_samples(5.0, rate, 3)
    for sl in ndimage.find_objects(labels):
        seg = mean[sl]
        out[sl] = ndimage.median_filter(seg, size=min(seg.size, span), mode="nearest")
    have = np.flatnonzero(np.isfinite(out))
    if have.size == 0:
        return base
    last = np.maximum.accumulate(np.where(np.isfinite(out), np.arange(mean.size), -1))
    return out[np.where(last >= 0, last, have[0])]


def _active(dev: np.ndarray, thr: float, merge: int) -> list[_Stretch]:
    """Stretches where ``|dev| > thr``, those closer than ``merge`` samples joined."""
    labels, _ = ndimage.label(np.abs(dev) > thr)
    spans = ndimage.find_objects(labels)
    joined: list[list[int]] = []
    for sl in spans:
        start, stop = sl[0].start, sl[0].stop
        if joined and start - joined[-1][1] < merge:
            joined[-1][1] = stop
        else:
            joined.append([start, stop])
    out = []
    for start, stop in joined:
        seg = dev[start:stop]
        big = seg[np.abs(seg) > thr]
        sign = int(np.sign(big[0])) if big.size else 1
        out.append(_Stretch(start, stop, sign, bool(np.any(big * sign < 0))))
    return out


def rise_onset(time: np.ndarray, accel: np.ndarray, lo: int, hi: int, peak: int, w: int) -> int:
    """Onset of the first-order rise best fitting the acceleration near ``peak``.

    Fits ``b + A (1 - exp(-(t - t0)/T))`` (zero before ``t0``) by least squares for every
    candidate ``t0`` (a sample in ``[peak - w, peak + w/4]``) and every ``T`` of a grid
    over 0.1..1 s, over the samples from ``w/2`` before the earliest candidate to ``w``
    after ``peak``. Above :data:`SEARCH_HZ` the search runs on block means (at most
    :data:`SEARCH_HZ`) and is then refined at the full rate within one block of the
    coarse onset, so the cost grows linearly with the rate, not with its square.

    Parameters
    ----------
    time, accel : numpy.ndarray
        Sample times (s) and vertical acceleration (m/s^2).
    lo, hi : int
        Gap-free stretch ``[lo, hi)`` holding ``peak``.
    peak : int
        Centre of the search.
    w : int
        Half-width scale of the search (samples).

    Returns
    -------
    int
        Sample index of the onset.
    """
    k_lo, k_hi = max(lo + 2, peak - w), min(hi - 2, peak + w // 4)
    f_lo, f_hi = max(lo, k_lo - w // 2), min(hi, peak + w)
    t = time[f_lo:f_hi]
    y = accel[f_lo:f_hi] - accel[f_lo:f_hi].mean()
    # w spans ~1 s: blocks of `step` samples bring the search to at most SEARCH_HZ
    step = max(1, w // SEARCH_HZ)
    if step == 1 or k_hi - k_lo < 4 * step:
        ks = np.arange(k_lo, k_hi + 1)
        j, _ = _best_rise(t, y, time[ks], _RISE_T)
        return int(ks[j])
    nb = t.size // step
    tb = t[: nb * step].reshape(nb, step).mean(axis=1)
    yb = y[: nb * step].reshape(nb, step).mean(axis=1)
    first = f_lo + np.arange(nb) * step  # first sample of each block
    cand = np.flatnonzero((first >= k_lo) & (first <= k_hi))
    j, i_tau = _best_rise(tb, yb, time[first[cand]], _RISE_T)
    k = int(first[cand[j]])
    taus = _RISE_T[i_tau : i_tau + 1]
    while step > 1:  # refine within one block, ~10 candidates per stage
        stride = max(1, step // 10)
        ks = np.arange(max(k_lo, k - step), min(k_hi, k + step) + 1, stride)
        j, _ = _best_rise(t, y, time[ks], taus)
        k, step = int(ks[j]), stride if stride > 1 else 1
    return k


def _best_rise(t: np.ndarray, y: np.ndarray, t0: np.ndarray, taus: np.ndarray) -> tuple[int, int]:
    """Index of the onset ``t0`` and of the time constant with the least squared error."""
    lag = np.clip(t[None, :] - t0[:, None], 0.0, None)
    best = (np.inf, 0, 0)
    n, sy, yy = y.size, y.sum(), y @ y
    for i, tau in enumerate(taus):
        rise = -np.expm1(-lag / tau)  # (candidates, samples)
        # least squares on [1, rise]: closed form of the 2x2 normal equations per row
        s1, s2 = rise.sum(axis=1), (rise * rise).sum(axis=1)
        ry = rise @ y
        det = n * s2 - s1 * s1
        ok = det > 1e-12
        b = np.where(ok, (s2 * sy - s1 * ry) / np.where(ok, det, 1.0), sy / n)
        amp = np.where(ok, (n * ry - s1 * sy) / np.where(ok, det, 1.0), 0.0)
        sse = yy - b * sy - amp * ry
        j = int(np.argmin(sse))
        if sse[j] < best[0]:
            best = (float(sse[j]), j, i)
    return best[1], best[2]
