"""Read logs and find their trials: the shared front half of every command."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import NoTrialError, UsageError
from balancer_id.read.recording import Log
from balancer_id.segment.trial import Trial


@dataclass(frozen=True)
class ReadOptions:
    """How logs are read and segmented (the CLI's common options).

    Attributes
    ----------
    columns : dict or None
        Column map for generic CSVs (``time=..., force=..., ax=...``).
    thrusts : list of float or None
        Thrust of each trial (N), when the force channel is missing or unreliable.
    force_sign : int or None
        Sign of the force channel (+1/-1); None: direction from the motion.
    vertical : str
        ``auto``, ``x``, ``y`` or ``z`` for logs without gravity.
    g : float
        Gravity (m/s^2).
    accel_unit : str
        ``auto``, ``m/s^2`` or ``g``: unit of the acceleration columns (``auto`` reads the
        header and converts evidently-g data with a warning).
    """

    columns: dict[str, str] | None = None
    thrusts: list[float] | None = None
    force_sign: int | None = None
    vertical: str = "auto"
    g: float = G_DEFAULT
    accel_unit: str = "auto"


@dataclass
class LoadedLog:
    """A log and the trials found in it."""

    log: Log
    trials: list[Trial] = field(default_factory=list)


def read(path: str | Path, options: ReadOptions | None = None) -> Log:
    """Read one log with the options' column map and gravity.

    Parameters
    ----------
    path : str or Path
        The CSV log.
    options : ReadOptions, optional
        Only ``columns`` and ``g`` are used here; None uses the defaults.

    Returns
    -------
    Log

    Raises
    ------
    LogReadError
        When the file cannot be read or is not a valid log.
    """
    from balancer_id.read import read_log

    options = options or ReadOptions()
    return read_log(path, columns=options.columns, g=options.g, accel_unit=options.accel_unit)


def segment(log: Log, options: ReadOptions | None = None, trajectory: Any = None) -> list[Trial]:
    """Find the trials of a log (raises NoTrialError when there is none).

    Parameters
    ----------
    log : Log
        A log from :func:`read`.
    options : ReadOptions, optional
        Column map, thrusts, force sign, vertical axis and gravity; None uses the
        defaults.
    trajectory : Trapezoid or TabulatedMove, optional
        A robot's reference move: one move window per run instead of step trials
        (:func:`balancer_id.segment.move.find_moves`).

    Returns
    -------
    list of Trial
        In time order, run by run.

    Raises
    ------
    NoTrialError
        When no step trial is found.
    """
    from balancer_id.segment import find_trials

    options = options or ReadOptions()
    if trajectory is not None:  # robot move (issue 9)
        from balancer_id.segment.move import find_moves

        o = options
        moves = find_moves(log, trajectory, force_sign=o.force_sign, vertical=o.vertical, g=o.g)
        return list(moves)
    return find_trials(
        log,
        thrusts=options.thrusts,
        force_sign=options.force_sign,
        vertical=options.vertical,
        g=options.g,
    )


def load_log(
    path: str | Path, options: ReadOptions | None = None, trajectory: Any = None
) -> LoadedLog:
    """Read one log and find its trials (raises NoTrialError when there is none).

    Parameters
    ----------
    path : str or Path
        The CSV log.
    options : ReadOptions, optional
        Column map, thrusts, force sign, vertical axis and gravity; None uses the
        defaults.
    trajectory : Trapezoid or TabulatedMove, optional
        A robot's reference move (see :func:`segment`).

    Returns
    -------
    LoadedLog

    Raises
    ------
    LogReadError
        When the file cannot be read or is not a valid log.
    NoTrialError
        When no step trial is found.
    """
    log = read(path, options)
    return LoadedLog(log, segment(log, options, trajectory))


def load_trials(
    paths: Sequence[str | Path], options: ReadOptions | None = None, trajectory: Any = None
) -> list[LoadedLog]:
    """Read several logs; trials are renumbered across logs.

    A log without trials is skipped as long as another log has some.

    Parameters
    ----------
    paths : sequence of str or Path
        The CSV logs, in order.
    options : ReadOptions, optional
        Column map, thrusts, force sign, vertical axis and gravity; None uses the
        defaults.
        ``thrusts`` may only be given with a single log.
    trajectory : Trapezoid or TabulatedMove, optional
        A robot's reference move (see :func:`segment`).

    Returns
    -------
    list of LoadedLog
        One per log with trials; ``Trial.index`` counts over all of them.

    Raises
    ------
    UsageError
        ``thrusts`` given with more than one log.
    NoTrialError
        When no log holds a trial.
    """
    options = options or ReadOptions()
    if options.thrusts is not None and len(paths) > 1:
        raise UsageError("--thrust lists the trials of one log; give one log per command")
    loaded = []
    problems = []
    for path in paths:
        try:
            loaded.append(load_log(path, options, trajectory))
        except NoTrialError as exc:
            if len(paths) == 1:
                raise
            problems.append(str(exc))
    if not loaded:
        raise NoTrialError("; ".join(problems) or "no step trial found")
    k = 0
    for item in loaded:
        for trial in item.trials:
            trial.index = k
            k += 1
    return loaded


def describe_log(log: Log, trials: Sequence[Trial]) -> dict[str, object]:
    """The CONTRACT.md ``inspect`` object: what was read and the trials found.

    Parameters
    ----------
    log : Log
        The log as read.
    trials : sequence of Trial
        The trials found in it (may be empty).

    Returns
    -------
    dict
        File, format, sample rate, sample count, gaps, one entry per run (channels,
        time span, saturation), the reader's warnings and the trials.
    """
    runs = []
    gaps = []
    for rec in log.recordings:
        channels = ["time"]
        if rec.force is not None:
            channels.append("force")
        if rec.accel is not None:
            kind = "accel" if rec.accel_includes_gravity else "linear accel"
            channels += [f"{kind} {ax}" for ax in rec.accel_axes]
        channels += list(rec.extra)
        runs.append(
            {
                "name": rec.name,
                "n_samples": rec.n_samples,
                "sample_rate_hz": rec.sample_rate_hz,
                "t_first": float(rec.time[0]) if rec.n_samples else None,
                "t_last": float(rec.time[-1]) if rec.n_samples else None,
                "channels": channels,
                "saturated": dict(rec.saturated),
                **_vertical_of(rec.name, trials),
            }
        )
        gaps += [{"run": rec.name, **g.to_dict()} for g in rec.gaps]
    return {
        "file": str(log.path),
        "format": log.format,
        "sample_rate_hz": log.sample_rate_hz,
        "n_samples": log.n_samples,
        "gaps": gaps,
        "runs": runs,
        "warnings": list(log.warnings),
        "trials": [t.to_dict() for t in trials],
    }


def _vertical_of(run: str, trials: Sequence[Trial]) -> dict[str, object]:
    """The up axis of a run and whether its sign is known, from its trials."""
    for t in trials:
        if t.recording == run and t.vertical:
            return {"vertical": t.vertical, "vertical_sign_known": t.vertical_sign_known}
    return {}
