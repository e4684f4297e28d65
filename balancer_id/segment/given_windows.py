"""Trials from windows the user gives (``--window START:END``): a lab rig, a free motion.

Where the log is no step experiment (a weight on a bungee pulled by hand and released, a
cart pushed along a track), the user knows the stretches in which only the measured force
acts on the load. Each stretch is one trial driven by the measured force; nothing is
detected, so no drive lag is assumed. The force's and the acceleration's resting levels
come from the quietest stretch of the run before the window (the run's start when none is
quiet), and the load's velocity at the window's start is integrated from the measured
acceleration since that rest (the load may be moving when the window opens).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from balancer_id.errors import NoTrialError, UsageError
from balancer_id.read.recording import Log, Recording
from balancer_id.segment.assign import vertical_name
from balancer_id.segment.gravity import vertical_motion
from balancer_id.segment.robust import fill_nan, n_samples, rate_of, smooth
from balancer_id.segment.trial import Trial

#: Length of the resting stretch looked for before a window (s).
REST_S = 0.5


def _quietest(x: np.ndarray, width: int, stop: int) -> slice:
    """The ``width`` samples before ``stop`` where ``x`` varies least."""
    if stop <= width:
        return slice(0, max(stop, 1))
    csum = np.concatenate([[0.0], np.cumsum(x[:stop])])
    csq = np.concatenate([[0.0], np.cumsum(x[:stop] ** 2)])
    mean = (csum[width:] - csum[:-width]) / width
    var = (csq[width:] - csq[:-width]) / width - mean**2
    k = int(np.argmin(var))
    return slice(k, k + width)


def force_zero(
    time: np.ndarray, force: np.ndarray, accel: np.ndarray, f_ref: float, lo: int, hi: int
) -> str | None:
    """Why the force's rest reading is not its zero in a window, or None when it is.

    A force's zero is known only where nothing pushes. The reading at the rest before a
    window is taken as the zero when the load there rested on the force alone (a weight
    on a bungee: the rest reads its weight, which gravity's removal balances); but a rest
    held against a tension or a preload (a cart held back on a string, a spring pressed by
    hand), or no rest at all, reads a force that goes on acting. The motion tells them
    apart: within the window ``a = (F - z) / m - (D / m) v`` is fitted for the zero ``z``
    (least squares on the force, the velocity and a constant). The rest reading is kept
    when ``z`` lies nearer it than 0; otherwise, or when the force does not explain the
    motion at all (a constant tension), the absolute force is the one that acts.

    Parameters
    ----------
    time, force, accel : numpy.ndarray
        The run's samples (force as read, vertical acceleration less its rest level).
    f_ref : float
        The force read at the rest before the window.
    lo, hi : int
        The window's samples.

    Returns
    -------
    str or None
        Why the absolute force drives the window; None: the rest reading is the zero.
    """
    t, f, a = time[lo:hi], force[lo:hi], accel[lo:hi]
    if t.size < 10:
        return None
    v = np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))])
    design = np.column_stack([f, v, np.ones_like(f)])
    coef, *_ = np.linalg.lstsq(design, a, rcond=None)
    b_f, c = float(coef[0]), float(coef[2])
    explained = 1.0 - float(np.var(a - design @ coef)) / max(float(np.var(a)), 1e-300)
    if not (np.isfinite(b_f) and b_f > 0 and explained > 0.3):
        return (
            f"the force ({f_ref:.3g} N at rest) does not follow the motion, as a constant "
            "tension that goes on pulling"
        )
    z = -c / b_f
    if abs(z - f_ref) <= abs(z):
        return None
    return (
        f"the rest before it holds {f_ref:.3g} N, and the motion shows the zero near "
        f"{z:.3g} N: a tension or preload that goes on acting, not an offset"
    )


def _noise(x: np.ndarray) -> float:
    """The white noise's standard deviation in ``x`` (median absolute first difference)."""
    d = np.abs(np.diff(x[np.isfinite(x)]))
    return float(np.median(d) / (0.6745 * np.sqrt(2.0))) if d.size else 0.0


def check_windows(windows: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    """The windows sorted, each with START < END and none overlapping.

    Parameters
    ----------
    windows : sequence of (float, float)
        ``(start, end)`` in seconds of the run's time base.

    Returns
    -------
    list of (float, float)
        Sorted by start.

    Raises
    ------
    UsageError
        For a window that is empty, not finite or overlaps another.
    """
    out = sorted((float(a), float(b)) for a, b in windows)
    for a, b in out:
        if not (np.isfinite(a) and np.isfinite(b) and a < b):
            raise UsageError(f"--window {a:g}:{b:g}: give START:END in seconds with START < END")
    for (a0, b0), (a1, b1) in itertools.pairwise(out):
        if a1 < b0:
            raise UsageError(
                f"--window {a0:g}:{b0:g} and {a1:g}:{b1:g} overlap; give separate stretches"
            )
    return out


def window_trials(
    log: Log,
    windows: Sequence[tuple[float, float]],
    *,
    vertical: str = "auto",
    g: float = 9.80665,
    force_sign: int | None = None,
) -> list[Trial]:
    """One trial per given window and run, driven by the measured force.

    Parameters
    ----------
    log : Log
        The log (every run is windowed on its own time base).
    windows : sequence of (float, float)
        Stretches ``(start, end)`` in seconds where only the measured force acts.
    vertical : str
        The vertical axis option (``auto``, ``z``, ``-z`` ...).
    g : float
        Gravity (m/s^2).
    force_sign : int or None
        Sign of the force channel; None: the sign that makes force and acceleration agree.

    Returns
    -------
    list of Trial
        ``kind="window"``, in time order, run by run.

    Raises
    ------
    NoTrialError
        When no window holds samples with force and acceleration.
    """
    wins = check_windows(windows)
    trials: list[Trial] = []
    why: list[str] = []
    for rec in log.recordings:
        made = _run_windows(rec, wins, vertical, g, force_sign, str(log.path), len(trials))
        if isinstance(made, str):
            why.append(f"{rec.name}: {made}")
        else:
            trials.extend(made)
    if not trials:
        raise NoTrialError(f"{log.path}: no trial in the windows given ({'; '.join(why)})")
    return trials


def _run_windows(
    rec: Recording,
    wins: list[tuple[float, float]],
    vertical: str,
    g: float,
    force_sign: int | None,
    source: str,
    first_index: int,
) -> list[Trial] | str:
    """The window trials of one run, or why there are none."""
    if rec.force is None or not np.isfinite(rec.force).any():
        return "no force channel (a window is driven by the measured force)"
    motion = vertical_motion(rec, vertical=vertical, g=g)
    if motion is None:
        return "no acceleration channel"
    time = rec.time
    rate = rate_of(time)
    force = fill_nan(rec.force)
    accel = fill_nan(motion.accel)
    width = n_samples(REST_S, rate, minimum=5)
    # the sign: a rise of the force moves the load up (over every window together)
    inside = np.zeros(time.size, dtype=bool)
    for a, b in wins:
        inside |= (time >= a) & (time <= b)
    if inside.sum() < 10:
        span = f"{time[0]:.2f}-{time[-1]:.2f} s"
        return f"fewer than 10 samples inside the windows (the run spans {span})"
    orientation, how = _orientation(force[inside], accel[inside], force_sign)
    out: list[Trial] = []
    for a, b in wins:
        sl = np.flatnonzero((time >= a) & (time <= b))
        if sl.size < 10:
            continue
        lo, hi = int(sl[0]), int(sl[-1]) + 1
        out.append(
            _window_trial(
                rec,
                motion,
                (a, b),
                (lo, hi),
                (force, accel, width),
                (orientation, how),
                source,
                first_index + len(out),
            )
        )
    return out or "no samples inside the windows"


def _orientation(force: np.ndarray, accel: np.ndarray, force_sign: int | None) -> tuple[float, str]:
    """The force's sign (a rise moves the load up, over every window together) and how it
    was found: given, from the motion, or from the means where the force hardly varies."""
    if force_sign is not None:
        return float(force_sign), "force sign as given"
    fc = force - np.mean(force)
    ac = accel - np.mean(accel)
    corr = abs(fc @ ac) / max(float(np.sqrt((fc @ fc) * (ac @ ac))), 1e-300)
    if corr < 0.3:  # a force that hardly varies (a tension): its level moves the load
        orientation = float(np.sign(np.mean(force) * np.mean(accel))) or 1.0
        return orientation, "force sign from the mean force and motion (the force hardly varies)"
    return float(np.sign(fc @ ac)) or 1.0, "force sign from the motion"


def _window_trial(
    rec: Recording,
    motion: Any,
    window: tuple[float, float],
    span: tuple[int, int],
    signals: tuple[np.ndarray, np.ndarray, int],
    sign: tuple[float, str],
    source: str,
    index: int,
) -> Trial:
    """One window's trial: its force's zero (the rest before it, or none: the absolute
    force, said), the load's velocity at its start, the force as the model's input."""
    (a, b), (lo, hi), (force, accel, width), (orientation, how) = window, span, signals, sign
    time = rec.time
    rest = _quietest(smooth(force, 3), width, lo)
    f_ref = float(np.median(force[rest]))
    a_ref = float(np.median(accel[rest]))
    if lo < width:  # no rest before it: the acceleration's zero is g's removal
        a_ref = 0.0
    zero = force_zero(time, force, accel - a_ref, f_ref, lo, hi)
    if zero is None and lo < width:
        zero = "no rest before it (it starts with the run)"
    where = f"window {a:g}:{b:g} s of {rec.name}"
    notes = []
    if zero is not None:  # issue 31: the force's zero is known only where nothing pushes
        f_ref = 0.0
        notes.append(
            f"warning: {where}: {zero}; the absolute force drives the model (zero the "
            "sensor before recording, or give a window with a rest before it where "
            "nothing but the measured force holds the load)"
        )
    # the velocity at the window's start: the measured motion since that rest
    k0 = rest.stop
    seg_t, seg_a = time[k0 : lo + 1], accel[k0 : lo + 1] - a_ref
    v0 = float(np.sum(0.5 * (seg_a[1:] + seg_a[:-1]) * np.diff(seg_t)))
    u = orientation * (force[lo:hi] - f_ref)
    peak = float(u[int(np.argmax(np.abs(u)))])
    return Trial(
        index=index,
        recording=rec.name,
        t_step=float(time[lo]),
        t_start=float(time[lo]),
        t_end=float(time[hi - 1]),
        thrust_N=peak,
        direction="up" if peak >= 0 else "down",
        time=time[lo:hi].copy(),
        accel=accel[lo:hi] - a_ref,
        force=u,
        end_reason="window",
        source=source,
        notes=[
            f"{where} given: the measured force drives the model; {how}; "
            + (
                f"rest levels from {time[rest.start]:.2f}-{time[rest.stop - 1]:.2f} s"
                if zero is None
                else "the absolute force (its zero unknown)"
            ),
            *notes,
        ],
        kind="window",
        vertical=vertical_name(motion, rec.accel_axes),
        vertical_sign_known=motion.sign_known,
        initial_state=(float(u[0]), v0, 0.0),
    )
