"""The analysis window of each step: rest before the onset, up to the next event.

The window starts up to ``rest_s`` before the onset, not before the previous step, a gap
or the last disturbance (a catch's transient); it ends at the first of: the next step, a
gap, the end of the run, or a catch. A catch is a transient the steps cannot explain:
the acceleration leaves its resting level by 2.5 times the step-driven level, or
reverses past minus its own plateau, or the force leaves its post-step level by more
than one step. The window ends where that transient began. (A catch found where the
next step begins is that step's own response: the window ends at the step.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from balancer_id.segment.robust import (
    block_noise,
    block_range,
    clipped_mean,
    fill_nan,
    level,
    local_std,
    n_samples,
    odd,
    rate_of,
    smooth,
)
from balancer_id.segment.steps import Step, StepSettings, rest_start, segment_bounds

#: Longest time (s) a catch is waited on to settle.
SETTLE_WITHIN_S = 20.0


@dataclass(frozen=True)
class Window:
    """Sample range ``[start, stop)`` of one trial and what ended it.

    ``settled`` is, after a catch, the first sample from which the signals are quiet
    again (None when no catch ended the trial); a step found before it is the catch's.
    ``rest_from`` is where the undisturbed stretch before the onset begins, looking back
    up to ``rest_lookback_s`` (it measures the level the step starts from).
    """

    start: int
    stop: int
    end_reason: str
    settled: int | None = None
    rest_from: int | None = None


@dataclass(frozen=True)
class Channel:
    """A channel, smoothed, with its noise: ``sigma`` of the samples, ``sigma_s`` of the
    smoothed signal, and ``clip``, the half-width of its clipped means."""

    raw: np.ndarray
    smooth: np.ndarray
    sigma: float
    sigma_s: float
    clip: float

    def level(self, lo: int, hi: int) -> float:
        """Clipped mean of the samples ``[lo, hi)``.

        Parameters
        ----------
        lo, hi : int
            Sample range, end excluded; a negative ``lo`` is taken as 0.

        Returns
        -------
        float
            The mean of the raw samples clipped to their median +- :attr:`clip` (N or
            m/s^2), NaN for an empty range.
        """
        return clipped_mean(self.raw[max(0, lo) : hi], self.clip)


def channel(x: np.ndarray | None, rate: float, settings: StepSettings) -> Channel | None:
    """Prepare a force or acceleration channel for windowing (None stays None).

    Parameters
    ----------
    x : numpy.ndarray or None
        The samples.
    rate : float
        Sample rate (Hz).
    settings : StepSettings
        Detector constants (smoothing kernel, noise blocks).

    Returns
    -------
    Channel or None
    """
    if x is None:
        return None
    raw = fill_nan(x)
    sm = smooth(raw, n_samples(settings.despike_s, rate))
    block = n_samples(settings.noise_block_s, rate, 5)
    sigma = block_noise(raw, block, 1e-3)
    clip = max(5 * sigma, block_range(raw, block))
    return Channel(raw, sm, sigma, block_noise(sm, block, 1e-4), clip)


def trial_windows(
    time: np.ndarray,
    fch: Channel | None,
    ach: Channel | None,
    steps: list[Step],
    signs: list[int],
    breaks: np.ndarray,
    settings: StepSettings,
    rest_s: float = 0.5,
    rest_lookback_s: float = 1.5,
) -> list[Window]:
    """Window every step of one recording.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s).
    fch, ach : Channel or None
        Force (N, sensor sign) and vertical acceleration (m/s^2, up positive), from
        :func:`channel`.
    steps : list of Step
        Steps in time order.
    signs : list of int
        Direction of each step, +1 up, -1 down.
    breaks : numpy.ndarray
        First sample after each gap.
    settings : StepSettings
        Detector constants.
    rest_s : float, optional
        Longest rest kept before the onset in the window (s).
    rest_lookback_s : float, optional
        Longest rest looked at before the onset to measure the starting level (s).

    Returns
    -------
    list of Window
        One per step.
    """
    n = time.size
    rate = rate_of(time)
    rest_n = n_samples(rest_s, rate)
    lookback_n = n_samples(rest_lookback_s, rate)
    # a catch this close after the next onset is that step's own response
    tol = odd(n_samples(settings.despike_s, rate)) // 2 + 2
    out: list[Window] = []
    rest_level, reference = 0.0, 0.0
    for i, st in enumerate(steps):
        k = st.onset
        lo, hi = segment_bounds(k, breaks, n)
        nxt = steps[i + 1].onset if i + 1 < len(steps) else n
        stop, reason = hi, ("gap" if hi < n else "end of run")
        if ach is not None:
            # a step taken while moving ("next step") keeps the rest level of its group
            chained = bool(out) and out[-1].end_reason == "next step"
            if not chained:
                rest_level, reference = ach.level(k - n_samples(0.5, rate), k), 0.0
            seg = ach.smooth[k + n_samples(0.1, rate) : min(nxt, hi, k + lookback_n)]
            driven = float(np.percentile(np.abs(seg - rest_level), 90)) if seg.size else 0.0
            reference = max(reference, driven)
        catch = _find_catch(
            k, hi, nxt, st, signs[i], fch, ach, rest_level, reference, rate, settings
        )
        settled = None
        if catch is not None and catch[0] < nxt - tol:
            stop, reason = catch[0], "catch"
            settled = _settled(catch[1], hi, fch, ach, rest_level, reference, rate)
        elif nxt < hi:
            stop, reason = nxt, "next step"
        rest_from = rest_start(k, lo, steps[i - 1].onset if i else None, rate, rest_lookback_s)
        if out and out[-1].settled is not None:
            rest_from = max(rest_from, out[-1].settled)
        rest_from = _after_disturbance(rest_from, k, st, fch, ach, rate, settings)
        start = max(rest_from, k - rest_n)
        out.append(Window(int(start), int(stop), reason, settled, int(rest_from)))
    return out


def _settled(
    c: int,
    hi: int,
    fch: Channel | None,
    ach: Channel | None,
    rest_level: float,
    reference: float,
    rate: float,
) -> int:
    """First sample after ``c`` (a catch's crossing) from which 0.3 s are quiet.

    Quiet: every channel's smoothed signal varies little, and the acceleration is back
    near its resting level (within half the step-driven level). Not quiet within
    ``SETTLE_WITHIN_S``: settled then.
    """
    q = n_samples(0.3, rate, 3)
    end = min(hi, c + n_samples(SETTLE_WITHIN_S, rate))
    quiet = np.ones(end - c, dtype=bool)
    for ch in (fch, ach):
        if ch is not None:
            sd = local_std(ch.smooth[c:end], q)
            quiet &= sd <= 2.5 * ch.sigma_s + 0.5 * ch.sigma
    if ach is not None:
        mean = ndimage.uniform_filter1d(ach.smooth[c:end], q, mode="nearest")
        quiet &= np.abs(mean - rest_level) <= 0.5 * reference + 3 * ach.sigma_s + ach.sigma
    hits = np.flatnonzero(quiet[q // 2 :])
    return c + int(hits[0]) if hits.size else end


def _find_catch(
    k: int,
    stop: int,
    nxt: int,
    st: Step,
    sign: int,
    fch: Channel | None,
    ach: Channel | None,
    rest_level: float,
    reference: float,
    rate: float,
    settings: StepSettings,
) -> tuple[int, int] | None:
    """Where a catch in ``(k, stop)`` begins and where it crosses its threshold, or None.

    Acceleration: ``|a - rest_level|`` beyond 2.5 times ``reference`` (the step-driven
    level of the trial and of the steps it follows while moving), or the acceleration
    change reversing past minus its own plateau. Force: more than one step away from
    the post-step level.
    """
    first = k + n_samples(0.2, rate)
    if first >= stop:
        return None
    # a catch is only used when it begins before the next onset; one that crosses more
    # than 1 s after it cannot walk back that far, so the search ends there (a long run
    # would otherwise be scanned to its end for every step)
    end = min(stop, nxt + n_samples(1.0, rate))
    run = n_samples(0.02, rate)
    found: list[tuple[int, int]] = []
    pre_n = n_samples(settings.level_window_s, rate)
    # everything below is on the slice [k, stop): indices relative to k
    if ach is not None:
        a = ach.smooth[k:end]
        x = sign * (a - ach.level(k - pre_n, k))
        seg = x[n_samples(0.1, rate) : min(stop, nxt, k + n_samples(1.5, rate)) - k]
        plateau = max(float(np.percentile(seg, 90)), 0.0) if seg.size else 0.0
        spike = np.abs(a - rest_level) > 2.5 * reference + 3 * ach.sigma
        reverse = x < -(plateau + 3 * ach.sigma)
        c = _first_run(spike | reverse, first - k, run)
        if c is not None:
            found.append((k + _walk_back(x, c, first - k, ach.sigma, rate), k + c))
    if fch is not None and np.isfinite(st.size):
        ga = n_samples(settings.guard_after_s, rate)
        y = fch.smooth[k:end] - fch.level(k + ga, min(stop, k + ga + pre_n))
        c = _first_run(np.abs(y) > abs(st.size) + 4 * fch.sigma, first - k, run)
        if c is not None:
            found.append((k + _walk_back(y, c, first - k, fch.sigma, rate), k + c))
    return min(found) if found else None


def _first_run(bad: np.ndarray, first: int, run: int) -> int | None:
    """First index from ``first`` on starting ``run`` consecutive True samples."""
    seg = bad[first:].astype(np.int64)
    if seg.size < run:
        return None
    counts = np.convolve(seg, np.ones(run, dtype=np.int64), mode="valid")
    hits = np.flatnonzero(counts == run)
    return first + int(hits[0]) if hits.size else None


def _walk_back(x: np.ndarray, c: int, first: int, sigma: float, rate: float) -> int:
    """Where the transient that crosses at ``c`` left its earlier level."""
    ref_lo = max(first, c - n_samples(0.5, rate))
    ref_hi = max(ref_lo + 1, c - n_samples(0.25, rate))
    ref = float(np.median(x[ref_lo:ref_hi])) if ref_hi > ref_lo else x[first]
    tol = max(3 * sigma, 0.25 * abs(x[c] - ref))
    j = c
    while j > first and abs(x[j - 1] - ref) > tol:
        j -= 1
    return j


def _after_disturbance(
    start: int,
    k: int,
    st: Step,
    fch: Channel | None,
    ach: Channel | None,
    rate: float,
    settings: StepSettings,
) -> int:
    """Move ``start`` past the last disturbed sample before the onset ``k``."""
    gb = n_samples(settings.guard_before_s, rate)
    ref_n = n_samples(0.2, rate)
    stop = max(start, k - gb)
    if stop - start < 2:
        return start
    disturbed = np.zeros(stop - start, dtype=bool)
    if ach is not None:
        seg = ach.smooth[start:stop]
        ref = ach.level(max(start, k - ref_n), k)
        resp = abs(st.response) if np.isfinite(st.response) else 0.0
        disturbed |= np.abs(seg - ref) > resp + 4 * ach.sigma
    if fch is not None and np.isfinite(st.size):
        seg = fch.smooth[start:stop]
        ref = fch.level(max(start, k - ref_n), stop)
        disturbed |= np.abs(seg - ref) > 0.5 * abs(st.size) + 4 * fch.sigma
    hits = np.flatnonzero(disturbed)
    return start + int(hits[-1]) + 1 if hits.size else start


def end_at_releases(
    time: np.ndarray,
    force: np.ndarray,
    steps: list[Step],
    windows: list[Window],
    settings: StepSettings,
) -> tuple[list[Step], list[Window], int]:
    """End trials where their thrust is released (logs without acceleration).

    Without acceleration a catch is seen in the force alone: a step taken while moving
    that brings the force back to its rest before the first step of the chain (the
    weight taken off as the load is caught) ends the trial before it, as its catch, and
    is no trial itself.

    Parameters
    ----------
    time, force : numpy.ndarray
        Sample times (s) and force (N).
    steps, windows : list
        Steps and their windows, in time order.
    settings : StepSettings
        Detector constants.

    Returns
    -------
    steps, windows : list
        Without the releases.
    dropped : int
        How many steps were releases.
    """
    rate = rate_of(time)
    win = n_samples(settings.level_window_s, rate)
    ga = n_samples(settings.guard_after_s, rate)
    gb = n_samples(settings.guard_before_s, rate)
    steps, windows = list(steps), list(windows)
    dropped = 0
    i = 1
    while i < len(steps):
        j = i - 1
        while j and windows[j - 1].end_reason == "next step":
            j -= 1  # first step of the chain that leads to step i
        if windows[i - 1].end_reason == "next step":
            k, k0 = steps[i].onset, steps[j].onset
            rest = level(force[windows[j].start : max(windows[j].start + 1, k0 - gb)])
            after = level(force[k + ga : k + ga + win])
            if abs(after - rest) < 0.25 * abs(steps[i - 1].size):
                prev = windows[i - 1]
                windows[i - 1] = Window(
                    prev.start, max(prev.start + 1, k - gb), "catch", None, prev.rest_from
                )
                del steps[i], windows[i]
                dropped += 1
                continue
        i += 1
    return steps, windows, dropped
