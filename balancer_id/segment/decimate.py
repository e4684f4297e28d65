"""Bring a high-rate trial down to a rate that keeps the balancer's dynamics.

The dynamics identified (drive lag ``T_a`` ~0.1-1 s, a catch of a few tenths of a
second) live below ~20 Hz; a fit at 200-400 Hz keeps them with a wide margin, and a
10 kHz trial fitted as it is costs 25-50 times the time and memory for nothing. The
decimation is an anti-aliased polyphase FIR (:func:`scipy.signal.resample_poly`,
Kaiser window, zero phase: nothing is delayed), by an integer factor so that every kept
sample is a sample of the log, at its own time.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from balancer_id.segment.robust import rate_of
from balancer_id.segment.trial import Trial

#: :func:`scipy.signal.resample_poly`'s default filter reaches this many times the
#: decimation factor of input samples either side of each output sample.
FILTER_HALF_LENGTH = 10

#: Decimate down to no less than this rate (Hz); the result lies in [MIN_RATE_HZ, 2 MIN_RATE_HZ).
MIN_RATE_HZ = 200.0


@dataclass(frozen=True)
class Decimation:
    """What :func:`decimate_trial` did.

    Attributes
    ----------
    factor : int
        Every ``factor``-th sample kept after the low-pass (1: unchanged).
    rate_in_hz, rate_out_hz : float
        The trial's rate before and after (Hz).
    reason : str
        One line for the notes: what was done, or why nothing was.
    """

    factor: int
    rate_in_hz: float
    rate_out_hz: float
    reason: str

    @property
    def reach_s(self) -> float:
        """How far (s) the anti-aliasing filter reaches either side of a sample: a kept
        sample nearer than this to a jump of the acceleration is a blend of both sides."""
        if self.factor <= 1 or not self.rate_in_hz > 0:
            return 0.0
        return (FILTER_HALF_LENGTH * self.factor + 1) / self.rate_in_hz


def decimation_factor(rate_hz: float, min_rate_hz: float = MIN_RATE_HZ) -> int:
    """Return the integer factor that brings ``rate_hz`` into ``[min_rate_hz, 2 min_rate_hz)``.

    Parameters
    ----------
    rate_hz : float
        The rate of the samples (Hz).
    min_rate_hz : float, optional
        The lowest rate to decimate to (Hz).

    Returns
    -------
    int
        ``floor(rate_hz / min_rate_hz)``, at least 1 (1 for a rate below ``2 min_rate_hz``
        or not finite).
    """
    if not (np.isfinite(rate_hz) and np.isfinite(min_rate_hz) and min_rate_hz > 0):
        return 1
    return max(1, int(np.floor(rate_hz / min_rate_hz + 1e-9)))


def decimate_trial(trial: Trial, min_rate_hz: float = MIN_RATE_HZ) -> tuple[Trial, Decimation]:
    """Decimate a trial for fitting, anti-aliased, to a rate in ``[min_rate_hz, 2 min_rate_hz)``.

    A pure function: the trial given is not changed. The acceleration and the force (when
    present) are low-pass filtered and decimated by :func:`decimation_factor` with
    :func:`scipy.signal.resample_poly` (zero phase; each end extended by its point
    reflection about the mean of its first ``factor`` samples, so a trial that starts or
    ends in motion has no edge transient); the times
    are the log's own times of the kept samples. A trial at or below ``2 min_rate_hz``,
    one with non-finite samples, or one too short to filter is returned as it is.

    Parameters
    ----------
    trial : Trial
        A segmented trial.
    min_rate_hz : float, optional
        The lowest rate to decimate to (Hz); the default keeps the dynamics (MODEL.md:
        lags of 0.1-1 s) with a wide margin.

    Returns
    -------
    trial : Trial
        The decimated trial (or ``trial`` itself), with a note saying what was done.
    decimation : Decimation
        The factor and the rates chosen.
    """
    time = np.asarray(trial.time, dtype=float)
    rate = rate_of(time) if time.size >= 2 else float("nan")
    q = decimation_factor(rate, min_rate_hz)
    channels = [np.asarray(trial.accel, dtype=float)]
    if trial.force is not None:
        channels.append(np.asarray(trial.force, dtype=float))
    if q == 1:
        why = f"kept at {rate:.4g} Hz (below {2 * min_rate_hz:g} Hz, no decimation needed)"
        return trial, Decimation(1, rate, rate, why)
    if not all(np.isfinite(c).all() for c in channels) or not np.isfinite(time).all():
        why = f"kept at {rate:.4g} Hz: non-finite samples, not decimated"
        return trial, Decimation(1, rate, rate, why)
    if time.size < 4 * q:
        why = f"kept at {rate:.4g} Hz: too short to decimate by {q}"
        return trial, Decimation(1, rate, rate, why)
    from scipy import signal  # lazy, only when decimating: it loads scipy.stats (~1 s)

    out = [_lowpass_decimate(signal, c, q) for c in channels]
    new_time = time[::q]
    n = min(new_time.size, *(c.size for c in out))
    rate_out = rate / q
    why = (
        f"decimated for fitting from {rate:.4g} Hz to {rate_out:.4g} Hz (factor {q}, "
        "anti-aliased polyphase FIR, zero phase)"
    )
    new = dataclasses.replace(
        trial,
        time=new_time[:n],
        accel=out[0][:n],
        force=out[1][:n] if trial.force is not None else None,
        notes=[*trial.notes, why],
    )
    return new, Decimation(q, rate, rate_out, why)


def _lowpass_decimate(signal: object, x: np.ndarray, q: int) -> np.ndarray:
    """Anti-aliased decimation by ``q``; ends point-reflected to keep their level and slope."""
    pad = min(FILTER_HALF_LENGTH * q, x.size - 1)  # the filter's reach either side
    pad -= pad % q  # whole output samples, so the kept samples stay on the log's times
    left = 2.0 * x[:q].mean() - x[pad:0:-1]
    right = 2.0 * x[-q:].mean() - x[-2 : -pad - 2 : -1]
    y = signal.resample_poly(np.concatenate([left, x, right]), 1, q)  # type: ignore[attr-defined]
    start = pad // q
    return y[start : start + -(-x.size // q)]
