"""Checks on one run's samples: time order, rate, gaps, saturation. All vectorized."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from balancer_id.constants import (
    ACCEL_RANGE_G,
    ACCEL_RESOLUTION,
    FORCE_RANGE_N,
    FORCE_RESOLUTION_N,
    G_DEFAULT,
)
from balancer_id.errors import LogReadError
from balancer_id.read.recording import Gap

#: A step longer than this many median steps is a gap (dropped samples).
GAP_FACTOR = 1.5


def check_time(path: object, time: np.ndarray, line_of: Callable[[int], int], column: str) -> None:
    """Raise when the time does not strictly increase.

    Parameters
    ----------
    path : path-like
        The file (for the message).
    time : numpy.ndarray
        Sample times of one run, in file order.
    line_of : callable
        Sample index -> file line number.
    column : str
        Name of the time column.

    Raises
    ------
    LogReadError
        Time goes backwards, or a timestamp repeats; names the line.
    """
    if time.size < 2:
        return
    dt = np.diff(time)
    bad = np.flatnonzero(~(dt > 0))
    if bad.size == 0:
        return
    i = int(bad[0])
    line, previous = line_of(i + 1), line_of(i)
    if dt[i] == 0:
        raise LogReadError(
            path,
            f"duplicate timestamp {time[i + 1]:g} s (same as line {previous})",
            line=line,
            column=column,
            hint="remove the repeated row, or export again with more decimal places for time",
        )
    raise LogReadError(
        path,
        f"time goes backwards ({time[i + 1]:g} s after {time[i]:g} s on line {previous})",
        line=line,
        column=column,
        hint="sort the rows by time, or split the file where the clock restarts",
    )


def sample_rate(time: np.ndarray) -> float:
    """Return the rate (Hz) from the median time step; NaN with fewer than 2 samples.

    Parameters
    ----------
    time : numpy.ndarray
        Strictly increasing sample times (s).

    Returns
    -------
    float
        ``1 / median(diff(time))``.
    """
    if time.size < 2:
        return float("nan")
    return float(1.0 / np.median(np.diff(time)))


def find_gaps(time: np.ndarray, factor: float = GAP_FACTOR) -> list[Gap]:
    """Find steps longer than ``factor`` median steps (dropped wireless samples).

    Parameters
    ----------
    time : numpy.ndarray
        Strictly increasing sample times (s).
    factor : float
        Threshold in median steps.

    Returns
    -------
    list of Gap
        One per long step, in time order; nothing is interpolated.
    """
    if time.size < 3:
        return []
    dt = np.diff(time)
    step = float(np.median(dt))
    where = np.flatnonzero(dt > factor * step)
    with np.errstate(over="ignore", invalid="ignore"):
        ratio = np.nan_to_num(dt[where] / step, nan=2.0, posinf=2.0**62)
    missing = np.maximum(np.rint(np.minimum(ratio, 2.0**62)).astype(np.int64) - 1, 1)
    return [
        Gap(float(time[i]), float(time[i + 1]), int(n))
        for i, n in zip(where.tolist(), missing.tolist(), strict=True)
    ]


def count_saturated(
    force: np.ndarray | None, accel: np.ndarray | None, g: float = G_DEFAULT
) -> dict[str, int]:
    """Count samples at the sensor's limits (MODEL.md, paper Table IV).

    Parameters
    ----------
    force : numpy.ndarray or None
        Force (N).
    accel : numpy.ndarray or None
        Acceleration (m/s^2), shape ``(n, k)``.
    g : float
        Gravity (m/s^2) for the ±16 g range.

    Returns
    -------
    dict
        ``"force"`` and/or ``"accel"`` -> number of samples with ``|value|`` at least the
        range minus one resolution step; channels without saturation are left out, and so
        is a channel with a sample past its range plus one step (a sensor of another
        range: a 78 N push read by a 100 N sensor is not at the 50 N limit).
    """
    out: dict[str, int] = {}
    if force is not None:
        size = np.abs(force[np.isfinite(force)])
        beyond = bool(size.size) and float(size.max()) > FORCE_RANGE_N + FORCE_RESOLUTION_N
        n = 0 if beyond else int(np.count_nonzero(size >= FORCE_RANGE_N - FORCE_RESOLUTION_N))
        if n:
            out["force"] = n
    if accel is not None and accel.size:
        limit = ACCEL_RANGE_G * g - ACCEL_RESOLUTION
        hit = np.zeros(accel.shape[0], dtype=bool)
        beyond = False
        for j in range(accel.shape[1]):  # column by column: no (n, k) temporaries
            size = np.abs(accel[:, j])
            hit |= size >= limit
            beyond |= bool(np.nanmax(size, initial=0.0) > limit + 2 * ACCEL_RESOLUTION)
        n = 0 if beyond else int(np.count_nonzero(hit))
        if n:
            out["accel"] = n
    return out


#: A run of at least this many equal samples at a channel's extreme is the sensor pinned.
PINNED_RUN = 3


def _runs(mask: np.ndarray) -> np.ndarray:
    """Lengths of the runs of True in a boolean array."""
    padded = np.concatenate(([False], mask, [False])).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return edges[1::2] - edges[::2]


#: A range reached near the channel's median is told from a quantized noise's top level by
#: its pile-up: this many times the samples of each of the next levels inward.
PILE_UP = 5.0


def _piled_up(finite: np.ndarray, ext: float) -> bool:
    """Whether the extreme value holds far more samples than the levels next to it.

    A sensor at its range piles every sample beyond it onto one value; a quantized
    signal's top level holds about as many as the levels just inside it.
    """
    at = int(np.count_nonzero(finite == ext))
    if at < 10:
        return False
    inside = finite[finite < ext] if ext >= np.median(finite) else finite[finite > ext]
    if inside.size == 0:
        return False
    _, counts = np.unique(inside, return_counts=True)
    nearest = counts[-3:] if ext >= np.median(finite) else counts[:3]
    return bool(at >= PILE_UP * max(int(nearest.max()), 1))


def pinned_extremes(values: np.ndarray) -> list[tuple[int, float, int, int]]:
    """Find where a channel sits pinned at one extreme value: a sensor at its range.

    At any range (±2 g, ±8 g, a load cell's span): the channel's largest (or smallest)
    value, far from its median (over 30 % of its span, or nearer with
    :data:`PILE_UP` times the samples of the levels inside it), held by runs of at least
    :data:`PINNED_RUN` equal samples, twice or more (or once for 5 samples and more).

    Parameters
    ----------
    values : numpy.ndarray
        Shape ``(n,)`` or ``(n, k)``; NaN ignored.

    Returns
    -------
    list of tuple
        ``(axis, value, samples, runs)`` per pinned extreme: the axis index, the value it
        is pinned at, how many samples and in how many runs.
    """
    block = values.reshape(values.shape[0], -1)
    found = []
    for j in range(block.shape[1]):
        x = block[:, j]
        finite = x[np.isfinite(x)]
        if finite.size < 10:
            continue
        hi, lo, med = float(finite.max()), float(finite.min()), float(np.median(finite))
        span = hi - lo
        if span <= 0:
            continue
        for ext in (hi, lo):
            if abs(ext - med) < 0.3 * span and not (
                _piled_up(finite, ext) and _beyond_resolution(finite, ext)
            ):
                continue
            lengths = _runs(x == ext)
            held = lengths[lengths >= PINNED_RUN]
            if held.size >= 2 or (held.size == 1 and held[0] >= 5):
                found.append((j, ext, int(held.sum()), int(held.size)))
    return found


def clipped_mask(values: np.ndarray) -> np.ndarray:
    """The samples that read a pinned extreme on any axis (:func:`pinned_extremes`).

    Parameters
    ----------
    values : numpy.ndarray
        Shape ``(n,)`` or ``(n, k)``; NaN ignored.

    Returns
    -------
    numpy.ndarray
        Boolean, shape ``(n,)``: True where some axis reads the value it is pinned at
        (the sensor's range reached: the true value lies at or beyond it, unknown).
    """
    block = values.reshape(values.shape[0], -1)
    mask = np.zeros(block.shape[0], dtype=bool)
    for j, value, _, _ in pinned_extremes(block):
        x = block[:, j]
        if _beyond_resolution(x[np.isfinite(x)], value):
            mask |= x == value
    return mask


#: A range is told from a quantized signal's last level by its distance from the median:
#: this many quantization steps and noise sigmas at least.
RANGE_STEPS = 3.0


def _beyond_resolution(finite: np.ndarray, ext: float) -> bool:
    """Whether ``ext`` lies :data:`RANGE_STEPS` quantization steps and noise sigmas from the
    channel's median (a quantized sensor's outer levels hold runs of equal samples too)."""
    if finite.size < 3:
        return False
    steps = np.diff(np.unique(finite))
    step = float(np.median(steps[: 64])) if steps.size else 0.0
    sigma = float(np.median(np.abs(np.diff(finite))) / (0.6745 * np.sqrt(2.0)))
    return bool(abs(ext - float(np.median(finite))) >= RANGE_STEPS * max(step, sigma))


def repeat_factor(values: np.ndarray) -> int:
    """How many times each sample is repeated in a row (1: none), when nearly all are.

    A 20 Hz export of a 10 Hz sensor writes each value twice: runs of equal rows of one
    length (2) make up at least 80 % of the rows.

    Parameters
    ----------
    values : numpy.ndarray
        Shape ``(n,)`` or ``(n, k)``.

    Returns
    -------
    int
        The repeat length, or 1 when the rows are not repeated that way.
    """
    block = values.reshape(values.shape[0], -1)
    if block.shape[0] < 20:
        return 1
    same = np.all(block[1:] == block[:-1], axis=1)
    if not same.any():
        return 1
    lengths = _runs(same) + 1
    if lengths.size < 10:  # a constant stretch is no repeated export
        return 1
    k = int(np.median(lengths))
    covered = int(lengths[lengths == k].sum())
    if k >= 2 and covered >= 0.8 * block.shape[0]:
        return k
    return 1
