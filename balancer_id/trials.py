"""The door: logs are read and segmented here, once, into a typed :class:`TrialSet`.

Everything below this module works on trials, never on paths: the CLI and the public API
turn what the user gave (paths, options, a reference move) into a :class:`TrialSet` with
:func:`load_trials`, and the identification, the diagnosis and the reports take it from
there. A :class:`ReadOptions` checks itself when it is made, so a bad option fails before
any file is read (exit code 2).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import NoTrialError, UsageError
from balancer_id.notes import Note, as_note, notes_json
from balancer_id.read.recording import Log
from balancer_id.segment.trial import Trial

if TYPE_CHECKING:
    pass

#: Values of ``vertical``.
VERTICAL_AXES = ("auto", "x", "y", "z")


@dataclass(frozen=True)
class OptionSpelling:
    """How one reading option is spelled on the command line.

    Every command that reads logs declares these options from :data:`READ_OPTION_SPELLINGS`
    (:func:`balancer_id.cli.options.reads_logs`) and hands their values to
    :meth:`ReadOptions.from_text`, so a new reading option is a row there, a field of
    :class:`ReadOptions` and its spelling in :meth:`ReadOptions.from_text`: this module.

    Attributes
    ----------
    name : str
        The keyword of :meth:`ReadOptions.from_text` (and of the command's parameter).
    flag : str
        The option (``--thrust``).
    kind : object
        The value's type as the command line gives it (``str | None``).
    default : object
        The value when the option is not given.
    metavar : str
        What the value is, in words (TEXT, NUMBER...).
    help : str
        One line of help.
    """

    name: str
    flag: str
    kind: Any
    default: Any
    metavar: str
    help: str


#: The reading options of every command that reads logs, in the order ``--help`` lists them.
READ_OPTION_SPELLINGS: tuple[OptionSpelling, ...] = (
    OptionSpelling("thrust", "--thrust", str | None, None, "TEXT",
                   "Thrust of each trial in N, e.g. 2.45,-4.9 (one log)."),
    OptionSpelling("force_sign", "--force-sign", int | None, None, "INTEGER",
                   "+1 or -1: fix the sign of the force channel."),
    OptionSpelling("vertical", "--vertical", str, "auto", "TEXT",
                   "auto|x|y|z|-z|...: up axis of logs without gravity."),
    OptionSpelling("columns", "--columns", str | None, None, "TEXT",
                   "Column map of a generic CSV: time=t,force=F,ax=..."),
    OptionSpelling("g", "--g", float, G_DEFAULT, "NUMBER", "Gravity in m/s^2."),
    OptionSpelling("accel_unit", "--accel-unit", str, "auto", "TEXT",
                   "auto|m/s^2|g: unit of the acceleration columns."),
    OptionSpelling("window", "--window", list[str] | None, None, "TEXT...",
                   "START:END in s: a stretch where only the measured force acts (repeatable); "
                   "each is a trial, nothing is detected (a lab rig)."),
    OptionSpelling("force_delay", "--force-delay", float, 0.0, "SECONDS",
                   "The force channel's lag behind the acceleration (s; diagnose measures it)."),
)


def _checked_delay(value: object) -> float:
    """``--force-delay`` as seconds, refused beyond a second either way."""
    try:
        delay = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise UsageError(f"--force-delay {value!r}: give seconds, e.g. 0.04") from None
    if not (math.isfinite(delay) and abs(delay) < 1.0):
        raise UsageError(
            f"--force-delay {value}: give the force channel's lag in seconds, "
            "between -1 and 1 (e.g. 0.04)"
        )
    return delay


@dataclass(frozen=True)
class ReadOptions:
    """How logs are read and segmented (the CLI's common options); checked when made.

    Attributes
    ----------
    columns : dict or None
        Column map for generic CSVs (``time=..., force=..., ax=...``).
    thrusts : list of float or None
        Thrust of each trial (N), when the force channel is missing or unreliable.
    thrusts_signed : bool or None
        Whether the thrusts carry signs to keep (``--thrust +5,-2``: a value written with
        ``+`` or ``-`` makes the list signed); False: magnitudes, the sign of each comes
        from the motion; None (the default): signed when any value is negative.
    force_sign : int or None
        Sign of the force channel (+1/-1); None: direction from the motion.
    vertical : str
        ``auto``, ``x``, ``y`` or ``z`` for logs without gravity.
    g : float
        Gravity (m/s^2), positive and finite.
    accel_unit : str
        ``auto``, ``m/s^2`` or ``g``: unit of the acceleration columns (``auto`` reads the
        header and converts evidently-g data with a warning).
    windows : tuple of (float, float)
        ``--window START:END``: stretches (s) where only the measured force acts; each is
        a trial and nothing is detected (a lab rig, a free motion).
    force_delay : float
        ``--force-delay S``: the force channel's time stamps run this late behind the
        acceleration's (s; negative: the acceleration is the late one); the force is
        moved back by it when read (``diagnose`` measures it: ``detail.force_delay_s``).

    Raises
    ------
    UsageError
        When an option is out of its range (the message names the option).
    """

    columns: dict[str, str] | None = None
    thrusts: list[float] | None = None
    force_sign: int | None = None
    vertical: str = "auto"
    g: float = G_DEFAULT
    accel_unit: str = "auto"
    windows: tuple[tuple[float, float], ...] = ()
    thrusts_signed: bool | None = None
    force_delay: float = 0.0

    def __post_init__(self) -> None:
        from balancer_id.read.units import check_accel_unit

        if self.force_sign not in (None, 1, -1):
            raise UsageError("--force-sign must be +1 or -1")
        axis = self.vertical.lstrip("+-")
        if axis not in VERTICAL_AXES or (axis == "auto" and self.vertical != "auto"):
            raise UsageError("--vertical must be auto or an axis with an optional sign: x, -z, +y")
        try:
            g = float(self.g)
        except (TypeError, ValueError):
            raise UsageError(f"--g {self.g!r}: give gravity in m/s^2, e.g. 9.81") from None
        if not (math.isfinite(g) and g > 0):
            raise UsageError(f"--g {self.g}: gravity must be a positive number of m/s^2, e.g. 9.81")
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "accel_unit", check_accel_unit(self.accel_unit))
        object.__setattr__(self, "force_delay", _checked_delay(self.force_delay))
        self._check_lists()

    def _check_lists(self) -> None:
        """Check and normalize the windows, thrusts and column map."""
        from balancer_id.read.generic import MAP_KEYS

        if self.windows:
            from balancer_id.segment.given_windows import check_windows

            object.__setattr__(self, "windows", tuple(check_windows(self.windows)))
        if self.thrusts is not None:
            thrusts = [float(f) for f in self.thrusts]
            if not all(math.isfinite(f) for f in thrusts):
                raise UsageError("--thrust: give each trial's thrust in N as a finite number")
            object.__setattr__(self, "thrusts", thrusts)
            if self.thrusts_signed is None:
                object.__setattr__(self, "thrusts_signed", any(f < 0 for f in thrusts))
        if self.columns is not None:
            cmap = {str(k).strip().lower(): str(v).strip() for k, v in self.columns.items()}
            unknown = sorted(set(cmap) - set(MAP_KEYS))
            if unknown:
                raise UsageError(
                    f"unknown column role(s) {', '.join(unknown)} in the column map; "
                    f"use {', '.join(MAP_KEYS)}"
                )
            if not all(cmap.values()):
                raise UsageError("--columns: every role needs a column name, e.g. time=t")
            object.__setattr__(self, "columns", cmap)

    @classmethod
    def from_text(
        cls,
        *,
        thrust: str | None = None,
        force_sign: int | None = None,
        vertical: str = "auto",
        columns: str | None = None,
        g: float = G_DEFAULT,
        accel_unit: str = "auto",
        window: list[str] | None = None,
        force_delay: float = 0.0,
    ) -> ReadOptions:
        """Build from the command-line spelling (``--thrust 2.45,-4.9``, ``--columns t=..``).

        Parameters
        ----------
        thrust : str, optional
            Thrusts in N separated by commas.
        force_sign : int, optional
            +1 or -1.
        vertical : str
            ``auto``, ``x``, ``y`` or ``z``.
        columns : str, optional
            ``ROLE=COLUMN`` pairs separated by commas.
        g : float
            Gravity (m/s^2).
        accel_unit : str
            ``auto``, ``m/s^2`` or ``g``.
        window : list of str, optional
            ``START:END`` stretches in seconds (``--window``, repeatable).
        force_delay : float
            ``--force-delay``: the force channel's lag (s).

        Returns
        -------
        ReadOptions

        Raises
        ------
        UsageError
            A malformed list or an option out of range.
        """
        thrusts = None
        signed = None
        if thrust is not None:
            items = [x.strip() for x in thrust.split(",")]
            if not all(items):
                raise UsageError(
                    f"--thrust '{thrust}': an empty item; give one number per trial, "
                    "separated by commas (e.g. 2.45,-2.45)"
                )
            try:
                thrusts = [float(x) for x in items]
            except ValueError:
                raise UsageError(f"--thrust '{thrust}': give numbers separated by commas") from None
            # a sign written on any value (+5 or -5) is kept: the list is signed
            signed = any(x[0] in "+-" for x in items)
        cmap = None
        if columns:
            cmap = {}
            for item in columns.split(","):
                key, sep, value = item.partition("=")
                if not sep:
                    raise UsageError(f"--columns '{item}': expected ROLE=COLUMN, e.g. time=t")
                cmap[key.strip()] = value.strip()
        windows = []
        for item in window or []:
            start, sep, end = item.partition(":")
            try:
                windows.append((float(start), float(end)))
            except ValueError:
                raise UsageError(
                    f"--window '{item}': give START:END in seconds, e.g. 2.05:5.4"
                ) from None
            if not sep:
                raise UsageError(f"--window '{item}': give START:END in seconds, e.g. 2.05:5.4")
        return cls(
            columns=cmap,
            thrusts=thrusts,
            force_sign=force_sign,
            vertical=vertical,
            g=g,
            accel_unit=accel_unit,
            windows=tuple(windows),
            thrusts_signed=signed,
            force_delay=force_delay,
        )

    def to_dict(self) -> dict[str, object]:
        """Every option, JSON-ready (for cache keys and provenance)."""
        return {
            "columns": dict(self.columns) if self.columns is not None else None,
            "thrusts": list(self.thrusts) if self.thrusts is not None else None,
            "thrusts_signed": self.thrusts_signed,
            "force_sign": self.force_sign,
            "vertical": self.vertical,
            "g": self.g,
            "accel_unit": self.accel_unit,
            "windows": [list(w) for w in self.windows],
            **({"force_delay": self.force_delay} if self.force_delay else {}),
        }

    def cli_args(self) -> list[str]:
        """The command-line options that reproduce these options (defaults left out).

        Returns
        -------
        list of str
            E.g. ``["--thrust", "2.45,-4.9", "--g", "9.81"]``.
        """
        args: list[str] = []
        if self.thrusts is not None:
            spell = "{:+}" if self.thrusts_signed else "{}"
            args += ["--thrust", ",".join(spell.format(f) for f in self.thrusts)]
        if self.force_sign is not None:
            args += ["--force-sign", str(self.force_sign)]
        if self.vertical != "auto":
            args += ["--vertical", self.vertical]
        if self.columns is not None:
            args += ["--columns", ",".join(f"{k}={v}" for k, v in self.columns.items())]
        if self.g != G_DEFAULT:
            args += ["--g", repr(self.g)]
        if self.accel_unit != "auto":
            args += ["--accel-unit", self.accel_unit]
        for start, end in self.windows:
            args += ["--window", f"{start:g}:{end:g}"]
        if self.force_delay:
            args += ["--force-delay", f"{self.force_delay:g}"]
        return args


def trajectory_text(trajectory: Any) -> str | None:
    """The ``--trajectory`` spelling of a reference move, when it has one.

    Parameters
    ----------
    trajectory : Trapezoid or TabulatedMove
        The robot's reference move.

    Returns
    -------
    str or None
        ``"trapezoid:distance=D,speed=V,accel=A,start=T"`` for a trapezoid (round-trips
        through :func:`~balancer_id.simulation.inputs.parse_trajectory`; ``start=0`` means
        "find it in the log" there too); None for a table, which is named by its file.
    """
    t = trajectory
    if not all(hasattr(t, k) for k in ("distance", "speed", "accel")):
        return None
    return (
        f"trapezoid:distance={t.distance!r},speed={t.speed!r},accel={t.accel!r},start={t.start!r}"
    )


@dataclass
class LoadedLog:
    """A log and the trials found in it.

    ``log`` keeps the runs' names, times, rates, gaps, clocks and notes; their force and
    acceleration channels are released once the trials are cut (see
    :meth:`~balancer_id.read.recording.Log.without_channels`): :func:`read` gives them.
    """

    log: Log
    trials: list[Trial] = field(default_factory=list)


@dataclass
class TrialSet:
    """The trials of one request, with where they came from and how they were read.

    Attributes
    ----------
    logs : list of LoadedLog
        The logs read, each with its trials (``Trial.index`` counts over all of them).
    options : ReadOptions
        How the logs were read and segmented.
    trajectory : Trapezoid, TabulatedMove or None
        The robot's reference move, when a robot held the load (``servo``).
    loose : list
        Trials given ready-made (segmented :class:`Trial` objects or the fitters'
        ``TrialData``), after those of the logs.
    trajectory_source : str or None
        ``--trajectory`` as given (a spec or a CSV file), for printed commands.
    """

    logs: list[LoadedLog] = field(default_factory=list)
    options: ReadOptions = field(default_factory=ReadOptions)
    trajectory: Any = None
    loose: list[object] = field(default_factory=list)
    trajectory_source: str | None = None

    @property
    def paths(self) -> list[str]:
        """The logs read, as given."""
        return [str(item.log.path) for item in self.logs]

    @property
    def trials(self) -> list[Trial]:
        """The segmented trials of the logs, in order."""
        return [t for item in self.logs for t in item.trials]

    def __len__(self) -> int:
        return len(self.trials) + len(self.loose)

    def trial_notes(self) -> list[Note]:
        """The warnings of the segmented trials, each named by its trial (see
        :func:`trial_notes`), for the top-level ``warnings`` of a fit."""
        return trial_notes(self.trials)

    def option_args(self) -> list[str]:
        """The command-line options that reproduce how this set was read.

        Returns
        -------
        list of str
            The reading options that differ from their defaults and ``--trajectory``
            when a reference move is known (the logs are :attr:`paths`).
        """
        args = self.options.cli_args()
        if self.trajectory is not None:
            text = self.trajectory_source or trajectory_text(self.trajectory)
            if text is not None:
                args += ["--trajectory", text]
        return args


def read(path: str | Path, options: ReadOptions | None = None) -> Log:
    """Read one log with the options' column map, gravity and acceleration unit.

    Parameters
    ----------
    path : str or Path
        The CSV log.
    options : ReadOptions, optional
        Only ``columns``, ``g`` and ``accel_unit`` are used here; None uses the defaults.

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
    log = read_log(path, columns=options.columns, g=options.g, accel_unit=options.accel_unit)
    return _force_moved(log, options.force_delay) if options.force_delay else log


def _force_moved(log: Log, delay: float) -> Log:
    """``log`` with each run's force moved ``delay`` s earlier (``--force-delay``).

    The force sampled at ``t + delay`` belongs to ``t``: interpolated between its own
    samples (blank cells left blank), held at the run's ends.
    """
    import dataclasses

    import numpy as np

    runs = []
    for rec in log.recordings:
        if rec.force is None:
            runs.append(rec)
            continue
        force = np.asarray(rec.force, dtype=float)
        ok = np.isfinite(force)
        moved = np.full_like(force, np.nan)
        if ok.sum() >= 2:
            moved[ok] = np.interp(rec.time[ok] + delay, rec.time[ok], force[ok])
        runs.append(dataclasses.replace(rec, force=moved))
    return dataclasses.replace(log, recordings=runs)


def segment(log: Log, options: ReadOptions | None = None, trajectory: Any = None) -> list[Trial]:
    """Find the trials of a log (raises NoTrialError when there is none).

    Parameters
    ----------
    log : Log
        A log from :func:`read`.
    options : ReadOptions, optional
        Thrusts, force sign, vertical axis and gravity; None uses the defaults.
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
    if options.windows:  # the user's stretches: no detection (a lab rig)
        from balancer_id.segment.given_windows import window_trials

        o = options
        return window_trials(log, o.windows, vertical=o.vertical, g=o.g, force_sign=o.force_sign)
    return find_trials(
        log,
        thrusts=options.thrusts,
        thrusts_signed=options.thrusts_signed,
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
        How the log is read and segmented; None uses the defaults.
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
    trials = segment(log, options, trajectory)
    # the trials hold the samples they use; the raw channels (a long log's largest
    # arrays) are not kept with them
    return LoadedLog(log.without_channels(), trials)


def reference_move(spec: str | Path) -> Any:
    """The robot's reference move from its ``--trajectory`` spelling.

    Parameters
    ----------
    spec : str or Path
        ``"trapezoid:distance=..,speed=..,accel=..[,start=..]"`` or a CSV file of
        time,position rows.

    Returns
    -------
    Trapezoid or TabulatedMove

    Raises
    ------
    UsageError
        A malformed ``trapezoid:`` spec.
    LogReadError
        A trajectory file that cannot be read.
    """
    from balancer_id.segment.move import read_trajectory_csv
    from balancer_id.simulation.inputs import parse_trajectory

    text = str(spec).strip()
    if not text.startswith("trapezoid") and Path(text).is_file():  # time,position (issue 9)
        return read_trajectory_csv(text)
    try:
        return parse_trajectory(text)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def load_trials(
    paths: str | Path | Sequence[str | Path],
    options: ReadOptions | None = None,
    trajectory: Any = None,
    trajectory_source: str | None = None,
) -> TrialSet:
    """Read and segment logs into one :class:`TrialSet`; trials are renumbered across logs.

    A log without trials is skipped as long as another log has some.

    Parameters
    ----------
    paths : str, Path or sequence of them
        One log or several, in order.
    options : ReadOptions, optional
        How the logs are read and segmented; None uses the defaults. ``thrusts`` may only
        be given with a single log.
    trajectory : Trapezoid, TabulatedMove, str or Path, optional
        The robot's reference move, when a robot held the load (``servo``): each log
        then holds move windows instead of step trials. Text is read by
        :func:`reference_move` (``"trapezoid:..."`` or a CSV file of time,position).
    trajectory_source : str, optional
        ``--trajectory`` as the user gave it (kept for printed commands).

    Returns
    -------
    TrialSet
        One :class:`LoadedLog` per log with trials; ``Trial.index`` counts over all.

    Raises
    ------
    UsageError
        ``thrusts`` given with more than one log, or no log at all.
    NoTrialError
        When no log holds a trial.
    """
    if isinstance(paths, str | Path):
        paths = [paths]
    paths = list(paths)
    if not paths:
        raise UsageError("give at least one log")
    if isinstance(trajectory, str | Path):
        trajectory_source = trajectory_source or str(trajectory)
        trajectory = reference_move(trajectory)
    options = options or ReadOptions()
    if options.thrusts is not None and len(paths) > 1:
        raise UsageError("--thrust lists the trials of one log; give one log per command")
    refuse_same_file_twice(paths)
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
    return TrialSet(loaded, options, trajectory, trajectory_source=trajectory_source)


def refuse_same_file_twice(paths: Sequence[str | Path]) -> None:
    """Refuse a log given twice, by any name (a copy, a link, another path to it).

    Its trials would count twice: every standard error would shrink by sqrt(2) for
    nothing measured.

    Parameters
    ----------
    paths : sequence of str or Path
        The logs, as given.

    Raises
    ------
    UsageError
        Two of them with the same contents (their SHA-256), naming both.
    """
    import hashlib

    if len(paths) < 2:
        return
    seen: dict[tuple[int, str], str | Path] = {}
    for path in paths:
        try:
            size = Path(path).stat().st_size
            digest = hashlib.sha256()
            with open(path, "rb") as fh:
                for block in iter(partial(fh.read, 1 << 20), b""):
                    digest.update(block)
        except OSError:
            continue  # the reader says what is wrong with it
        key = (size, digest.hexdigest())
        if key in seen:
            raise UsageError(
                f"{path} and {seen[key]} hold the same log (identical contents): its trials "
                "would count twice and every standard error shrink by 1.4x for nothing "
                "measured; give each log once"
            )
        seen[key] = path


def as_trial_set(
    sources: TrialSet | str | Path | Sequence[object],
    options: ReadOptions | None = None,
    trajectory: Any = None,
) -> TrialSet:
    """What the public functions accept, as a :class:`TrialSet`.

    Parameters
    ----------
    sources : TrialSet, str, Path or sequence
        A ready set (returned as is), one log path, or a sequence of log paths and
        ready-made trials (segmented :class:`Trial` or ``TrialData``), mixed freely; the
        trials of the logs come first.
    options : ReadOptions, optional
        How the logs are read; None uses the defaults. Not allowed with a ready set.
    trajectory : Trapezoid, TabulatedMove, str or Path, optional
        The robot's reference move (text as for :func:`reference_move`); not allowed with
        a ready set (it carries its own).

    Returns
    -------
    TrialSet

    Raises
    ------
    UsageError
        Options or a trajectory given with a ready set.
    """
    if isinstance(sources, TrialSet):
        if options is not None or trajectory is not None:
            raise UsageError(
                "a TrialSet carries its reading options and reference move; "
                "give them to load_trials instead"
            )
        return sources
    if isinstance(sources, str | Path):
        sources = [sources]
    paths = [s for s in sources if isinstance(s, str | Path)]
    loose = [s for s in sources if not isinstance(s, str | Path)]
    if paths:
        ts = load_trials(paths, options, trajectory)
    else:
        source = str(trajectory) if isinstance(trajectory, str | Path) else None
        if source is not None:
            trajectory = reference_move(source)
        ts = TrialSet(
            options=options or ReadOptions(), trajectory=trajectory, trajectory_source=source
        )
    ts.loose = loose
    return ts


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

    Raises
    ------
    ValueError
        For a log whose channels were released (the one a :class:`LoadedLog` keeps).
    """
    if log.channels_released:
        raise ValueError(
            f"{log.path}: describe the log as read (balancer_id.trials.read), not the one "
            "kept with its trials (its channels were released)"
        )
    runs = []
    gaps = []
    # a trial's warnings reach the top level, named by the trial
    trial_warnings: list[Note | str] = list(trial_notes(trials))
    if log.recordings and all(rec.accel is None for rec in log.recordings):
        trial_warnings.insert(
            0,
            "no acceleration channel: the trials found cannot be identified (fit needs the "
            "load's acceleration); record or export it, or map it with --columns a=COLUMN",
        )
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
                **_vertical_of(log, rec.name, trials),
                **_no_trial_reason(log, rec.name, trials),
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
        "warnings": [*log.warnings, *(str(w) for w in trial_warnings)],
        "notes": notes_json([*log.notes, *(as_note(w, "segment.other") for w in trial_warnings)]),
        "inferences": [i.to_dict() for i in getattr(log, "inferences", [])],
        "trials": [t.to_dict() for t in trials],
    }


def trial_notes(trials: Sequence[Trial]) -> list[Note]:
    """The warnings of the trials (their notes starting with ``warning:``), each named by
    its trial, for a result's top-level ``warnings`` and ``notes``.

    Parameters
    ----------
    trials : sequence of Trial
        Segmented trials.

    Returns
    -------
    list of Note
        ``"trial N: ..."``, with the trial's code (``segment.thrust_sign``) or
        ``segment.other``, subject ``"trial N"``.
    """
    out = []
    for t in trials:
        subject = f"trial {t.index}"
        typed = {n.text: n for n in getattr(t, "typed_notes", ())}
        for text in map(str, t.notes):
            if text.startswith("warning:"):
                own = typed.get(text)
                said = text.removeprefix("warning:").strip()
                if own is not None:
                    out.append(Note(own.code, f"{subject}: {said}", subject, own.severity))
                else:
                    out.append(Note("segment.other", f"{subject}: {said}", subject, "warning"))
    return out


def _no_trial_reason(log: Log, run: str, trials: Sequence[Trial]) -> dict[str, object]:
    """``{"no_trial_reason": ...}`` for a run that gave no trial (when the log says why)."""
    if any(t.recording == run for t in trials):
        return {}
    for note in log.notes:
        if note.code == "segment.run_without_trial" and note.subject == run:
            return {"no_trial_reason": note.text}
    return {}


def _vertical_of(log: Log, run: str, trials: Sequence[Trial]) -> dict[str, object]:
    """The up axis of a run, whether its sign and the axis itself are known: from the
    segmentation (with or without trials), else from its trials."""
    found = dict(log.verticals.get(run, {}))
    for t in trials:
        if t.recording == run and t.vertical:
            found.setdefault("vertical", t.vertical)
            found["vertical_sign_known"] = t.vertical_sign_known
            break
    return found
