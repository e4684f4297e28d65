"""The time column's unit: from the header, the column's name, the column map, or the values.

Rules (in this order):

* the column map's unit (``--columns time=Time_ms:ms``) or a layout's (Sensor Logger's
  ``time`` is in ns);
* the unit in the header (``Time (ms)``, ``t (us)``);
* a unit word ending the name (``Time_ms``, ``timestamp_ns``, ``seconds_elapsed``);
* the values: beyond 1e17 they are ns since 1970 (19 digits), beyond 1e14 µs, beyond
  1e11 ms; else seconds.

A time beyond 1e8 s (three years) once in seconds is a clock time since 1970 (epoch):
the run's times are counted from its first sample (so no precision is lost) and the
clock time of that sample is kept as :attr:`~balancer_id.read.recording.Recording.started_at`.
Every unit other than seconds read from a ``(s)`` header is stated in a note
``read.time_unit``.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np

from balancer_id.read.header import TIME_UNITS, Column

#: A time beyond this (s) counts from 1970: a clock time, not a time since the start.
EPOCH_MIN_S = 1e8
#: ... up to the year 2100; beyond, the unit is wrong (the rate note says which fits).
EPOCH_MAX_S = 4.1e9
#: Value thresholds of a time column without a unit: (bound, unit), largest first.
_VALUE_UNITS = ((1e17, "ns"), (1e14, "us"), (1e11, "ms"))
_NAMES = {"s": "s", "sec": "s", "secs": "s", "seconds": "s", "msec": "ms", "millis": "ms"}
_NAMES.update({"micros": "us", "µs": "us", "μs": "us", "nanos": "ns", "min": "min"})


def canonical(unit: str) -> str:
    """The short name of a time unit (``"msec"`` -> ``"ms"``, ``"µs"`` -> ``"us"``).

    Parameters
    ----------
    unit : str
        The unit as written.

    Returns
    -------
    str
        ``"s"``, ``"ms"``, ``"us"``, ``"ns"`` or ``"min"`` (anything else lower-cased).
    """
    key = unit.strip().lower()
    return _NAMES.get(key, key)


def unit_of_column(col: Column) -> tuple[str, str]:
    """The unit a time column states, and where: ``("ms", "header")``, ``("", "")``.

    Parameters
    ----------
    col : Column
        The time column.

    Returns
    -------
    tuple of str
        Unit (a key of :data:`~balancer_id.read.header.TIME_UNITS`, canonical) and its
        source ``"header"`` or ``"name"``; ``("", "")`` when the column states none.
    """
    if col.unit and col.unit.strip().lower() in TIME_UNITS:
        return canonical(col.unit), "header"
    words = [w for w in re.split(r"[^\wµμ]+|_", re.sub(r"([a-z])([A-Z])", r"\1 \2", col.raw)) if w]
    for word in reversed(words[1:] if len(words) > 1 else []):
        if word.lower() in TIME_UNITS:
            return canonical(word), "name"
    return "", ""


@dataclass(frozen=True)
class TimeBase:
    """A time column in seconds.

    Attributes
    ----------
    seconds : numpy.ndarray
        The times (s); counted from the first sample for a clock time.
    unit : str
        The unit the values were in (``"s"``, ``"ms"``, ``"us"``, ``"ns"``, ``"min"``).
    source : str
        Where the unit came from: ``"map"``, ``"layout"``, ``"header"``, ``"name"``,
        ``"values"`` or ``"default"``.
    started_at : float or None
        For a clock time, the first sample's time in seconds since 1970 (UTC).
    clock : str
        The column ``started_at`` was read from when it is not the time column.
    """

    seconds: np.ndarray
    unit: str
    source: str
    started_at: float | None = None
    clock: str = ""

    def note(self, column: str) -> str | None:
        """The ``read.time_unit`` sentence, or None when the time is plain seconds.

        Parameters
        ----------
        column : str
            The time column's name as written.

        Returns
        -------
        str or None
        """
        if self.unit == "s" and self.started_at is None and self.source in ("header", "default"):
            return None
        where = {
            "map": "from the column map",
            "layout": "from the export's layout",
            "header": "from the header",
            "name": "from the column's name",
            "values": "from the size of its values",
            "default": "no unit stated",
        }[self.source]
        text = f"time column '{column}' read in {self.unit} ({where})"
        if self.started_at is not None:
            stamp = datetime.fromtimestamp(self.started_at, tz=UTC)
            if self.clock:
                text += (
                    f"; recording started {stamp:%Y-%m-%d %H:%M:%S} UTC (clock column "
                    f"'{self.clock}'), times counted from the first sample"
                )
            else:
                text += (
                    f", a clock time: recording started {stamp:%Y-%m-%d %H:%M:%S} UTC, "
                    "times counted from the first sample"
                )
        return text


def to_seconds(raw: np.ndarray, unit: str = "", source: str = "") -> TimeBase:
    """Convert a time column to seconds, deciding its unit from the values when none is known.

    Parameters
    ----------
    raw : numpy.ndarray
        The values as read (NaN for blank cells).
    unit : str
        The known unit (a key of :data:`~balancer_id.read.header.TIME_UNITS`), or ``""``.
    source : str
        Where ``unit`` came from (see :class:`TimeBase`).

    Returns
    -------
    TimeBase
        Seconds, unit, its source and the clock time of the first sample.
    """
    finite = raw[np.isfinite(raw)]
    if not unit:
        top = float(np.max(np.abs(finite))) if finite.size else 0.0
        unit, source = next(((u, "values") for bound, u in _VALUE_UNITS if top > bound), ("s", ""))
        source = source or "default"
    unit = canonical(unit)
    scale = TIME_UNITS.get(unit, 1.0)
    if finite.size and EPOCH_MIN_S < float(np.min(finite)) * scale < EPOCH_MAX_S:
        first = float(finite[0])
        return TimeBase((raw - first) * scale, unit, source, started_at=first * scale)
    seconds = raw if scale == 1.0 else raw * scale
    return TimeBase(seconds, unit, source)


#: Wall-clock formats of a date-and-time column (SPARKvue writes the first).
WALL_CLOCK_FORMATS = (
    "%m/%d/%Y %I:%M:%S %p",
    "%m/%d/%Y %H:%M:%S",
    "%Y-%m-%d %H:%M:%S",
    "%Y-%m-%dT%H:%M:%S",
    "%d.%m.%Y %H:%M:%S",
)


def first_wall_clock(lines: list[str], delimiter: str, column: int) -> float | None:
    """The first date-and-time cell of a column, in seconds since 1970.

    A wall clock without a time zone (SPARKvue's ``01/13/2025 10:15:42 am``) is taken in
    this machine's time zone: good to order recordings, not to compare zones.

    Parameters
    ----------
    lines : list of str
        The first data lines of the file.
    delimiter : str
        The cell separator.
    column : int
        The column's index.

    Returns
    -------
    float or None
        The time, or None when no cell of the lines parses.
    """
    rows = (
        csv.reader(lines, delimiter=delimiter) if delimiter != " " else (ln.split() for ln in lines)
    )
    for row in rows:
        cell = row[column].strip() if column < len(row) else ""
        if not cell:
            continue
        for fmt in WALL_CLOCK_FORMATS:
            try:
                return datetime.strptime(cell, fmt).timestamp()  # %p ignores case
            except ValueError:
                continue
        return None
    return None
