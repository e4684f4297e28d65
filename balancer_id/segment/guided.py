"""Human-guided moves: one excitation window where the force varies without steps.

A person guiding the load (the paper's human-assist experiment) pushes and pulls
smoothly: the step detector finds no step, yet the log is a good identification
experiment because the measured force drives the model. The window runs from the rest
before the force first leaves its resting level to the end of the run (or the next
gap), and the motion must confirm it.
"""

from __future__ import annotations

import numpy as np

from balancer_id.notes import Note
from balancer_id.read.recording import Recording
from balancer_id.segment.assign import clip_note, clipped_samples, vertical_name
from balancer_id.segment.gravity import VerticalMotion
from balancer_id.segment.robust import fill_nan, n_samples, rate_of, smooth
from balancer_id.segment.steps import StepSettings
from balancer_id.segment.trial import Trial

#: Rest kept before the move (s), smoothing of the force (s), shortest move (s).
REST_BEFORE_S = 0.5
SMOOTH_S = 0.1
MIN_MOVE_S = 1.0
#: The force has left its rest when it is this many noise deviations away (and at least
#: half the smallest step); the move starts where it was last within ``START_K``.
DEPART_K = 8.0
START_K = 2.0
#: The motion confirms the move when its smoothed acceleration exceeds this many noise
#: deviations of the acceleration and follows the force: its correlation with the force
#: passed through a balancer's response (a drive lag of one of ``LAGS_S``, then a mass
#: whose viscosity takes one of ``VISCOUS_S`` to stop it, or none), at least
#: ``MIN_CORRELATION`` for the best of them.
MOTION_K = 5.0
LAGS_S = (0.03, 0.3, 1.5)
VISCOUS_S = (0.1, 0.4, 1.5, np.inf)
MIN_CORRELATION = 0.5
#: A person moves the load within seconds: the force leaves its rest within this time
#: (a slow drift of the sensor's offset is no move).
MAX_DEPARTURE_S = 3.0


def _noise(x: np.ndarray) -> float:
    """White-noise deviation from first differences (robust: MAD)."""
    d = np.diff(x)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0)) if d.size else 0.0


def _lowpass(x: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """``x`` through a first-order lag of ``tau`` (s) at sample interval ``dt``."""
    from scipy.signal import lfilter

    alpha = float(np.exp(-dt / tau))
    return lfilter([1.0 - alpha], [1.0, -alpha], x)


def _response_correlation(t: np.ndarray, u: np.ndarray, a: np.ndarray) -> float:
    """The largest correlation (in size) of ``a`` with ``u`` passed through a balancer's
    response: a drive lag, then a mass held back by a viscosity.

    A mass alone accelerates as its (lagged) force; held back by a viscosity that stops
    it in ``tau_v``, its acceleration is that force less its own lag over ``tau_v`` (a
    high-pass: ``m a = f - D v``, ``v = LP_tau_v(f) / D``). A heavily damped load's
    acceleration follows the force's changes, not the force: one fixed lag (0.3 s, a
    mass alone) missed it, and a light cart's guided move was refused as no trial.
    """
    if u.size < 3 or np.std(a) == 0:
        return 0.0
    dt = float(np.median(np.diff(t)))
    if not dt > 0:
        return 0.0
    best = 0.0
    for lag in LAGS_S:
        f = _lowpass(u, dt, lag)
        for tau_v in VISCOUS_S:
            r = f if not np.isfinite(tau_v) else f - _lowpass(f, dt, tau_v)
            if np.std(r) > 0:
                best = max(best, abs(float(np.corrcoef(r, a)[0, 1])))
    return best


def _stretch(breaks: np.ndarray, first: int, n: int) -> tuple[int, int]:
    """The gap-free stretch around sample ``first``: its start and its end."""
    later = breaks[breaks > first] if breaks.size else breaks
    stop = int(later[0]) if later.size else n
    earlier = breaks[breaks <= first] if breaks.size else breaks
    lo = int(earlier[-1]) if earlier.size else 0
    return lo, stop


def _orientation(
    force_sign: int | None, change: np.ndarray, accel: np.ndarray
) -> tuple[float, str]:
    """The force's sign (given, else from the motion it drives) and how it was found."""
    if force_sign is not None:
        return float(force_sign), "force sign as given"
    orientation = float(np.sign(np.dot(change, accel))) or 1.0
    return orientation, "force sign from the motion (a push moves the load its way)"


def guided_move(
    rec: Recording,
    motion: VerticalMotion | None,
    breaks: np.ndarray,
    *,
    force_sign: int | None,
    settings: StepSettings,
    index: int,
    source: str,
) -> Trial | None:
    """The one excitation window of a run without steps, or None.

    Parameters
    ----------
    rec : Recording
        The run (needs a force channel).
    motion : VerticalMotion or None
        Its vertical acceleration (needed: the motion confirms the move).
    breaks : numpy.ndarray
        First sample after each gap that splits the run.
    force_sign : int or None
        The user's force sign; None takes the sign that makes force and acceleration
        agree (a push up moves the load up).
    settings : StepSettings
        Detector constants (``min_step_N``).
    index : int
        Index to give the trial.
    source : str
        The file, for ``Trial.source``.

    Returns
    -------
    Trial or None
        ``thrust_N`` is the signed peak of the operating force (N, up positive);
        ``force`` the operating force less its resting level; None without a move.
    """
    if rec.force is None or motion is None or rec.n_samples < 10:
        return None
    if np.isfinite(rec.force).sum() < 10:
        return None
    time = rec.time
    rate = rate_of(time)
    force = fill_nan(rec.force)
    accel = fill_nan(motion.accel)
    w = n_samples(SMOOTH_S, rate, minimum=3)
    fs = smooth(force, w)
    rest_n = n_samples(REST_BEFORE_S, rate, minimum=3)
    ref = float(np.median(fs[:rest_n]))
    sigma = max(_noise(force), 1e-6)
    dev = np.abs(fs - ref)
    gone = np.flatnonzero(dev > max(DEPART_K * sigma, 0.5 * settings.min_step_N))
    if gone.size == 0:
        return None
    first = int(gone[0])
    lo, stop = _stretch(breaks, first, rec.n_samples)
    begin = first
    while begin > lo and dev[begin - 1] > START_K * sigma:
        begin -= 1
    start = max(lo, begin - rest_n)
    if (time[stop - 1] - time[begin]) < MIN_MOVE_S or begin - lo < 3:
        return None
    if time[first] - time[begin] > MAX_DEPARTURE_S:
        return None
    acc_s = smooth(accel, w)
    a_sigma = max(_noise(accel) / np.sqrt(w), 1e-9)
    if np.max(np.abs(acc_s[begin:stop] - np.median(acc_s[start:begin]))) < MOTION_K * a_sigma:
        return None
    # the force's zero: its mean over all the rest before the move (the median of the
    # first half second above only finds the departure; its error would drive the model
    # with a constant force all move long, errors in variables)
    quiet_end = max(begin - w, lo)
    if quiet_end - lo > rest_n:
        ref = float(np.mean(force[lo:quiet_end]))
    change = force[start:stop] - ref
    if _response_correlation(time[start:stop], change, acc_s[start:stop]) < MIN_CORRELATION:
        return None
    orientation, how = _orientation(force_sign, smooth(change, w), acc_s[start:stop])
    u = orientation * change
    peak = float(u[int(np.argmax(np.abs(u)))])
    sl = slice(start, stop)
    notes = [f"guided move: no step, the measured force drives the model; {how}"]
    typed: list[Note] = []
    clipped = clipped_samples(rec)
    if clipped is not None:
        clip_note(int(clipped[sl].sum()), notes, typed)
    return Trial(
        index=index,
        recording=rec.name,
        t_step=float(time[begin]),
        t_start=float(time[start]),
        t_end=float(time[stop - 1]),
        thrust_N=peak,
        direction="up" if peak > 0 else "down",
        time=time[sl].copy(),
        accel=motion.accel[sl].copy(),
        force=u,
        end_reason="end of run" if stop == rec.n_samples else "gap",
        source=source,
        notes=notes,
        typed_notes=typed,
        kind="guided",
        vertical=vertical_name(motion, rec.accel_axes),
        vertical_sign_known=motion.sign_known,
    )
