"""Bring a channel sampled at another rate onto the acceleration's sample times.

The acceleration is the output of the identification and is never interpolated; the
force is the input and may be: a faster force is averaged over each acceleration
sample's period (a boxcar low-pass centred on the sample, so no time shift), a slower
or equally fast one is interpolated linearly. Both are vectorized (cumulative sums and
``searchsorted``), linear in the number of samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The force is "faster" (averaged, not interpolated) above this multiple of the accel rate.
FASTER = 1.5


@dataclass(frozen=True)
class Resampled:
    """A channel brought onto other sample times.

    Attributes
    ----------
    values : numpy.ndarray
        The channel at the kept target times.
    keep : numpy.ndarray
        Boolean mask over the target times: True where the source covers the time
        (the source's span plus half a target sample period at either end).
    method : str
        ``"averaged"`` (source faster) or ``"interpolated"``.
    source_rate_hz, target_rate_hz : float
        Rates from the median steps.
    """

    values: np.ndarray
    keep: np.ndarray
    method: str
    source_rate_hz: float
    target_rate_hz: float


def _median_step(t: np.ndarray) -> float:
    dt = np.diff(t)
    dt = dt[np.isfinite(dt) & (dt > 0)]
    return float(np.median(dt)) if dt.size else float("nan")


def onto_times(t_src: np.ndarray, x_src: np.ndarray, t_dst: np.ndarray) -> Resampled:
    """Bring samples ``(t_src, x_src)`` onto the times ``t_dst``.

    When the source is more than :data:`FASTER` times faster than the target, each target
    sample gets the mean of the source samples in its cell (from the midpoint with the
    previous target time to the midpoint with the next); cells without a source sample
    (a gap in the source) are interpolated. Otherwise the source is interpolated
    linearly. Target times outside the source's span (by more than half a target
    sample period) are marked in ``keep`` as not covered; nothing is extrapolated.

    Parameters
    ----------
    t_src, x_src : numpy.ndarray
        Strictly increasing source times (s) and finite values, at least 2 samples.
    t_dst : numpy.ndarray
        Strictly increasing target times (s), at least 2 samples.

    Returns
    -------
    Resampled
        ``values`` has one entry per True of ``keep``.
    """
    t_src = np.asarray(t_src, dtype=float)
    x_src = np.asarray(x_src, dtype=float)
    t_dst = np.asarray(t_dst, dtype=float)
    dt_src, dt_dst = _median_step(t_src), _median_step(t_dst)
    tol = 0.5 * dt_dst
    keep = (t_dst >= t_src[0] - tol) & (t_dst <= t_src[-1] + tol)
    t = t_dst[keep]
    interp = np.interp(t, t_src, x_src)
    if not dt_src * FASTER < dt_dst or t.size < 2:
        return Resampled(interp, keep, "interpolated", 1.0 / dt_src, 1.0 / dt_dst)
    mid = 0.5 * (t[1:] + t[:-1])
    edges = np.concatenate([[t[0] - (mid[0] - t[0])], mid, [t[-1] + (t[-1] - mid[-1])]])
    bounds = np.searchsorted(t_src, edges, side="left")
    offset = float(np.mean(x_src))  # cumulative sums of small numbers keep their precision
    csum = np.concatenate([[0.0], np.cumsum(x_src - offset)])
    count = np.diff(bounds)
    total = csum[bounds[1:]] - csum[bounds[:-1]]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1) + offset, interp)
    return Resampled(mean, keep, "averaged", 1.0 / dt_src, 1.0 / dt_dst)
