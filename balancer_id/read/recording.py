"""What a reader returns: one :class:`Log` per file, one :class:`Recording` per run."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from balancer_id.notes import Note
from balancer_id.read.inference import Inference

#: The layouts a reader may report (CONTRACT.md, ``inspect --json`` ``format``).
FORMATS = (
    "pasco-capstone",
    "pasco-sparkvue",
    "phyphox",
    "sensor-logger",
    "vernier",
    "generic",
)


@dataclass(frozen=True)
class Gap:
    """A stretch of dropped samples in a recording's time column.

    Attributes
    ----------
    t_before, t_after : float
        Times (s) of the last sample before and the first sample after the gap.
    n_missing : int
        Samples that the nominal rate says are missing.
    """

    t_before: float
    t_after: float
    n_missing: int

    def to_dict(self) -> dict[str, float | int]:
        """Return the gap as a JSON-ready dict."""
        return {"t_before": self.t_before, "t_after": self.t_after, "n_missing": self.n_missing}


@dataclass
class Recording:
    """One run of a log, on its own time base.

    Attributes
    ----------
    name : str
        The run's name as the export wrote it (``"Run 1"``, ``"Run #2"``, ``"9.9"``, ...).
    time : numpy.ndarray
        Sample times (s), strictly increasing, as in the file (the first need not be 0).
    force : numpy.ndarray or None
        Force channel (N), sensor convention (compression positive), or None when absent.
    accel : numpy.ndarray or None
        Acceleration, shape ``(n, k)`` with ``k`` = 1 or 3 (m/s^2), sensor frame.
    accel_includes_gravity : bool
        True when the accelerometer reads specific force (``+g`` up at rest); False for
        "linear acceleration" exports (phyphox "without g").
    accel_axes : tuple of str
        Axis labels of the ``accel`` columns (``("x", "y", "z")`` or ``("z",)``).
    sample_rate_hz : float
        Rate estimated from the median time step.
    gaps : list of Gap
        Dropped-sample stretches (a step longer than 1.5 nominal steps).
    saturated : dict
        Channel name -> number of samples at the sensor's limits.
    extra : dict
        Other numeric channels kept by name (gyro, position, ...).
    started_at : float or None
        When the run's first sample was taken, in seconds since 1970 (UTC), when the file
        says: a clock time in its time column (epoch ms/µs/ns, Sensor Logger's ``time``),
        or a date-and-time column (SPARKvue; a wall clock without zone, taken in this
        machine's time zone, to the second); None otherwise.
    """

    name: str
    time: np.ndarray
    force: np.ndarray | None = None
    accel: np.ndarray | None = None
    accel_includes_gravity: bool = True
    accel_axes: tuple[str, ...] = ("x", "y", "z")
    sample_rate_hz: float = float("nan")
    gaps: list[Gap] = field(default_factory=list)
    saturated: dict[str, int] = field(default_factory=dict)
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    started_at: float | None = None

    @property
    def n_samples(self) -> int:
        """Number of samples in the run."""
        return int(self.time.size)


@dataclass
class Log:
    """Everything read from one file.

    Attributes
    ----------
    path : pathlib.Path
        The file read.
    format : str
        One of :data:`FORMATS`.
    recordings : list of Recording
        One per run, in file order.
    warnings : list of str
        Things the user should know (saturation, gaps, guessed units), as text.
    notes : list of Note
        The same, typed (:class:`~balancer_id.notes.Note`: a code such as
        ``read.time_unit``, ``read.gravity_header``, ``read.column_guess``, a subject and
        the text); code decides on ``note.code``. Remarks without a code of their own
        carry ``read.other``.
    verticals : dict of str to dict
        Run name -> how its vertical was found, once the log was segmented:
        ``{"vertical": "+z, 12 deg off", "vertical_sign_known": bool,
        "vertical_axis_known": bool}`` (``inspect`` shows it with or without trials).
    inferences : list of Inference
        What the reader decided that the file does not state outright (layout, columns,
        time unit, acceleration unit, gravity), each with its evidence and the option
        that overrides it (:mod:`~balancer_id.read.inference`).
    """

    path: Path
    format: str
    recordings: list[Recording]
    warnings: list[str] = field(default_factory=list)
    notes: list[Note] = field(default_factory=list)
    verticals: dict[str, dict[str, object]] = field(default_factory=dict)
    inferences: list[Inference] = field(default_factory=list)
    #: True once the runs' force, acceleration and extra channels were released
    #: (:meth:`without_channels`).
    channels_released: bool = False

    @property
    def n_samples(self) -> int:
        """Total samples over all runs."""
        return sum(r.n_samples for r in self.recordings)

    def without_channels(self) -> Log:
        """This log with each run's force, acceleration and extra channels released.

        What a fit keeps once the trials are cut (they hold the samples they use): the
        runs' names, times, rates, gaps and clocks, and the log's notes. A shift-long
        log's raw channels are its largest arrays; :func:`balancer_id.trials.read` gives
        them whole.

        Returns
        -------
        Log
            A new log; this one is unchanged.
        """
        runs = [dataclasses.replace(r, force=None, accel=None, extra={}) for r in self.recordings]
        return dataclasses.replace(self, recordings=runs, channels_released=True)

    @property
    def started_at(self) -> float | None:
        """When the recording started (s since 1970, UTC), when the file says; else None."""
        times = [r.started_at for r in self.recordings if r.started_at is not None]
        return min(times) if times else None

    @property
    def sample_rate_hz(self) -> float:
        """The rate of the longest run (Hz)."""
        longest = max(self.recordings, key=lambda r: r.n_samples)
        return longest.sample_rate_hz
