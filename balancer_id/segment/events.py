"""Every motion that stands out of a run's vertical acceleration, whatever the detector kept.

The step detector keeps onsets that look like thrusts (a new level after a step); a
user who gives one thrust per onset would fit fewer steps than the log holds when the
detector leaves a motion out (an elevator's braking as large as its start, the tenth of
ten lifts). :func:`standing_out` lists every stretch whose smoothed vertical
acceleration leaves the resting noise by far (8 robust standard deviations of the
quietest seconds) and reaches a quarter of the run's largest motion; the hint of a
refusal names those no onset accounts for.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from balancer_id.segment.robust import fill_nan, rate_of

#: A motion stands out beyond this many resting standard deviations ...
K_SIGMA = 8.0
#: ... and beyond this share of the run's largest motion (its 99.5th percentile).
SHARE_OF_LARGEST = 0.25
#: Motions closer than this (s) are one event; shorter than MIN_S are no event.
MERGE_S, MIN_S = 0.3, 0.05


@dataclass(frozen=True)
class Event:
    """One motion that stands out: where it starts, its peak time and size (m/s^2)."""

    t_start: float
    t_peak: float
    peak: float

    @property
    def text(self) -> str:
        """``"12.30 s (-1.1 m/s^2)"``."""
        return f"{self.t_start:.2f} s ({self.peak:+.2g} m/s^2)"


def standing_out(time: np.ndarray, accel: np.ndarray) -> list[Event]:
    """The motions of a vertical acceleration that stand out of its resting noise.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s).
    accel : numpy.ndarray
        Vertical acceleration (m/s^2), gravity removed; NaN filled.

    Returns
    -------
    list of Event
        In time order.
    """
    n = accel.size
    if n < 10 or not np.isfinite(accel).any():
        return []
    rate = rate_of(time)
    x = fill_nan(np.asarray(accel, dtype=float))
    width = max(1, round(0.1 * rate))
    smooth = np.convolve(x, np.ones(width) / width, mode="same")
    block = max(width, round(rate))  # 1-s blocks: the quietest quarter is the rest
    count = n // block
    if count < 2:
        return []
    blocks = smooth[: count * block].reshape(count, block)
    spread = blocks.std(axis=1)
    quiet = spread <= np.quantile(spread, 0.25)
    base = float(np.median(blocks[quiet]))
    sigma = max(float(np.median(spread[quiet])), 1e-6)
    dev = smooth - base
    largest = float(np.quantile(np.abs(dev), 0.995))
    threshold = max(K_SIGMA * sigma, SHARE_OF_LARGEST * largest)
    active = np.abs(dev) > threshold
    if not active.any():
        return []
    padded = np.concatenate(([False], active, [False])).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    stretches = [[int(a), int(b)] for a, b in zip(edges[::2], edges[1::2], strict=True)]
    merged: list[list[int]] = []
    for a, b in stretches:
        if merged and (a - merged[-1][1]) / rate < MERGE_S:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    events = []
    for a, b in merged:
        if (b - a) / rate < MIN_S:
            continue
        start = a
        while start > 0 and abs(dev[start - 1]) > threshold / 3:
            start -= 1
        peak = a + int(np.argmax(np.abs(dev[a:b])))
        events.append(Event(float(time[start]), float(time[peak]), float(dev[peak])))
    return events


def without_onset(events: list[Event], onsets: list[float], before: float = 0.5) -> list[Event]:
    """The events no onset accounts for (none within ``before`` s before to the peak).

    Parameters
    ----------
    events : list of Event
        The events of a run.
    onsets : list of float
        The onsets kept (s).
    before : float
        How long before an event's start an onset may lie and still be its onset.

    Returns
    -------
    list of Event
    """
    return [
        e for e in events if not any(e.t_start - before <= t <= e.t_peak + before for t in onsets)
    ]
