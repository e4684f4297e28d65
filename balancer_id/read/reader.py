"""``read_log``: one call that detects the layout of a log and reads it."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import LogReadError
from balancer_id.notes import Note, as_note, texts
from balancer_id.read.assemble import build_recordings
from balancer_id.read.evidence import columns_inference, layout_inference
from balancer_id.read.generic import (
    guess_plan,
    no_columns_error,
    plan_from_map,
    scale_stated_force_units,
)
from balancer_id.read.header import Column, classify_header
from balancer_id.read.layouts import detect_layout
from balancer_id.read.orientation import orientations, turned_note_text
from balancer_id.read.plan import RunPlan
from balancer_id.read.recording import Log
from balancer_id.read.scale import refuse_headerless, refuse_no_scale
from balancer_id.read.sniff import Sniffed, sniff
from balancer_id.read.table import Table, read_table
from balancer_id.read.timebase import first_wall_clock
from balancer_id.read.units import check_accel_unit

#: Largest plausible time value before conversion: a Unix time in ns (19 digits) fits.
TIME_BOUND = 1e19
#: Note codes kept in ``Log.notes`` only, not in the warnings text (they are no warning:
#: every generic CSV read without a column map has its columns guessed).
NOTES_ONLY = frozenset({"read.column_guess"})
#: Largest plausible force (N) or acceleration (m/s^2 or g) of any sensor.
SIGNAL_BOUND = 1e6


def _rows_with_a_value(table: Table) -> int:
    """Rows of the table with a number in at least one of its columns."""
    if not table.columns:
        return 0
    filled = np.zeros(table.n_rows, dtype=bool)
    for values in table.columns.values():
        filled |= np.isfinite(values)
    return int(np.count_nonzero(filled))


#: Fewer data rows than this hold no run (no rate, no rest, no step).
MIN_ROWS_OF_A_RUN = 3


def read_log(
    path: str | os.PathLike[str],
    *,
    columns: dict[str, str] | None = None,
    accel_unit: str = "auto",
    max_bytes: int | None = None,
    g: float = G_DEFAULT,
) -> Log:
    """Read a PASCO Capstone, PASCO SPARKvue, phyphox or generic CSV log.

    The layout, delimiter (``,``, ``;``, tab), decimal mark, BOM and line endings are
    detected from the file. Each run becomes one :class:`Recording` on its own time base;
    dropped samples are reported as gaps and never interpolated. Only regular files are
    read, streamed within ``max_bytes``; a cut last line is dropped and values that are
    infinite or beyond any sensor's range (force, acceleration beyond 1e6; time beyond
    1e19) are treated as missing samples, each with a warning.

    Parameters
    ----------
    path : str or path-like
        The CSV file.
    columns : dict, optional
        Column map for a generic CSV: ``{"time": ..., "force": ..., "ax": ..., "ay": ...,
        "az": ...}`` (or ``"a"`` for one vertical acceleration column); names match the
        header case-insensitively. Given, it overrides the layout detection.
    accel_unit : {"auto", "m/s^2", "g"}
        Unit of the acceleration values. ``"auto"`` uses the header's unit and, for an
        acceleration that includes gravity, converts values whose resting magnitude is
        ~1 (g) instead of ~9.8 (m/s^2), with a warning.
    max_bytes : int, optional
        Refuse larger files (default: a quarter of the available memory, at most 2 GiB).
    g : float
        Gravity (m/s^2) used to convert accelerations given in g.

    Returns
    -------
    Log
        Format, recordings and warnings.

    Raises
    ------
    LogReadError
        The file cannot be read or is not valid; the message names the file, the line or
        column, and what to do.
    UsageError
        ``accel_unit`` or ``columns`` do not make sense.
    """
    accel_unit = check_accel_unit(accel_unit)
    sniffed = sniff(path, max_bytes)
    refuse_headerless(sniffed)
    header = classify_header(sniffed.header)
    fmt, plans = _plan(sniffed.path, header, columns)
    fmt = _refined(fmt, plans, header, sniffed, columns)
    inferences = [layout_inference(fmt, header, columns)]
    inferences += [columns_inference(plan, header, fmt, columns) for plan in plans]
    scaled = scale_stated_force_units(plans, header)
    inferences += scaled
    _wall_clocks(sniffed, header, plans)
    wanted = sorted({c for plan in plans for c in plan.columns})
    optional = {c for plan in plans for c in plan.extra.values()}
    limits = _bounds(plans)
    clocks = {c for plan in plans for c in (plan.time, plan.force_time) if c is not None}
    table = read_table(sniffed, wanted, optional, limits, clocks)
    refuse_no_scale(sniffed, plans, table)
    with np.errstate(over="ignore", invalid="ignore"):  # absurd values must not warn
        recordings, warnings = build_recordings(
            sniffed.path,
            plans,
            table,
            sniffed.header,
            accel_unit=accel_unit,
            g=g,
            inferences=inferences,
        )
    if not recordings:
        raise _no_rows_error(sniffed, plans, table)
    found = [Note("read.other", text, subject=str(sniffed.path)) for text in sniffed.notes]
    found += [as_note(w, "read.other") for w in warnings]
    found += _turned_notes(recordings, g)
    found += [
        Note("read.force_unit", f"{s.run}: force read in {s.decision} ({s.evidence})",
             subject=s.run, severity="info")
        for s in scaled
    ]  # fmt: skip
    return Log(
        path=sniffed.path,
        format=fmt,
        recordings=recordings,
        warnings=texts(n for n in found if n.code not in NOTES_ONLY),
        notes=found,
        inferences=inferences,
    )


def _refined(
    fmt: str, plans: list[RunPlan], header: list[Any], sniffed: Sniffed, columns: Any
) -> str:
    """The layout, phyphox's told apart from a generic CSV by its numbers and names."""
    if (
        fmt == "phyphox"
        and any(p.force is not None for p in plans)
        and not _phyphox_numbers(sniffed)
    ):  # phyphox records no force sensor, and writes its numbers as 1.005775000E-2
        return "generic"
    if fmt == "generic" and not columns and _phyphox_like(header, sniffed):
        return "phyphox"  # another phyphox experiment (Elevator: 'Acceleration (m/s²)')
    return fmt


def _turned_notes(recordings: list[Any], g: float) -> list[Note]:
    """A note for each run whose sensor turned during it (issue 19.3)."""
    found = []
    for rec in recordings:
        parts = orientations(rec, g)
        if len(parts) > 1:
            found.append(Note("read.turned_sensor", turned_note_text(rec, parts), rec.name))
    return found


def _bounds(plans: list[RunPlan]) -> dict[int, float]:
    """The largest magnitude each time and signal column may hold (beyond: not a number)."""
    limits: dict[int, float] = {}
    for plan in plans:
        for col in (plan.time, plan.force_time, plan.clock):
            if col is not None:
                limits[col] = TIME_BOUND
        for col in (plan.force, *plan.accel):
            if col is not None:  # the bound holds after the column map's scale
                factor, offset = plan.scales.get(col, (1.0, 0.0))
                limits[col] = (SIGNAL_BOUND + abs(offset)) / max(abs(factor), 1e-300)
    return limits


def _no_rows_error(sniffed: Sniffed, plans: list[RunPlan], table: Table) -> LogReadError:
    """Why no run could be built: too few rows, or none with the measurements."""
    n_filled = _rows_with_a_value(table)
    if 0 < n_filled < MIN_ROWS_OF_A_RUN:
        return LogReadError(
            sniffed.path,
            f"only {n_filled} data row(s): a log needs at least {MIN_ROWS_OF_A_RUN} "
            "samples of a run",
            line=sniffed.header_line + 1,
            hint="record longer, or check that the export includes every sample",
        )
    return LogReadError(
        sniffed.path,
        "no usable data rows: " + _blank_cause(plans, table, sniffed.header),
        line=sniffed.header_line + 1,
        hint="check that the export includes the measurements",
    )


_PHYPHOX_NUMBER = re.compile(rb"-?\d[.,]\d{9}E[-+]?\d+")


def _phyphox_numbers(sniffed: Sniffed) -> bool:
    """True when the first data line's numbers are written as phyphox writes them."""
    end = sniffed.data.find(b"\n", sniffed.data_start)
    line = sniffed.data[sniffed.data_start : end if end >= 0 else None]
    return _PHYPHOX_NUMBER.search(line) is not None


def _blank_cause(plans: list[RunPlan], table: Table, header: list[str]) -> str:
    """Why no run has a row: the columns are blank, or their filled rows never meet."""
    for plan in plans:
        signals = [c for c in (plan.force, *plan.accel[:1]) if c is not None]
        time = np.isfinite(table.columns[plan.time])
        for col in signals:
            values = np.isfinite(table.columns[col])
            if time.any() and values.any() and not (time & values).any():
                return (
                    f"'{header[plan.time]}' ({int(time.sum())} values) and "
                    f"'{header[col]}' ({int(values.sum())} values) are never filled on the "
                    "same row: channels on clocks of their own"
                )
    return "every run's time, force and acceleration cells are blank"


def _phyphox_like(header: list[Column], sniffed: Sniffed) -> bool:
    """A header phyphox writes (time first, no runs, no force) over phyphox's numbers."""
    return (
        bool(header)
        and header[0].kind == "time"
        and not any(c.run for c in header)
        and not any(c.kind == "force" for c in header)
        and _phyphox_numbers(sniffed)
    )


def _wall_clocks(sniffed: Sniffed, header: list[Column], plans: list[RunPlan]) -> None:
    """Set each plan's start from its run's date-and-time column (SPARKvue), if any."""
    clocks = {c.run: c.index for c in header if c.kind == "datetime"}
    if not clocks:
        return
    end = sniffed.data.find(b"\n", sniffed.data_start)
    for _ in range(20):  # a run's first date is on one of the first lines
        nxt = sniffed.data.find(b"\n", end + 1)
        end = len(sniffed.data) if nxt < 0 else nxt
    lines = sniffed.data[sniffed.data_start : end].decode("utf-8", "replace").splitlines()
    for plan in plans:
        run = next((r for r in clocks if r and plan.name.startswith(r)), None)
        column = clocks.get(run if run is not None else "")
        if column is not None:
            plan.clock_start = first_wall_clock(lines, sniffed.delimiter, column)


def _plan(
    path: Path, header: list[Column], columns: dict[str, str] | None
) -> tuple[str, list[RunPlan]]:
    """Choose the layout and plan its runs."""
    if columns:
        return "generic", plan_from_map(path, header, columns)
    fmt, plans = detect_layout(path, header)
    if not plans:
        plans = guess_plan(header)
        if fmt != "generic" and plans:
            fmt = "generic"
    if plans:
        return fmt, plans
    has_time = any(c.kind == "time" for c in header)
    has_signal = any(c.kind in ("force", "accel") for c in header)
    if has_time:
        missing = "no force or acceleration column"
    elif has_signal:
        missing = "no time column"
    else:
        missing = "no time, force or acceleration column"
    raise no_columns_error(path, header, missing)
