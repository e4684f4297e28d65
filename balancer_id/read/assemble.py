"""Turn run plans and parsed columns into :class:`Recording` objects.

Each run keeps the rows where its time and its channels are present: padded blanks at
the end of a short run, derived channels blank in the first and last rows, and a
channel sampled at another rate under a shared time column all drop out this way,
without interpolation. When the force and the acceleration of one run are sampled at
clearly different rates (fewer than 75 % of the rows in common), the sparser channel
becomes a recording of its own, named ``"<run> (force)"`` or ``"<run> (acceleration)"``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from balancer_id.constants import FORCE_RANGE_N
from balancer_id.read.plan import RunPlan
from balancer_id.read.recording import Recording
from balancer_id.read.table import Table
from balancer_id.read.units import resolve_accel
from balancer_id.read.validate import check_time, count_saturated, find_gaps, sample_rate

#: Force and acceleration of one run share a time base when this share of rows is common.
COMMON_SHARE = 0.75


@dataclass
class _ChannelSet:
    name: str
    rows: np.ndarray  # boolean mask over the table's rows
    force: bool
    accel: bool


def build_recordings(
    path: Path,
    plans: list[RunPlan],
    table: Table,
    header: list[str],
    *,
    accel_unit: str,
    g: float,
) -> tuple[list[Recording], list[str]]:
    """Build the recordings of a log.

    Parameters
    ----------
    path : pathlib.Path
        The file (for error messages).
    plans : list of RunPlan
        The runs.
    table : Table
        The parsed columns.
    header : list of str
        The header cells (for error messages).
    accel_unit : str
        ``"auto"``, ``"m/s^2"`` or ``"g"``.
    g : float
        Gravity (m/s^2).

    Returns
    -------
    recordings : list of Recording
        In file order; runs without data are left out.
    warnings : list of str
        What the user should know.

    Raises
    ------
    LogReadError
        Time going backwards or repeating (from :func:`check_time`).
    """
    recordings: list[Recording] = []
    warnings: list[str] = []
    for col, (line, cell) in table.dropped.items():
        warnings.append(
            f"column '{header[col]}' ignored: non-numeric value {cell.strip()[:40]!r} "
            f"on line {line}"
        )
    for plan in plans:
        warnings.extend(f"{plan.name}: {note}" for note in plan.notes)
        time = table.columns[plan.time]
        if plan.time_scale != 1.0:
            time = time * plan.time_scale
        sets, notes = _channel_sets(plan, table, time)
        warnings.extend(f"{plan.name}: {note}" for note in notes)
        for chosen in sets:
            rec, rec_warnings = _build_one(
                path, plan, chosen, table, header, time, accel_unit=accel_unit, g=g
            )
            warnings.extend(rec_warnings)
            if rec is not None:
                recordings.append(rec)
    return recordings, warnings


def _channel_sets(
    plan: RunPlan, table: Table, time: np.ndarray
) -> tuple[list[_ChannelSet], list[str]]:
    notes: list[str] = []
    has_time = np.isfinite(time)
    masks: dict[str, np.ndarray] = {}
    if plan.force is not None:
        masks["force"] = np.isfinite(table.columns[plan.force])
    if plan.accel:
        ok = np.ones(table.n_rows, dtype=bool)
        for col in plan.accel:
            ok &= np.isfinite(table.columns[col])
        masks["acceleration"] = ok
    counts = {k: int(np.count_nonzero(m & has_time)) for k, m in masks.items()}
    for key in [k for k, n in counts.items() if n == 0]:
        notes.append(f"the {key} column is empty; ignored")
        del masks[key], counts[key]
    if masks:
        any_value = np.logical_or.reduce(list(masks.values()))
        no_time = int(np.count_nonzero(any_value & ~has_time))
        if no_time:
            notes.append(f"{no_time} row(s) with values but no time were skipped")
    if not masks:
        notes.append("no data; run skipped")
        return [], notes
    if len(masks) == 1:
        ((key, mask),) = masks.items()
        return [_ChannelSet(plan.name, mask & has_time, key == "force", key != "force")], notes
    both = masks["force"] & masks["acceleration"] & has_time
    common = int(np.count_nonzero(both))
    if common >= COMMON_SHARE * max(counts.values()):
        return [_ChannelSet(plan.name, both, True, True)], notes
    dense = max(counts, key=lambda k: counts[k])
    sparse = "force" if dense == "acceleration" else "acceleration"
    notes.append(
        f"force and acceleration are sampled at different rates; the {sparse} is returned as "
        f"its own run '{plan.name} ({sparse})'"
    )
    return [
        _ChannelSet(plan.name, masks[dense] & has_time, dense == "force", dense != "force"),
        _ChannelSet(
            f"{plan.name} ({sparse})",
            masks[sparse] & has_time,
            sparse == "force",
            sparse != "force",
        ),
    ], notes


def _build_one(
    path: Path,
    plan: RunPlan,
    chosen: _ChannelSet,
    table: Table,
    header: list[str],
    time_all: np.ndarray,
    *,
    accel_unit: str,
    g: float,
) -> tuple[Recording | None, list[str]]:
    warnings: list[str] = []
    idx = np.flatnonzero(chosen.rows)
    name = chosen.name
    if idx.size < 2:
        warnings.append(f"{name}: only {idx.size} sample(s); run skipped")
        return None, warnings
    time = time_all[idx]
    check_time(path, time, lambda i: table.line_of(idx[i]), header[plan.time])
    force = table.columns[plan.force][idx] if chosen.force and plan.force is not None else None
    accel = None
    includes_gravity = True
    if chosen.accel and plan.accel:
        raw = np.column_stack([table.columns[c][idx] for c in plan.accel])
        accel, includes_gravity, note = resolve_accel(
            raw,
            header_unit=plan.accel_unit,
            includes_gravity=plan.includes_gravity,
            accel_unit=accel_unit,
            g=g,
        )
        if note:
            warnings.append(f"{name}: {note}")
    extra = {
        label: table.columns[col][idx] for label, col in plan.extra.items() if col in table.columns
    }
    gaps = find_gaps(time)
    if gaps:
        longest = max(gap.t_after - gap.t_before for gap in gaps)
        warnings.append(
            f"{name}: {len(gaps)} gap(s) in the time column, {sum(gp.n_missing for gp in gaps)} "
            f"sample(s) missing, longest {longest:.3g} s (kept as gaps, not interpolated)"
        )
    saturated = count_saturated(force, accel, g)
    if "force" in saturated:
        warnings.append(
            f"{name}: {saturated['force']} force sample(s) at the sensor limit "
            f"(±{FORCE_RANGE_N:g} N)"
        )
    if "accel" in saturated:
        warnings.append(
            f"{name}: {saturated['accel']} acceleration sample(s) at the sensor limit (±16 g)"
        )
    rec = Recording(
        name=name,
        time=time,
        force=force,
        accel=accel,
        accel_includes_gravity=includes_gravity,
        accel_axes=plan.accel_axes if accel is not None else ("x", "y", "z"),
        sample_rate_hz=sample_rate(time),
        gaps=gaps,
        saturated=saturated,
        extra=extra,
    )
    return rec, warnings
