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
from balancer_id.read.inference import Inference

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
    if len(words) == 1 and words[0].lower() in ("millis", "micros", "nanos", "msec"):
        return canonical(words[0]), "name"  # Arduino's millis()
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
    stated : str
        The unit the header or name stated when the spacing overruled it (``"s"``).
    spacing : float
        The median step between samples as read (in ``unit``).
    """

    seconds: np.ndarray
    unit: str
    source: str
    started_at: float | None = None
    clock: str = ""
    stated: str = ""
    spacing: float = float("nan")

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
            "spacing": f"from its spacing: whole numbers {self.spacing:.4g} apart",
        }[self.source]
        text = f"time column '{column}' read in {self.unit} ({where})"
        if self.stated:
            text += (
                f"; the header says {self.stated}, but {self.spacing:.4g} s apart would be "
                f"{1.0 / self.spacing:.3g} Hz, no force or acceleration log's rate"
            )
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
    stated = ""
    if source in ("header", "name", "default") and unit == "s":
        by_spacing = unit_from_spacing(finite)
        if by_spacing is not None:
            stated = "s" if source != "default" else ""
            unit, source = by_spacing, "spacing"
    scale = TIME_UNITS.get(unit, 1.0)
    if finite.size and EPOCH_MIN_S < float(np.min(finite)) * scale < EPOCH_MAX_S:
        first = float(finite[0])
        return TimeBase(
            (raw - first) * scale,
            unit,
            source,
            started_at=first * scale,
            stated=stated,
            spacing=_spacing(finite),
        )
    seconds = raw if scale == 1.0 else raw * scale
    return TimeBase(seconds, unit, source, stated=stated, spacing=_spacing(finite))


#: A log's rate lies in this range (Hz); the spacing of a time in s beyond it is checked.
RATE_RANGE_HZ = (1.0, 100_000.0)


def _spacing(finite: np.ndarray) -> float:
    """The median step between successive finite times (NaN with fewer than 2)."""
    if finite.size < 2:
        return float("nan")
    steps = np.diff(finite[:200_000])
    steps = steps[steps > 0]
    return float(np.median(steps)) if steps.size else float("nan")


def unit_from_spacing(finite: np.ndarray) -> str | None:
    """The unit of a time read as seconds whose spacing says it is not in seconds.

    Whole numbers spaced more than a second apart (below 1 Hz in s: no force or
    acceleration log) are a counter in ms, µs or ns: the unit that brings the rate
    nearest 100 Hz within 1 Hz-100 kHz is taken.

    Parameters
    ----------
    finite : numpy.ndarray
        The time column's finite values as read.

    Returns
    -------
    str or None
        ``"ms"``, ``"us"`` or ``"ns"``; None when seconds fit (or nothing fits better).
    """
    step = _spacing(finite)
    if not np.isfinite(step) or step <= 1.0:
        return None
    head = finite[:10_000]
    if not np.all(head == np.round(head)):
        return None
    if EPOCH_MIN_S < float(np.min(finite)) < EPOCH_MAX_S:  # a clock in whole seconds
        return None
    low, high = RATE_RANGE_HZ
    options = [
        (abs(np.log10(1.0 / (step * scale)) - 2.0), u)
        for u, scale in (("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9))
        if low <= 1.0 / (step * scale) <= high
    ]
    return min(options)[1] if options else None


def time_inference(base: TimeBase, column: str, run: str) -> Inference:
    """The ``time unit`` inference of a run: the unit, what it rests on, how to override.

    Parameters
    ----------
    base : TimeBase
        The converted time column.
    column : str
        Its name as written.
    run : str
        The run.

    Returns
    -------
    Inference
        E.g. ``time unit: ms (whole numbers 5 apart: 0.2 Hz in s, 200 Hz in ms; ...)``.
    """
    where = {
        "map": "given in the column map",
        "layout": "the export's layout states it",
        "header": "the header states it",
        "name": "the column's name states it",
        "values": "the size of its values (a clock time)",
        "default": "no unit stated",
        "spacing": "from its spacing",
    }[base.source]
    step = base.spacing
    evidence = where
    if np.isfinite(step) and step > 0:
        rate = 1.0 / (step * TIME_UNITS.get(base.unit, 1.0))
        evidence += f"; samples {step:.4g} apart: {rate:.4g} Hz"
        if base.source == "spacing":
            evidence += f" in {base.unit}, {1.0 / step:.3g} Hz in s"
            if base.stated:
                evidence += f"; the header says {base.stated}, which its spacing contradicts"
    if base.started_at is not None:
        evidence += "; a clock time, counted from the first sample"
    low, high = RATE_RANGE_HZ
    rate_ok = (
        np.isfinite(step)
        and step > 0
        and low <= 1.0 / (step * TIME_UNITS.get(base.unit, 1.0)) <= high
    )
    weak = base.source == "default" and not rate_ok
    override = "" if base.source == "map" else f"--columns time={column}:<s|ms|us|ns>,..."
    return Inference("time unit", base.unit, evidence, override, weak=weak, run=run)


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
