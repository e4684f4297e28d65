"""Refusals that name the true cause: a missing header, values at no physical scale.

A file whose first line holds numbers has lost its header (:func:`refuse_headerless`);
a force or acceleration column whose values lie beyond any sensor's range is not blank
but scaled (a spreadsheet's re-export, raw counts): :func:`refuse_no_scale` says how far.
"""

from __future__ import annotations

import math
import re

import numpy as np

from balancer_id.errors import LogReadError
from balancer_id.read.plan import RunPlan
from balancer_id.read.sniff import Sniffed
from balancer_id.read.table import Table
from balancer_id.read.units import raw_scale_error, rest_of

_NUMBER = re.compile(r"^[+-]?(?:\d+[.,]?\d*|[.,]\d+)(?:[eE][+-]?\d+)?$")
#: A signal column with more than this share of its values beyond its bound is refused.
BEYOND_SHARE = 0.5


def refuse_headerless(sniffed: Sniffed) -> None:
    """Refuse a file whose first line is data: its header is missing.

    Parameters
    ----------
    sniffed : Sniffed
        The sniffed file.

    Raises
    ------
    LogReadError
        When every cell of the first line is a number.
    """
    cells = [c.strip().strip('"') for c in sniffed.header]
    if len(cells) < 2 or not all(_NUMBER.match(c) for c in cells if c) or not any(cells):
        return
    shown = ", ".join(repr(c) for c in cells[:4]) + (", ..." if len(cells) > 4 else "")
    raise LogReadError(
        sniffed.path,
        f"the header line is missing: the first line holds only numbers ({shown}), "
        "not the names of the columns",
        line=sniffed.header_line,
        hint="add the export's header line back (e.g. time,force,ax,ay,az) as the first "
        "line, then read it again (with --columns naming those columns if needed)",
    )


def _mostly_beyond(table: Table, col: int) -> np.ndarray | None:
    """The column as read when most of its values lay beyond its bound, else None."""
    raw = table.beyond.get(col)
    if raw is None:
        return None
    finite = np.isfinite(raw)
    beyond = finite & ~np.isfinite(table.columns[col])
    if np.count_nonzero(beyond) <= BEYOND_SHARE * max(1, int(np.count_nonzero(finite))):
        return None
    return raw


def refuse_no_scale(sniffed: Sniffed, plans: list[RunPlan], table: Table) -> None:
    """Refuse a force or acceleration whose values are at no physical scale.

    Parameters
    ----------
    sniffed : Sniffed
        The sniffed file (path and header names).
    plans : list of RunPlan
        The runs.
    table : Table
        The parsed columns (values beyond their bound already NaN, kept in ``beyond``).

    Raises
    ------
    LogReadError
        Most of a force or acceleration column lies beyond any sensor's range: says how
        large the values are and the scale that reads them.
    """
    for plan in plans:
        if plan.accel and any(_mostly_beyond(table, c) is not None for c in plan.accel):
            block = np.column_stack([table.beyond.get(c, table.columns[c]) for c in plan.accel])
            level = rest_of(block[np.all(np.isfinite(block), axis=1)]).level
            exc = raw_scale_error(level)
            raise LogReadError(
                sniffed.path,
                f"{plan.name}: {exc.message}",
                column=sniffed.header[plan.accel[0]],
                hint=exc.hint,
            )
        if plan.force is not None:
            raw = _mostly_beyond(table, plan.force)
            if raw is not None:
                size = float(np.median(np.abs(raw[np.isfinite(raw)])))
                k = max(1, math.ceil(math.log10(size / 1e3)))
                raise LogReadError(
                    sniffed.path,
                    f"{plan.name}: the force values sit around {size:.3g}, beyond any force "
                    "sensor's range: values at no physical scale (scaled by a spreadsheet's "
                    "re-export, or raw counts)",
                    column=sniffed.header[plan.force],
                    hint="export the values again unscaled, or give the scale in the column "
                    f"map: --columns force=NAME:1e-{k}N for values {10**k:g} times too large, "
                    "or a load cell's calibration, N per count plus offset "
                    "(force=NAME:3.15e-6N+0.30)",
                )
