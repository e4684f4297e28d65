"""A robot move as an excitation window (paper section IV).

A robot (or a person) that guides the load along a reference move is no step of thrust:
the excitation is the reference ``z_ref(t)`` itself, through the servo force
``k_r (z_ref - z) + c_r (v_ref - v)`` (MODEL.md, ``servo``). This module finds the move
in each run of a log and returns one :class:`MoveTrial` per run: a
:class:`~balancer_id.segment.trial.Trial` whose thrust is zero and that carries the
reference, aligned to the log's clock, in :attr:`MoveTrial.reference`.

The start of the move is taken from the reference when it gives one (``start=``);
otherwise it is found from the motion: the onset of the vertical motion, refined by a
least-squares alignment of the reference velocity against the integrated vertical
acceleration (see :func:`align_start`).

A reference is anything with ``evaluate(t) -> (z_ref, v_ref)`` and a ``start``
attribute that :func:`dataclasses.replace` can set (the trapezoid of
``balancer_id.simulation.inputs`` or :class:`TabulatedMove` read from a CSV file).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import LogReadError, NoTrialError
from balancer_id.read.recording import Log, Recording
from balancer_id.segment.gravity import vertical_motion
from balancer_id.segment.robust import fill_nan, n_samples, rate_of, smooth
from balancer_id.segment.trial import Trial

#: Rest kept before the move's start (s).
REST_BEFORE_S = 1.0
#: Settling kept after the motion has died down (s), and the most kept after the move (s).
SETTLE_AFTER_S = 1.0
MAX_AFTER_S = 10.0
#: How far the least-squares alignment may move the start from the motion's onset (s).
SEARCH_BEFORE_S = 1.5
SEARCH_AFTER_S = 0.5


class Reference(Protocol):
    """A reference move: position and velocity at given times, and a start time."""

    @property
    def start(self) -> float:
        """Start time of the move (s)."""
        ...  # pragma: no cover

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reference position (m) and velocity (m/s) at times ``t`` (s).

        Parameters
        ----------
        t : numpy.ndarray
            Times (s) on the log's clock.

        Returns
        -------
        tuple of numpy.ndarray
            Position and velocity.
        """
        ...  # pragma: no cover


@dataclass
class MoveTrial(Trial):
    """A trial excited by a reference move rather than a step of thrust.

    Attributes
    ----------
    reference : Reference or None
        The reference move on the log's clock (its ``start`` is the move's start).
    start_found : bool
        True when the start was found in the log (``start=`` left out).
    """

    reference: Any = None
    start_found: bool = False

    def to_dict(self) -> dict[str, object]:
        """The ``inspect`` trial record, plus the move's kind, start and end."""
        out = super().to_dict()
        out["kind"] = "move"
        out["move_start"] = round(float(self.t_step), 6)
        out["move_end"] = round(float(move_end(self.reference)), 6)
        out["start_found"] = self.start_found
        out["notes"] = list(self.notes)
        return out


@dataclass(frozen=True)
class TabulatedMove:
    """A reference move given as a table of time and position (``--trajectory FILE.csv``).

    The table's time is relative to the move's start: its first row is the start. The
    position is taken relative to the first row (the servo holds the rest position
    before the move); the velocity is the table's central-difference derivative, and
    both hold their end values after the last row.

    Attributes
    ----------
    time : numpy.ndarray
        Times of the table (s) from the move's start, increasing, first 0.
    position : numpy.ndarray
        Position (m, up positive) relative to the first row.
    start : float
        Start time of the move on the log's clock (s).
    """

    time: np.ndarray
    position: np.ndarray
    start: float = 0.0
    start_given: bool = False

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reference position and velocity at times ``t``.

        Parameters
        ----------
        t : numpy.ndarray
            Times (s) on the log's clock.

        Returns
        -------
        z_ref : numpy.ndarray
            Position (m), 0 before the start, the last row's after the end.
        v_ref : numpy.ndarray
            Velocity (m/s), 0 outside the table.
        """
        tr = np.asarray(t, dtype=float) - self.start
        vel = np.gradient(self.position, self.time)
        vel[0] = vel[-1] = 0.0
        z = np.interp(tr, self.time, self.position, left=0.0, right=self.position[-1])
        v = np.interp(tr, self.time, vel, left=0.0, right=0.0)
        return z, v


def read_trajectory_csv(path: str | Path) -> TabulatedMove:
    """Read a reference move from a CSV of ``time,position`` (s, m; header optional).

    Parameters
    ----------
    path : str or Path
        The CSV file: two numeric columns, comma, semicolon or tab separated.

    Returns
    -------
    TabulatedMove
        Its start is the first time of the table; it is found again in each log unless
        the command gives it (see :func:`find_moves`).

    Raises
    ------
    LogReadError
        When the file cannot be read, a row is not two numbers, or time does not increase.
    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8-sig").splitlines()
    except OSError as exc:
        raise LogReadError(path, f"cannot read the trajectory: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise LogReadError(
            path, "the trajectory is not a text file", hint="give a CSV of time,position rows"
        ) from None
    rows: list[tuple[float, float]] = []
    for k, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        cells = [c for c in text.replace(";", ",").replace("\t", ",").split(",") if c.strip()]
        try:
            if len(cells) < 2:
                raise ValueError
            rows.append((float(cells[0]), float(cells[1])))
        except ValueError:
            if not rows and k == 1:
                continue  # a header line
            raise LogReadError(
                path,
                f"line {k}: expected two numbers 'time,position' (s, m), got {text!r}",
                hint="write the reference move as time,position rows",
            ) from None
    if len(rows) < 2:
        raise LogReadError(path, "the trajectory needs at least two rows of time,position")
    table = np.array(rows, dtype=float)
    bad = np.flatnonzero(~np.isfinite(table).all(axis=1))
    if bad.size:
        raise LogReadError(
            path,
            f"row {bad[0] + 1} of the data holds a value that is not finite",
            hint="every time and position must be a number",
        )
    if np.any(np.diff(table[:, 0]) <= 0):
        raise LogReadError(path, "the trajectory's time column must be increasing")
    t0 = float(table[0, 0])
    return TabulatedMove(table[:, 0] - t0, table[:, 1] - table[0, 1], start=t0)


def _started(reference: Reference, start: float) -> Reference:
    """The same reference move, starting at ``start`` (s)."""
    return dataclasses.replace(reference, start=float(start))  # type: ignore[type-var]


def move_duration(reference: Reference) -> float:
    """Length of the move (s): from its start to the last instant it moves.

    Parameters
    ----------
    reference : Reference
        The reference move.

    Returns
    -------
    float
        Seconds from ``reference.start`` to the end of the motion (0 for no motion).
    """
    if isinstance(reference, TabulatedMove):
        return float(reference.time[-1])
    base = _started(reference, 0.0)
    horizon = 60.0
    t = np.linspace(0.0, horizon, 60001)
    z, v = base.evaluate(t)
    final = z[-1]
    moving = np.flatnonzero((np.abs(v) > 1e-9) | (np.abs(z - final) > 1e-9))
    return float(t[moving[-1]]) if moving.size else 0.0


def move_end(reference: Reference) -> float:
    """End time of the move on the log's clock (s).

    Parameters
    ----------
    reference : Reference
        The reference move.

    Returns
    -------
    float
        ``reference.start`` plus :func:`move_duration`.
    """
    return float(reference.start) + move_duration(reference)


def start_given(reference: Reference) -> bool:
    """Whether the reference fixes its start (``start=`` in a trapezoid spec).

    A trapezoid spec without ``start=`` leaves ``start`` at 0, which means "find it in
    the log"; a CSV table never fixes it.

    Parameters
    ----------
    reference : Reference
        The reference move.

    Returns
    -------
    bool
    """
    if isinstance(reference, TabulatedMove):
        return reference.start_given
    return float(getattr(reference, "start", 0.0)) != 0.0 or bool(
        getattr(reference, "start_given", False)
    )


def motion_onset(time: np.ndarray, accel: np.ndarray) -> int | None:
    """Index where the vertical motion starts: the smoothed acceleration leaves its rest.

    The rest level and noise are the median and the median absolute deviation of the
    first second (or of the quietest fifth of the run when the run starts moving); the
    onset is the first sample of 0.1 s in a row above 6 noise units of the 0.1 s mean.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s).
    accel : numpy.ndarray
        Vertical acceleration (m/s^2).

    Returns
    -------
    int or None
        The onset index, or None when nothing moves.
    """
    rate = rate_of(time)
    w = n_samples(0.1, rate, minimum=3)
    a = smooth(fill_nan(accel), w)
    head = a[: max(n_samples(1.0, rate, minimum=5), w)]
    level = float(np.median(head))
    raw_head = fill_nan(accel)[: head.size]
    sigma = 1.4826 * float(np.median(np.abs(np.diff(raw_head)))) / np.sqrt(2.0)
    sigma = max(sigma, 1e-4)
    thr = 6.0 * sigma / np.sqrt(w) + 3.0 * 1.4826 * float(np.median(np.abs(head - level)))
    above = np.abs(a - level) > max(thr, 0.01)
    run = np.convolve(above.astype(int), np.ones(w, dtype=int), mode="full")[w - 1 :]
    hits = np.flatnonzero(run >= w)
    if hits.size == 0:
        return None
    return int(hits[0])


def align_start(
    time: np.ndarray, accel: np.ndarray, reference: Reference, onset: int
) -> tuple[float, float]:
    """Start of the move that best aligns the reference with the integrated motion.

    The vertical acceleration, less its rest level before ``onset``, is integrated to a
    velocity; the start ``s`` minimizes the squared difference between it and
    ``v_ref(t - s)`` over a fixed window around the move (a grid at the sample interval
    within :data:`SEARCH_BEFORE_S` before and :data:`SEARCH_AFTER_S` after the onset,
    then a parabola through the best three points). A closed servo loop delays the load
    behind its reference by ``D / k_r`` on average (a few milliseconds), which this
    leaves in.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s).
    accel : numpy.ndarray
        Vertical acceleration (m/s^2), up positive.
    reference : Reference
        The reference move (its ``start`` is ignored).
    onset : int
        Index of the motion's onset (:func:`motion_onset`).

    Returns
    -------
    start : float
        The aligned start (s).
    sign : float
        +1, or -1 when the motion runs opposite to the reference (an acceleration whose
        sign is only a convention).
    """
    a = fill_nan(accel)
    rate = rate_of(time)
    t_on = float(time[onset])
    pre = a[max(onset - n_samples(1.0, rate), 0) : max(onset - n_samples(0.05, rate), 1)]
    a = a - (float(np.median(pre)) if pre.size else 0.0)
    v = np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(time))])
    dur = move_duration(reference)
    lo = t_on - SEARCH_BEFORE_S
    sel = (time >= lo - 0.5) & (time <= t_on + SEARCH_AFTER_S + dur + 1.0)
    ts, vs = time[sel], v[sel]
    vs = vs - (vs[0] if vs.size else 0.0)
    dt = 1.0 / rate
    grid = np.arange(lo, t_on + SEARCH_AFTER_S + dt / 2, dt)
    costs = np.empty((2, grid.size))
    for k, s in enumerate(grid):
        _, vr = _started(reference, float(s)).evaluate(ts)
        costs[0, k] = np.sum((vs - vr) ** 2)
        costs[1, k] = np.sum((vs + vr) ** 2)
    row = int(np.argmin(costs.min(axis=1)))
    k = int(np.argmin(costs[row]))
    start = float(grid[k])
    if 0 < k < grid.size - 1:
        c0, c1, c2 = costs[row, k - 1 : k + 2]
        den = c0 - 2 * c1 + c2
        if den > 0:
            start += float(np.clip(0.5 * (c0 - c2) / den, -1.0, 1.0)) * dt
    return start, (1.0 if row == 0 else -1.0)


def align_start_by_force(
    time: np.ndarray,
    accel: np.ndarray,
    force: np.ndarray,
    reference: Reference,
    coarse: float,
    half_width: float = 0.3,
) -> tuple[float, float, float]:
    """Refine the move's start with the servo law the force channel follows.

    The servo force is ``h = k_r (z_ref - z) + c_r (v_ref - v)`` (MODEL.md). With the
    velocity and position integrated from the acceleration, for each start ``s`` near
    ``coarse`` the measured force is regressed on ``z_ref(t - s) - z``, ``v_ref(t - s) - v``
    and a quadratic in time (the integration drift); the start with the smallest residual
    wins (a parabola through the best three). Unlike aligning the velocities, this is not
    pulled by the oscillation of the closed loop.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s).
    accel : numpy.ndarray
        Vertical acceleration (m/s^2), up positive, gravity removed.
    force : numpy.ndarray
        Measured force change (N), either sign.
    reference : Reference
        The reference move (its ``start`` is ignored).
    coarse : float
        The start from :func:`align_start` (s).
    half_width : float
        Search from ``coarse - 2 half_width`` to ``coarse + half_width`` (s).

    Returns
    -------
    start : float
        The refined start (s).
    k_r, c_r : float
        The regression's servo stiffness and damping (N/m, N s/m), signed as the force
        channel reads (both negative for an inverted channel): start values for a fit.
    """
    a = fill_nan(accel)
    f = fill_nan(force)
    rate = rate_of(time)
    dur = move_duration(reference)
    sel = (time >= coarse - 2 * half_width - 1.0) & (time <= coarse + dur + 1.5)
    t, a, f = time[sel], a[sel], f[sel]
    pre = t < coarse - 2 * half_width
    a = a - (float(np.median(a[pre])) if pre.sum() > 5 else 0.0)
    dt_s = np.diff(t)
    v = np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * dt_s)])
    z = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt_s)])
    tau = (t - t[0]) / max(t[-1] - t[0], 1e-9)
    dt = 1.0 / rate
    grid = np.arange(coarse - 2 * half_width, coarse + half_width + dt / 2, dt)
    costs = np.empty(grid.size)
    coefs = np.empty((grid.size, 2))
    for k, s in enumerate(grid):
        zr, vr = _started(reference, float(s)).evaluate(t)
        X = np.column_stack([zr - z, vr - v, np.ones_like(t), tau, tau**2])
        beta, *_ = np.linalg.lstsq(X, f, rcond=None)
        r = f - X @ beta
        costs[k] = float(r @ r)
        coefs[k] = beta[:2]
    k = int(np.argmin(costs))
    start = float(grid[k])
    if 0 < k < grid.size - 1:
        c0, c1, c2 = costs[k - 1 : k + 2]
        den = c0 - 2 * c1 + c2
        if den > 0:
            start += float(np.clip(0.5 * (c0 - c2) / den, -1.0, 1.0)) * dt
    return start, float(coefs[k, 0]), float(coefs[k, 1])


def find_moves(
    log: Log,
    reference: Reference,
    *,
    force_sign: int | None = None,
    vertical: str = "auto",
    g: float = G_DEFAULT,
) -> list[MoveTrial]:
    """Find the reference move in every run of a log: one window per run.

    Each window covers :data:`REST_BEFORE_S` of rest before the move's start, the move,
    and its settling: until the smoothed vertical acceleration has stayed near rest for
    :data:`SETTLE_AFTER_S` (at most :data:`MAX_AFTER_S` after the move's end), or the
    run's end.

    Parameters
    ----------
    log : Log
        What a reader returned.
    reference : Reference
        The reference move; its start is used as given when :func:`start_given`, else
        found in each run (:func:`motion_onset`, :func:`align_start`).
    force_sign : {+1, -1}, optional
        Sign of the force channel; None takes the sign under which the force change
        correlates positively with the acceleration.
    vertical : {"auto", "x", "y", "z"}, optional
        Vertical axis of a linear-acceleration log.
    g : float, optional
        Gravity (m/s^2).

    Returns
    -------
    list of MoveTrial
        One per run where the move was found; ``thrust_N`` is 0 (the servo force is the
        operating force) and ``direction`` the reference's.

    Raises
    ------
    NoTrialError
        When no run shows the move (the message says what each run showed).
    """
    trials: list[MoveTrial] = []
    why: list[str] = []
    given = start_given(reference)
    for rec in log.recordings:
        trial, problem = _find_in_run(rec, reference, given, force_sign, vertical, g)
        if trial is None:
            why.append(f"{rec.name}: {problem}")
            continue
        trial.index = len(trials)
        trial.source = str(log.path)
        trials.append(trial)
    if not trials:
        raise NoTrialError(
            f"{log.path}: the reference move was not found ({'; '.join(why) or 'no run'}); "
            "check --trajectory, or give its start with 'start=SECONDS'"
        )
    return trials


def _move_force(
    rec: Recording,
    time: np.ndarray,
    accel: np.ndarray,
    inside: np.ndarray,
    t_start: float,
    start: float,
    force_sign: int | None,
) -> np.ndarray | None:
    """The force over the move's window, its rest level removed and signed with the motion
    (or by ``force_sign``); None without a usable force channel."""
    if rec.force is None or np.isfinite(rec.force).sum() <= 10:
        return None
    fr = fill_nan(np.asarray(rec.force, dtype=float))
    f_rest = fr[(time >= t_start) & (time < start)]
    fc = fr - (float(np.median(f_rest)) if f_rest.size else 0.0)
    if force_sign is not None:
        fs = float(force_sign)
    else:
        fs = 1.0 if float(np.dot(fc[inside], accel[inside])) >= 0 else -1.0
    return fs * fc[inside]


def _find_in_run(
    rec: Recording,
    reference: Reference,
    given: bool,
    force_sign: int | None,
    vertical: str,
    g: float,
) -> tuple[MoveTrial | None, str]:
    motion = vertical_motion(rec, vertical=vertical, g=g)
    if motion is None or rec.n_samples < 20:
        return None, "no acceleration channel"
    time = np.asarray(rec.time, dtype=float)
    accel = np.asarray(motion.accel, dtype=float)
    sign = 1.0
    caveat = ""
    if given:
        start = float(reference.start)
        if not time[0] <= start < time[-1]:
            return None, f"the given start {start:.2f} s is outside the run"
    else:
        onset = motion_onset(time, accel)
        if onset is None:
            return None, "no motion"
        start, sign = align_start(time, accel, reference, onset)
        if not motion.sign_known:
            accel = sign * accel
        elif sign < 0:
            return None, "the motion runs opposite to the reference move"
        if rec.force is not None and np.isfinite(rec.force).sum() > 10:
            start, _, _ = align_start_by_force(time, accel, rec.force, reference, start)
        else:
            caveat = (
                "move start aligned on the motion alone (no force channel): the closed "
                "loop's oscillation can shift it by a few tenths of a second, which biases "
                "k_r and c_r; give the start with 'start=SECONDS' if it is known"
            )
    ref = _started(reference, start)
    end_move = move_end(ref)
    rate = rate_of(time)
    a = smooth(fill_nan(accel), n_samples(0.1, rate, minimum=3))
    rest = a[time < start - 0.05]
    level = float(np.median(rest)) if rest.size > 5 else 0.0
    noise = 1.4826 * float(np.median(np.abs(np.diff(fill_nan(accel))))) / np.sqrt(2.0)
    busy = np.flatnonzero((np.abs(a - level) > max(4.0 * noise, 0.02)) & (time >= end_move))
    settled = float(time[busy[-1]]) if busy.size else end_move
    t_end = min(max(settled, end_move) + SETTLE_AFTER_S, end_move + MAX_AFTER_S, float(time[-1]))
    t_start = max(start - REST_BEFORE_S, float(time[0]))
    inside = (time >= t_start) & (time <= t_end)
    force = _move_force(rec, time, accel, inside, t_start, start, force_sign)
    distance = float(ref.evaluate(np.array([end_move + 1.0]))[0][0])
    notes = [
        "move found in the log" if not given else "move start as given",
        f"move from {start:.3f} s to {end_move:.3f} s",
        *([caveat] if caveat else []),
    ]
    trial = MoveTrial(
        index=0,
        recording=rec.name,
        t_step=start,
        t_start=t_start,
        t_end=t_end,
        thrust_N=0.0,
        direction="up" if distance >= 0 else "down",
        time=time[inside],
        accel=accel[inside],
        force=force,
        end_reason="settled" if t_end < float(time[-1]) else "end of run",
        notes=notes,
        reference=ref,
        start_found=not given,
    )
    return trial, ""
