"""Give the detected steps their direction and thrust, and cut them out as trials."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from balancer_id.notes import Note
from balancer_id.read.orientation import axis_name
from balancer_id.read.recording import Recording
from balancer_id.segment.gravity import VerticalMotion
from balancer_id.segment.robust import fill_nan, level, n_samples, rate_of
from balancer_id.segment.steps import Step, StepSettings
from balancer_id.segment.trial import Trial
from balancer_id.segment.window import Window


@dataclass
class Run:
    """What detection found in one recording.

    Attributes
    ----------
    rec : Recording
        The run.
    motion : VerticalMotion or None
        Its vertical acceleration.
    breaks : numpy.ndarray
        First sample after each gap.
    steps : list of Step
        Steps kept, in time order.
    windows : list of Window
        One per step.
    why : str
        What the detector saw (for "no step trial found").
    notes : list of str
        Notes for every trial of the run.
    """

    rec: Recording
    motion: VerticalMotion | None
    breaks: np.ndarray
    steps: list[Step]
    windows: list[Window]
    why: str
    notes: list[str] = field(default_factory=list)


def mounting_sign(
    steps: list[Step], k_sigma: float, chained: list[bool] | None = None
) -> int | None:
    """How the force sensor is mounted: +1 when force steps and motion share their sign.

    Steps taken from rest vote (a step taken while moving has the previous step's rise
    in its response); steps taken while moving vote only when no step from rest does.

    Parameters
    ----------
    steps : list of Step
        Steps with force sizes and acceleration responses.
    k_sigma : float
        Responses below this many noise standard deviations do not vote.
    chained : list of bool, optional
        Per step, whether it was taken while moving (default: none was).

    Returns
    -------
    int or None
        The majority sign weighted by significance, None without a vote.
    """
    chained = chained if chained is not None else [False] * len(steps)
    for allowed in ({False}, {False, True}):
        votes = [
            np.sign(st.size * st.response) * st.response_z
            for st, ch in zip(steps, chained, strict=True)
            if ch in allowed
            and np.isfinite(st.size)
            and np.isfinite(st.response)
            and st.response_z >= k_sigma
        ]
        total = float(np.sum(votes)) if votes else 0.0
        if total:
            return int(np.sign(total))
    return None


def orient(
    run: Run, given: list[float] | None, force_sign: int | None, *, signed: bool | None = None
) -> None:
    """Fix the sign of an automatic linear-acceleration vertical (in place).

    The vertical is flipped when most steps move against ``force_sign`` (or, without
    it, against the signs of the given thrusts when they are signed).

    Parameters
    ----------
    run : Run
        One run's detection; ``motion`` and the step responses may be negated.
    given : list of float or None
        The run's given thrusts.
    force_sign : int or None
        The user's force sign.
    signed : bool or None, optional
        Whether the given thrusts carry signs (None: when any is negative).
    """
    m = run.motion
    if signed is None:
        signed = given is not None and any(v < 0 for v in given)
    if m is None or m.sign_known:
        return
    expected: list[float] = []
    source = ""
    if force_sign is not None and all(np.isfinite(st.size) for st in run.steps):
        expected = [float(np.sign(st.size * force_sign)) for st in run.steps]
        source = "force_sign"
    elif given is not None and signed:
        expected = [float(np.sign(v)) for v in given]
        source = "the signed thrusts"
    pairs = [
        (e, np.sign(st.response))
        for e, st in zip(expected, run.steps, strict=False)
        if np.isfinite(st.response)
    ]
    if not pairs:
        run.notes.append(f"vertical sign is a convention: {m.method}")
        return
    if 2 * sum(1 for e, r in pairs if e == r) < len(pairs):
        run.motion = m.flipped(f"sign reversed to agree with {source}")
        run.steps = [
            Step(st.onset, st.size, -st.response, st.response_z, st.source) for st in run.steps
        ]
    else:
        run.motion = dataclasses.replace(m, method=f"{m.method}; sign agrees with {source}")


def _direction(
    st: Step,
    force_sign: int | None,
    mounting: int | None,
    k_sigma: float,
    notes: list[str],
) -> int:
    """+1 (up) or -1 (down) for one step, noting how it was decided when not by motion.

    Order: the user's ``force_sign``; the run's mounting (the force/motion sign relation
    its steps from rest agree on), noting a step whose own motion disagrees; the step's
    own motion; the force sign assumed +1.
    """
    moved = np.isfinite(st.response) and st.response_z >= k_sigma
    if force_sign is not None and np.isfinite(st.size):
        return int(np.sign(st.size * force_sign))
    if np.isfinite(st.size) and mounting is not None:
        sign = int(np.sign(st.size * mounting))
        if moved and np.sign(st.response) != sign:
            notes.append("the motion after this step disagrees with the force sign of the run")
        elif not moved:
            notes.append("motion unclear: direction from the force sign of the run")
        return sign
    if moved or not np.isfinite(st.size):
        return int(np.sign(st.response)) or 1
    notes.append("direction from the force step, force sign +1 assumed")
    return int(np.sign(st.size)) or 1


def build_trials(
    run: Run,
    first_index: int,
    given: list[float] | None,
    force_sign: int | None,
    settings: StepSettings,
    source: str,
    *,
    signed: bool | None = None,
) -> list[Trial]:
    """Cut the trials of one run.

    Parameters
    ----------
    run : Run
        The run's steps and windows.
    first_index : int
        Index of its first trial in the log.
    given : list of float or None
        The run's given thrusts: each trial's new level (N); signs, when given, are kept.
    force_sign : int or None
        The user's force sign.
    settings : StepSettings
        Detector constants.
    source : str
        The file, for ``Trial.source``.
    signed : bool or None, optional
        Whether ``given`` carries signs to keep (``--thrust +5,+5``); None: when any
        value is negative; False: magnitudes, signed by the motion.

    Returns
    -------
    list of Trial
    """
    if signed is None:
        signed = given is not None and any(v < 0 for v in given)
    rec = run.rec
    chained = [
        i > 0 and run.windows[i - 1].end_reason == "next step" for i in range(len(run.steps))
    ]
    mounting = mounting_sign(run.steps, settings.response_k_sigma, chained)
    accel = run.motion.accel if run.motion is not None else None
    clipped = clipped_samples(rec)
    force = fill_nan(rec.force) if rec.force is not None else None
    gb = n_samples(settings.guard_before_s, rate_of(rec.time))
    trials: list[Trial] = []
    level_now = 0.0  # the thrust level reached (N, up positive), relative to ref_chain
    ref_chain = np.nan  # force reading at the rest before the chain's first onset
    for j, (st, win) in enumerate(zip(run.steps, run.windows, strict=True)):
        notes = list(run.notes)
        typed: list[Note] = []
        sign = _direction(st, force_sign, mounting, settings.response_k_sigma, notes)
        change = abs(st.size) * sign
        if not chained[j]:
            level_now = 0.0
        if given is not None:
            change, level_new = _given_level(
                given, j, sign, level_now, chained[j], notes, signed=signed, typed=typed
            )
        else:
            level_new = level_now + change
        notes += [] if accel is not None else ["no acceleration channel"]
        notes += _gap_notes(rec, win)
        if clipped is not None:
            clip_note(int(clipped[st.onset : win.stop].sum()), notes, typed)
        sl = slice(win.start, win.stop)
        trial_force = None
        if force is not None and np.isfinite(st.size):
            if not chained[j] or not np.isfinite(ref_chain):
                ref_chain = level(force[win.start : max(win.start + 1, st.onset - gb)])
            orientation = _force_orientation(sign, st, chained[j], mounting, force_sign)
            trial_force = orientation * (force[sl] - ref_chain)
        direction = int(np.sign(level_new)) or sign
        trials.append(
            Trial(
                index=first_index + j,
                recording=rec.name,
                t_step=float(rec.time[st.onset]),
                t_start=float(rec.time[win.start]),
                t_end=float(rec.time[win.stop - 1]),
                thrust_N=float(level_new),
                direction="up" if direction > 0 else "down",
                time=_read_only(rec.time[sl]),
                accel=_trial_accel(accel, sl),
                force=trial_force,
                end_reason=win.end_reason,
                source=source,
                notes=notes,
                thrust_change_N=float(change),
                continues=bool(chained[j]),
                thrust_given=given is not None,
                vertical=vertical_name(run.motion, rec.accel_axes, at=st.onset),
                vertical_sign_known=run.motion is None or run.motion.sign_known,
                typed_notes=typed,
            )
        )
        level_now = level_new
    return trials


def _force_orientation(
    sign: int, st: Step, chained: bool, mounting: int | None, force_sign: int | None
) -> float:
    """The factor turning the force channel into the thrust: the step's direction, or in
    a chain the sensor's mounting (or the sign given)."""
    if chained and mounting is not None:
        return mounting if force_sign is None else force_sign
    return sign * np.sign(st.size)


def _trial_accel(accel: np.ndarray | None, sl: slice) -> np.ndarray:
    """The trial's acceleration (read only), or NaN without an acceleration channel."""
    if accel is None:
        return np.full(sl.stop - sl.start, np.nan)
    return _read_only(accel[sl])


def _gap_notes(rec: Recording, win: Window) -> list[str]:
    """The short gaps a trial's window bridges, counted."""
    bridged = [
        gp for gp in rec.gaps if win.start <= np.searchsorted(rec.time, gp.t_after) < win.stop
    ]
    if not bridged:
        return []
    missing = sum(gp.n_missing for gp in bridged)
    return [f"{len(bridged)} short gap(s) inside ({missing} samples missing)"]


def _given_level(
    given: list[float],
    j: int,
    sign: int,
    level_now: float,
    chained: bool,
    notes: list[str],
    *,
    signed: bool,
    typed: list[Note],
) -> tuple[float, float]:
    """The change and the new level of trial ``j`` from the user's thrusts.

    A given thrust is the trial's new level (N). When the user gave signs (``signed``)
    they are kept, and a sign the motion disagrees with is noted (a
    ``segment.thrust_sign`` warning, never replaced). With magnitudes only, the sign is
    the one that makes the change agree with the motion (the previous level's sign when
    both would). ``typed`` receives the typed warning.
    """
    value = float(given[j])
    notes.append(f"thrust {value:g} N given by the user")
    if signed:
        level_new = value
    else:
        candidates = [value, -value]
        agree = [c for c in candidates if np.sign(c - level_now) == sign]
        if chained and len(agree) == 2 and level_now != 0:
            level_new = abs(value) * float(np.sign(level_now))
        else:
            level_new = agree[0] if agree else abs(value) * sign
    change = level_new - level_now
    if signed and np.sign(change) != sign:
        word = "up" if sign > 0 else "down"
        text = (
            f"warning: the given thrust {value:+g} N changes the thrust "
            f"{'up' if change > 0 else 'down'} but the motion after the onset is {word}; "
            "the given sign is kept (check --thrust or the vertical axis)"
        )
        notes.append(text)
        typed.append(Note("segment.thrust_sign", text))
    return change, level_new


def vertical_name(
    motion: VerticalMotion | None, axes: tuple[str, ...], at: int | None = None
) -> str:
    """Name the vertical (up) direction in the sensor frame: ``"+z"`` or ``"-x, 12 deg off"``.

    Parameters
    ----------
    motion : VerticalMotion or None
        The run's vertical motion (None: no acceleration channel).
    axes : tuple of str
        Names of the acceleration columns.
    at : int, optional
        A sample: the up direction of the orientation the sensor was in there (a sensor
        turned during the run); default the run's main one.

    Returns
    -------
    str
        The nearest signed axis, with the angle to it when over 1 degree; ``""`` without
        acceleration.
    """
    if motion is None or motion.up.size == 0:
        return ""
    return axis_name(np.asarray(motion.up if at is None else motion.up_at(at), float), axes)


def clipped_samples(rec: Recording) -> np.ndarray | None:
    """Where the run's raw acceleration reads a pinned extreme (None: nowhere).

    Parameters
    ----------
    rec : Recording
        The run.

    Returns
    -------
    numpy.ndarray or None
        A mask of the clipped samples, or None when none is.
    """
    from balancer_id.read.validate import clipped_mask

    if rec.accel is None:
        return None
    mask = clipped_mask(np.asarray(rec.accel, dtype=float))
    return mask if mask.any() else None


def clip_note(n: int, notes: list[str], typed: list[Note]) -> None:
    """Add the warning of ``n`` clipped samples in a trial's motion (severity ``error``).

    A sample at the sensor's range holds a bound, not a value; a fit that follows it
    bends ``D0``, ``A`` and ``m_a`` to the clip (issue 31.4), so the trial's fit is not
    trusted: 'diagnose' weighs the clipping as the sensor's explanation.

    Parameters
    ----------
    n : int
        Clipped samples in the motion.
    notes : list of str
        The trial's notes (the warning is added).
    typed : list of Note
        The trial's typed notes (the note is added).
    """
    if n <= 0:
        return
    text = (
        f"warning: {n} acceleration sample(s) in the motion read the sensor's range "
        "(clipped): the fit follows the clip, so its values are not trusted; record with a "
        "wider range, or see 'balancer-id diagnose' (the clipping's explanation)"
    )
    notes.append(text)
    typed.append(Note("read.sensor_limit", text, severity="error"))


def _read_only(view: np.ndarray) -> np.ndarray:
    """A read-only view: trials share the run's samples (a long log is held once) and
    none may change another's."""
    view = view.view()
    view.flags.writeable = False
    return view
