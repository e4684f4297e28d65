"""Find the step trials of a log: detect and window the steps of every run, then assign."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import NoTrialError, UsageError
from balancer_id.notes import Note, has_code
from balancer_id.read.recording import Log, Recording
from balancer_id.segment.accel_steps import detect_accel_steps
from balancer_id.segment.assign import Run, build_trials, mounting_sign, orient, vertical_name
from balancer_id.segment.events import standing_out, without_onset
from balancer_id.segment.gravity import (
    VerticalMotion,
    check_vertical,
    pool_rest_levels,
    vertical_motion,
)
from balancer_id.segment.guided import guided_move
from balancer_id.segment.robust import fill_nan, level, n_samples, rate_of
from balancer_id.segment.steps import (
    SHORT_REST,
    Detection,
    Step,
    StepSettings,
    detect_force_steps,
    gap_breaks,
    measure_responses,
)
from balancer_id.segment.trial import Trial
from balancer_id.segment.window import Channel, Window, channel, end_at_releases, trial_windows
from balancer_id.status import step, tell


def find_trials(
    log: Log,
    *,
    thrusts: Sequence[float] | None = None,
    force_sign: int | None = None,
    vertical: str = "auto",
    g: float = G_DEFAULT,
    min_step_N: float = 0.0,
    thrusts_signed: bool | None = None,
) -> list[Trial]:
    """Find every step trial in every run of a log.

    Steps come from the force channel when there is one (confirmed by the motion that
    follows), else from the vertical acceleration. A run whose force varies without
    steps (a person guiding the load) is one excitation window
    (:func:`~balancer_id.segment.guided.guided_move`). A trial's direction is the sign of
    the acceleration change after its onset, or ``sign(force step * force_sign)`` when
    ``force_sign`` is given. Its thrust is the force step, or the given ``thrusts``.

    Parameters
    ----------
    log : Log
        What a reader returned.
    thrusts : sequence of float, optional
        One thrust (N) per trial found, in order over all runs: each trial's new level.
        They replace the measured force steps (and are required without a force
        channel). Signed thrusts keep their signs (a sign the motion disagrees with is a
        ``segment.thrust_sign`` warning naming the trial); magnitudes take the motion's.
    force_sign : {+1, -1}, optional
        Fixes the direction from the force step: up when ``force step * force_sign > 0``.
    vertical : {"auto", "x", "y", "z", "-z", ...}, optional
        Vertical axis of a linear-acceleration log (see
        :func:`~balancer_id.segment.gravity.vertical_motion`).
    g : float, optional
        Gravity (m/s^2) removed from with-g acceleration.
    min_step_N : float, optional
        Smallest force step reported (N).
    thrusts_signed : bool or None, optional
        Whether ``thrusts`` carry signs to keep (``--thrust +5,+5``); None: signed when
        any value is negative; False: magnitudes.

    Returns
    -------
    list of Trial
        In time order, run by run; ``index`` counts over all runs.

    Raises
    ------
    NoTrialError
        When no step trial is found (the message says what the detector saw), or a log
        without a force channel comes without thrusts (the message lists the onsets).
    LogReadError
        When ``thrusts`` does not hold one value per trial found.
    UsageError
        For an invalid ``force_sign``, ``vertical``, ``thrusts`` or ``min_step_N``.
    """
    given = _check_arguments(thrusts, force_sign, vertical, min_step_N)
    settings = StepSettings(min_step_N=float(min_step_N))
    runs = []
    motions = log_verticals(log, vertical, g)
    for k, (rec, motion) in enumerate(zip(log.recordings, motions, strict=True), 1):
        with step(f"finding the trials of run {k}/{len(log.recordings)}"):
            runs.append(_detect(rec, vertical, g, settings, motion))
    _note_verticals(log, runs)
    total = sum(len(r.steps) for r in runs)
    if total == 0 and given is None:
        found = _guided_moves(log, runs, force_sign, settings)
        if found:
            return found
    _refuse_unusable(log, runs, total, given)
    _note_empty_runs(log, runs)
    _note_missed_motions(log, runs)
    first = np.cumsum([0] + [len(r.steps) for r in runs])
    run_given = [None if given is None else given[a:b] for a, b in itertools.pairwise(first)]
    signed = any(v < 0 for v in given or ()) if thrusts_signed is None else thrusts_signed
    for run, gv in zip(runs, run_given, strict=True):
        orient(run, gv, force_sign, signed=signed)
    _note_verticals(log, runs)  # the signs the force or the thrusts fixed
    trials: list[Trial] = []
    for run, i0, gv in zip(runs, first, run_given, strict=False):
        trials.extend(
            build_trials(run, int(i0), gv, force_sign, settings, str(log.path), signed=signed)
        )
    return trials


def _guided_moves(
    log: Log, runs: list[Run], force_sign: int | None, settings: StepSettings
) -> list[Trial]:
    """Without a step: each run's move guided by a reference (a robot's), numbered."""
    moves = [
        guided_move(
            r.rec,
            r.motion,
            r.breaks,
            force_sign=force_sign,
            settings=settings,
            index=0,
            source=str(log.path),
        )
        for r in runs
    ]
    found = [m for m in moves if m is not None]
    for k, m in enumerate(found):
        m.index = k
    return found


def _refuse_unusable(log: Log, runs: list[Run], total: int, given: list[float] | None) -> None:
    """No trial, thrusts that do not match the trials, or onsets no thrust belongs to."""
    if total == 0:
        why = "; ".join(f"{r.rec.name}: {r.why}" for r in runs) or "the log holds no run"
        lead = ""
        if any(SHORT_REST in r.why for r in runs):
            lead = (
                ": the log starts too soon before its steps (the force's and the "
                "acceleration's zero are read in the rest before each step); record longer "
                "before the first step"
            )
        raise NoTrialError(f"{log.path}: no step trial found{lead} ({why})")
    if given is not None and len(given) != total:  # the option's value is wrong: exit 2
        raise UsageError(
            f"--thrust: {len(given)} thrust(s) given but {log.path} holds {total} step "
            f"trial(s) (onsets at {_onsets(runs)}); give one thrust per trial, in order"
        )
    if given is None and any(st.source == "accel" for r in runs for st in r.steps):
        # without force and without thrusts the onsets are no usable step trials
        missed = _events_hint(runs)
        advice = (
            "give one thrust per onset, in order, with --thrust F1,F2,..."
            if not missed
            else "check every motion with inspect --plot before giving thrusts (one per step "
            "kept, --thrust F1,F2,...; a missed step's stretch with --window START:END)"
        )
        raise NoTrialError(
            f"{log.path}: no step trial found (no force channel and no thrusts given: the "
            f"acceleration shows {total} onset(s) at {_onsets(runs)}{missed}; {advice})"
        )


def _note_empty_runs(log: Log, runs: list[Run]) -> None:
    """A run without a trial says why (counted in one warning beyond a few)."""
    empty = [r for r in runs if not r.steps]
    for r in empty:
        _note_run_without_trial(log, r.rec.name, r.why, quiet=len(empty) > MAX_RUN_WARNINGS)
    if len(empty) > MAX_RUN_WARNINGS:
        text = (
            f"{len(empty)} of {len(runs)} runs gave no step trial ("
            + ", ".join(r.rec.name for r in empty)
            + "); each run's reason is in inspect --json (runs[].no_trial_reason)"
        )
        if text not in log.warnings:
            log.warnings.append(text)


def find_onsets(
    log: Log, *, vertical: str = "auto", g: float = G_DEFAULT, min_step_N: float = 0.0
) -> dict[str, list[float]]:
    """The onsets the detector keeps in every run, without building trials.

    What ``inspect`` lists when a log without a force channel comes without thrusts;
    for tests and benchmarks that count onsets (a phantom onset, one in steady travel).

    Parameters
    ----------
    log : Log
        What a reader returned.
    vertical : str, optional
        Vertical axis (see :func:`find_trials`).
    g : float, optional
        Gravity (m/s^2).
    min_step_N : float, optional
        Smallest force step reported (N).

    Returns
    -------
    dict of str to list of float
        Run name -> onset times (s), in order.
    """
    check_vertical(vertical)
    settings = StepSettings(min_step_N=float(min_step_N))
    out = {}
    for rec, motion in zip(log.recordings, log_verticals(log, vertical, g), strict=True):
        run = _detect(rec, vertical, g, settings, motion)
        out[rec.name] = [float(rec.time[st.onset]) for st in run.steps]
    return out


def _check_arguments(
    thrusts: Sequence[float] | None, force_sign: int | None, vertical: str, min_step_N: float
) -> list[float] | None:
    check_vertical(vertical)
    if force_sign is not None and force_sign not in (1, -1):
        raise UsageError(f"force_sign must be +1 or -1, not {force_sign!r}")
    if not (np.isfinite(min_step_N) and min_step_N >= 0):
        raise UsageError(f"min_step_N must be a number of newtons >= 0, not {min_step_N!r}")
    if thrusts is None:
        return None
    values = [float(v) for v in thrusts]
    if not all(np.isfinite(v) and v != 0 for v in values):
        raise UsageError(f"thrusts must be finite and non-zero (N), got {values}")
    return values


def _events_hint(runs: list[Run]) -> str:
    """``"; 3 more motion(s) stand out with no onset: ..."``, or ``""`` when none do."""
    missed = []
    for r in runs:
        if r.motion is None:
            continue
        onsets = [float(r.rec.time[st.onset]) for st in r.steps]
        missed += without_onset(standing_out(r.rec.time, r.motion.accel), onsets)
    if not missed:
        return ""
    shown = ", ".join(e.text for e in missed[:8]) + (", ..." if len(missed) > 8 else "")
    return (
        f"; {len(missed)} more motion(s) stand out with no onset ({shown}): the log may hold "
        "more steps than the onsets listed"
    )


def _onsets(runs: list[Run]) -> str:
    times = [f"{r.rec.time[st.onset]:.2f} s" for r in runs for st in r.steps]
    return ", ".join(times) if times else "none"


def log_verticals(log: Log, vertical: str, g: float) -> list[VerticalMotion | None]:
    """Every run's vertical motion, their resting level pooled (one sensor, one place:
    :func:`~balancer_id.segment.gravity.pool_rest_levels`).

    Parameters
    ----------
    log : Log
        What a reader returned.
    vertical : str
        The vertical axis setting.
    g : float
        Gravity (m/s^2) removed from with-g acceleration.

    Returns
    -------
    list of VerticalMotion or None
        One per run, in order.
    """
    tell("the vertical")
    motions = [vertical_motion(rec, vertical=vertical, g=g) for rec in log.recordings]
    return pool_rest_levels(motions, g)


def _detect(
    rec: Recording,
    vertical: str,
    g: float,
    settings: StepSettings,
    motion: VerticalMotion | None = None,
) -> Run:
    """Detect the steps of one run (force first, else acceleration) and window them.

    Force steps are measured against the motion twice: up to the next step, then inside
    their windows (a catch left out). A step from rest that no motion follows is
    dropped (see :func:`_moved`), and so is a step found inside the previous trial's
    catch; the windows are then redone.
    """
    if motion is None:
        tell("the vertical")
        motion = vertical_motion(rec, vertical=vertical, g=g)
    breaks = _breaks(rec, motion, settings)
    force = _usable_force(rec)
    accel = motion.accel if motion is not None else None
    if rec.n_samples < 4 or (force is None and accel is None):
        return Run(rec, motion, breaks, [], [], "no usable force or acceleration channel")
    det, what = _first_steps(rec, force, accel, breaks, settings)
    rate = rate_of(rec.time)
    tell("the trials' windows")
    chans = (channel(force, rate, settings), channel(accel, rate, settings))
    steps = det.steps
    while True:
        if force is not None and accel is not None:
            steps = measure_responses(rec.time, accel, steps, breaks, settings)
        windows = _windows(rec.time, chans, steps, breaks, settings)
        if force is not None and accel is not None:
            limits = [
                (w.rest_from if w.rest_from is not None else w.start, w.stop) for w in windows
            ]
            steps = measure_responses(rec.time, accel, steps, breaks, settings, limits)
            windows = _windows(rec.time, chans, steps, breaks, settings)
            still = _still(steps, windows, settings)
            if still:
                det.reject("no motion followed the force step")
                steps = steps[: still[0]] + steps[still[0] + 1 :]
                continue
        caught = _caught(steps, windows)
        if force is not None and not caught:
            released = _released_after_gaps(force, steps, windows, rate, settings)
            if released:
                det.reject("the thrust released after a drop-out (a catch)")
                steps = steps[: released[0]] + steps[released[0] + 1 :]
                continue
        if not caught:
            if accel is None and force is not None:
                steps, windows, dropped = end_at_releases(rec.time, force, steps, windows, settings)
                for _ in range(dropped):
                    det.reject("the thrust released (a catch)")
            return Run(rec, motion, breaks, steps, windows, _why(det, what))
        det.reject("inside a catch")
        steps = steps[: caught[0]] + steps[caught[0] + 1 :]


def _breaks(rec: Recording, motion: Any, settings: StepSettings) -> np.ndarray:
    """Where no window may cross: the drop-outs, and a turned sensor's turns."""
    breaks = gap_breaks(rec, settings.bridge_gap_s)
    if motion is not None and motion.turns:  # a turned sensor: no window crosses a turn
        edges = [i for turn in motion.turns for i in turn if 0 < i < rec.n_samples]
        breaks = np.unique(np.concatenate([breaks, np.asarray(edges, dtype=int)]))
    return breaks


def _usable_force(rec: Recording) -> np.ndarray | None:
    """The force channel with its gaps filled, when it holds two samples or more."""
    usable = rec.force is not None and np.isfinite(rec.force).sum() >= 2
    return fill_nan(rec.force) if usable and rec.force is not None else None


def _first_steps(
    rec: Recording,
    force: np.ndarray | None,
    accel: np.ndarray | None,
    breaks: np.ndarray,
    settings: StepSettings,
) -> tuple[Detection, str]:
    """The steps of the force (else of the acceleration) and what a step is called."""
    if force is not None:
        tell("the force steps")
        return detect_force_steps(rec.time, force, breaks, settings), "force change"
    assert accel is not None
    return detect_accel_steps(rec.time, accel, breaks, settings), "acceleration departure"


def _still(steps: list[Step], windows: list[Window], settings: StepSettings) -> list[int]:
    """The force steps no motion followed (a step chained to the one before excepted)."""
    mounting = mounting_sign(steps, settings.response_k_sigma)
    return [
        i
        for i, st in enumerate(steps)
        if not _moved(st, mounting, settings)
        and not (i and windows[i - 1].end_reason == "next step")
    ]


def _caught(steps: list[Step], windows: list[Window]) -> list[int]:
    """The steps that start before the motion of the one before settled (inside a catch)."""
    return [
        i
        for i in range(1, len(steps))
        if (settled := windows[i - 1].settled) is not None and steps[i].onset < settled
    ]


def _released_after_gaps(
    force: np.ndarray, steps: list[Step], windows: list[Window], rate: float, settings: StepSettings
) -> list[int]:
    """Steps that release the thrust of a trial a drop-out cut short (issue 17.6).

    A trial's window ends at a gap; the load may still move past it. A force step after
    the gap that brings the force back to its rest before the trial (the weight taken
    off as the load is caught) is that trial's catch, as
    :func:`~balancer_id.segment.window.end_at_releases` finds without acceleration, and
    no trial of its own.
    """
    win = n_samples(settings.level_window_s, rate)
    ga = n_samples(settings.guard_after_s, rate)
    gb = n_samples(settings.guard_before_s, rate)
    out = []
    for i in range(1, len(steps)):
        j = i - 1
        if windows[j].end_reason != "gap" or not np.isfinite(steps[j].size):
            continue
        while j and windows[j - 1].end_reason == "next step":
            j -= 1  # first step of the chain the gap cut
        k, k0 = steps[i].onset, steps[j].onset
        rest = level(force[windows[j].start : max(windows[j].start + 1, k0 - gb)])
        after = level(force[k + ga : k + ga + win])
        if abs(after - rest) < 0.25 * abs(steps[i - 1].size):
            out.append(i)
    return out


def _moved(st: Step, mounting: int | None, settings: StepSettings) -> bool:
    """Whether motion followed a force step: a response over ``response_k_sigma``, or
    over ``response_weak_k_sigma`` in the direction the run's other steps predict."""
    if st.response_z >= settings.response_k_sigma:
        return True
    return (
        mounting is not None
        and st.response_z >= settings.response_weak_k_sigma
        and np.sign(st.response) == np.sign(st.size * mounting)
    )


def _windows(
    time: np.ndarray,
    chans: tuple[Channel | None, Channel | None],
    steps: list[Step],
    breaks: np.ndarray,
    settings: StepSettings,
) -> list[Window]:
    """Windows, with each step's motion sign (from the run's mounting when unclear)."""
    k = settings.response_k_sigma
    mounting = mounting_sign(steps, k) or 1
    signs = []
    for st in steps:
        if np.isfinite(st.response) and st.response_z >= k:
            signs.append(int(np.sign(st.response)))
        else:
            signs.append(int(np.sign(st.size * mounting)) if np.isfinite(st.size) else 1)
    return trial_windows(time, *chans, steps, signs, breaks, settings)


#: More runs without a trial than this are summed up in one warning (each keeps its note).
MAX_RUN_WARNINGS = 5


def _note_verticals(log: Log, runs: list[Run]) -> None:
    """Record each run's up direction on the log (``inspect`` shows it with or without
    trials) and note an up axis that is a guess (``read.vertical_guess``, once)."""
    for r in runs:
        m = r.motion
        if m is None:
            continue
        name = vertical_name(m, r.rec.accel_axes)
        log.verticals[r.rec.name] = {
            "vertical": name,
            "vertical_sign_known": bool(m.sign_known),
            "vertical_axis_known": bool(m.axis_known),
        }
        if m.axis_known or has_code(log.notes, "read.vertical_guess", r.rec.name):
            continue
        log.notes.append(
            Note(
                "read.vertical_guess",
                f"{r.rec.name}: the up axis {name} is a guess ({m.method}); give it with "
                "--vertical x|y|z|-z|... if it is another",
                subject=r.rec.name,
                severity="info",
            )
        )


def _note_missed_motions(log: Log, runs: list[Run]) -> None:
    """Note each accel-only run's motions that stand out with no onset (issue 32.4)."""
    for r in runs:
        if r.motion is None or not r.steps or r.steps[0].source != "accel":
            continue
        hint = _events_hint([r])
        if hint:
            text = f"{r.rec.name}: {hint.removeprefix('; ')}; each trial is one onset"
            note = Note("segment.other", text, subject=r.rec.name)
            if note not in log.notes:
                log.notes.append(note)
                log.warnings.append(text)


def _note_run_without_trial(log: Log, run: str, why: str, quiet: bool = False) -> None:
    """Add the note that ``run`` gave no trial, and why, to the log (once)."""
    note = Note("segment.run_without_trial", f"{run}: no step trial found ({why})", subject=run)
    if note not in log.notes:
        log.notes.append(note)
        if not quiet:
            log.warnings.append(note.text)


def _why(det: Detection, what: str) -> str:
    text = f"largest {what} {det.largest:.3g} {det.unit} (threshold {det.threshold:.3g} {det.unit})"
    if det.rejected:
        text += "; candidates dropped: " + ", ".join(
            f"{n} {reason}" for reason, n in det.rejected.items()
        )
    return text
