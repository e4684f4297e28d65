"""Turn run plans and parsed columns into :class:`Recording` objects.

Each run keeps the rows where its time and its channels are present: padded blanks at
the end of a short run and derived channels blank in the first and last rows drop out
this way, without interpolation. When the force and the acceleration of one run are
sampled at clearly different rates (fewer than 75 % of the rows in common under one
time column, or each under a time column of its own), the run is one recording on the
acceleration's sample times: the acceleration (the output) is never interpolated, the
force (the input) is brought onto its times by :func:`~balancer_id.read.resample.onto_times`
(averaged over each acceleration period when faster, interpolated when slower), and a
warning says so.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from balancer_id.constants import FORCE_RANGE_N
from balancer_id.errors import LogReadError
from balancer_id.notes import Note
from balancer_id.read.header import TIME_UNITS
from balancer_id.read.inference import Inference
from balancer_id.read.plan import RunPlan
from balancer_id.read.recording import Recording
from balancer_id.read.resample import onto_times
from balancer_id.read.table import Table
from balancer_id.read.timebase import TimeBase, time_inference, to_seconds
from balancer_id.read.units import UnitMismatch, resolve_accel
from balancer_id.read.validate import (
    check_time,
    count_saturated,
    find_gaps,
    pinned_extremes,
    repeat_factor,
    sample_rate,
)

#: Force and acceleration of one run share a time base when this share of rows is common.
COMMON_SHARE = 0.75
#: An accelerometer sampled outside this range (Hz) is warned: a time unit misread.
RATE_MIN_HZ, RATE_MAX_HZ = 1.0, 100_000.0
#: A stretch of a restarting clock has at least this many samples.
MIN_BLOCK = 10


@dataclass
class _ChannelSet:
    name: str
    rows: np.ndarray  # boolean mask over the table's rows
    force: bool
    accel: bool
    force_rows: np.ndarray | None = None  # force samples on their own rows/time: resample


def build_recordings(
    path: Path,
    plans: list[RunPlan],
    table: Table,
    header: list[str],
    *,
    accel_unit: str,
    g: float,
    inferences: list[Inference] | None = None,
) -> tuple[list[Recording], list[str | Note]]:
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
    inferences : list of Inference, optional
        Filled with each run's decisions (time unit, acceleration unit, gravity) and
        their evidence.

    Returns
    -------
    recordings : list of Recording
        In file order; runs without data are left out.
    warnings : list of str
        What the user should know.

    Raises
    ------
    LogReadError
        Time going backwards or repeating (from :func:`check_time`), or a resting
        acceleration that contradicts the unit the user forced or ``g``.
    """
    recordings: list[Recording] = []
    warnings: list[str | Note] = []
    said_list: list[Inference] = inferences if inferences is not None else []
    stated: set[str] = set()
    warnings.extend(table.notes)
    for col, (line, cell) in table.dropped.items():
        warnings.append(
            f"column '{header[col]}' ignored: non-numeric value {cell.strip()[:40]!r} "
            f"on line {line}"
        )
    for plan in plans:
        warnings.extend(f"{plan.name}: {note}" for note in plan.notes)
        if plan.guessed:
            warnings.append(_guess_note(plan, header))
        for col, (factor, offset) in plan.scales.items():  # the column map's scales
            table.columns[col] = table.columns[col] * factor + offset
        base = _time_base(plan, table, header)
        time = base.seconds
        said = base.note(header[plan.time])
        if said and said not in stated:
            stated.add(said)
            subject = header[plan.time]
            warnings.append(Note("read.time_unit", said, subject=subject, severity="info"))
        said_list.append(time_inference(base, header[plan.time], plan.name))
        force_time = time
        if plan.force_time is not None:
            force_time = table.columns[plan.force_time] * plan.force_time_scale
            if base.started_at is not None:
                force_time = force_time - base.started_at
        _refuse_untimed(path, plan, table, header, time, force_time)
        sets, notes = _channel_sets(plan, table, time, force_time)
        warnings.extend(f"{plan.name}: {note}" for note in notes)
        sets, restarts = _split_restarts(sets, time, table, plan.name)
        warnings.extend(restarts)
        for chosen in sets:
            force_only = chosen.force and not chosen.accel and plan.force_time is not None
            rec, rec_warnings = _build_one(
                path,
                plan,
                chosen,
                table,
                header,
                force_time if force_only else time,
                accel_unit=accel_unit,
                g=g,
                force_time=force_time,
                time_unit=base.unit,
                inferences=said_list,
            )
            warnings.extend(rec_warnings)
            if rec is not None:
                recordings.append(_started(rec, base, plan))
    return recordings, warnings


def _time_base(plan: RunPlan, table: Table, header: list[str]) -> TimeBase:
    """The run's time in seconds; with a clock column beside a relative time, its start."""
    base = to_seconds(table.columns[plan.time], plan.time_unit, plan.time_unit_from)
    if plan.clock is not None and base.started_at is None:
        clock = to_seconds(table.columns[plan.clock])
        rows = np.isfinite(table.columns[plan.clock]) & np.isfinite(base.seconds)
        if clock.started_at is not None and rows.any():
            first = int(np.argmax(rows))
            base = TimeBase(
                base.seconds - base.seconds[first],
                base.unit,
                base.source,
                clock.started_at + float(clock.seconds[first]),
                clock=header[plan.clock],
                stated=base.stated,
                spacing=base.spacing,
            )
    return base


def _started(rec: Recording, base: TimeBase, plan: RunPlan) -> Recording:
    """The recording's start (a clock time counted from its first sample, or the plan's)."""
    rec.started_at = base.started_at if base.started_at is not None else plan.clock_start
    if base.started_at is not None and rec.n_samples:
        rec.started_at = base.started_at + float(rec.time[0])
        rec.time = rec.time - rec.time[0]
    return rec


def _guess_note(plan: RunPlan, header: list[str]) -> Note:
    """The ``read.column_guess`` note naming the columns guessed from their names."""
    roles = [f"time={header[plan.time]}"]
    if plan.force is not None:
        roles.append(f"force={header[plan.force]}")
    names = ["a"] if len(plan.accel) == 1 else [f"a{axis}" for axis in plan.accel_axes]
    roles += [f"{r}={header[c]}" for r, c in zip(names, plan.accel, strict=True)]
    return Note(
        "read.column_guess",
        f"columns guessed from their names: {','.join(roles)} (pass --columns to choose others)",
        subject=plan.name,
        severity="info",
    )


def _split_restarts(
    sets: list[_ChannelSet], time: np.ndarray, table: Table, name: str
) -> tuple[list[_ChannelSet], list[Note]]:
    """Make each stretch of a clock that restarts (falls back to its start) a run of its own.

    A fall of the time, after at least :data:`MIN_BLOCK` samples, to within two median
    steps of the stretch's first time and by more than half the stretch's span is a
    restart (a test rig's per-block clock); any other fall stays an error of
    :func:`~balancer_id.read.validate.check_time`.
    """
    out: list[_ChannelSet] = []
    notes: list[Note] = []
    for chosen in sets:
        idx = np.flatnonzero(chosen.rows)
        if idx.size < 3 or chosen.force_rows is not None:
            out.append(chosen)
            continue
        t = time[idx]
        dt = np.diff(t)
        falls = np.flatnonzero(dt < 0)
        if falls.size == 0:
            out.append(chosen)
            continue
        step = float(np.median(np.abs(dt[dt != 0]))) if np.any(dt != 0) else 0.0
        starts = [0]
        for i in falls.tolist():
            first = float(t[starts[-1]])
            long_block = i + 1 - starts[-1] >= MIN_BLOCK
            if (
                not long_block
                or t[i + 1] > first + 2 * step
                or t[i] - t[i + 1] < 0.5 * (t[i] - first)
            ):
                break  # not a restart: check_time names the line
            starts.append(i + 1)
        else:
            bounds = [*starts, idx.size]
            for k, (a, b) in enumerate(itertools.pairwise(bounds), start=1):
                rows = np.zeros_like(chosen.rows)
                rows[idx[a:b]] = True
                part = f"Run {k}" if name == "Run 1" else f"{name} ({k})"
                out.append(_ChannelSet(part, rows, chosen.force, chosen.accel))
            lines = ", ".join(str(table.line_of(idx[i])) for i in starts[1:4])
            more = ", ..." if len(starts) > 4 else ""
            notes.append(
                Note(
                    "read.clock_restart",
                    f"{name}: the time restarts {len(starts) - 1} time(s) (lines {lines}{more}); "
                    f"each stretch is a run of its own ({len(starts)} runs)",
                    subject=name,
                )
            )
            continue
        out.append(chosen)
    return out, notes


#: A channel with more than this share of its values without a time is on another clock.
UNTIMED_SHARE = 0.5


def _refuse_untimed(
    path: Path,
    plan: RunPlan,
    table: Table,
    header: list[str],
    time: np.ndarray,
    force_time: np.ndarray,
) -> None:
    """Refuse a channel most of whose values have no time: it runs on another clock.

    Cutting the run to the rows with a time (a photogate's event rows) would drop most
    of the channel's samples and report the events' spacing as its rate.
    """
    channels = [(plan.force, force_time)] if plan.force is not None else []
    channels += [(c, time) for c in plan.accel[:1]]
    for col, clock in channels:
        values = np.isfinite(table.columns[col])
        n = int(np.count_nonzero(values))
        timed = int(np.count_nonzero(values & np.isfinite(clock)))
        if n >= MIN_BLOCK and n - timed > UNTIMED_SHARE * n:
            column = header[
                plan.force_time if col == plan.force and plan.force_time is not None else plan.time
            ]
            raise LogReadError(
                path,
                f"{plan.name}: '{header[col]}' has {n} values but only {timed} of them a time "
                f"in '{column}': the channels run on clocks of their own (event-timed rows "
                "beside sampled ones?); cutting the run to the timed rows would drop "
                f"{100 * (n - timed) / n:.0f} % of the samples",
                column=header[col],
                hint="export each sensor with its own time column, or give the channel's own "
                "time with --columns time=...",
            )


def _channel_sets(
    plan: RunPlan, table: Table, time: np.ndarray, force_time: np.ndarray
) -> tuple[list[_ChannelSet], list[str]]:
    notes: list[str] = []
    has_time = np.isfinite(time)
    masks: dict[str, np.ndarray] = {}
    timed: dict[str, np.ndarray] = {}
    if plan.force is not None:
        masks["force"] = np.isfinite(table.columns[plan.force])
        timed["force"] = masks["force"] & np.isfinite(force_time)
    if plan.accel:
        ok = np.ones(table.n_rows, dtype=bool)
        for col in plan.accel:
            ok &= np.isfinite(table.columns[col])
        masks["acceleration"] = ok
        timed["acceleration"] = ok & has_time
    counts = {k: int(np.count_nonzero(m)) for k, m in timed.items()}
    for key in [k for k, n in counts.items() if n == 0]:
        untimed = int(np.count_nonzero(masks[key]))
        if untimed:
            notes.append(
                f"the {key} column has {untimed} value(s) but none on a row with a time "
                "(a clock of its own?); ignored"
            )
        else:
            notes.append(f"the {key} column is empty; ignored")
        del masks[key], counts[key], timed[key]
    if masks:
        no_time = sum(int(np.count_nonzero(masks[k] & ~timed[k])) for k in masks)
        if no_time:
            notes.append(f"{no_time} value(s) without a time were skipped")
    if not masks:
        notes.append("no data; run skipped")
        return [], notes
    if len(masks) == 1:
        ((key, mask),) = timed.items()
        return [_ChannelSet(plan.name, mask, key == "force", key != "force")], notes
    if plan.force_time is None:
        both = timed["force"] & timed["acceleration"]
        if np.count_nonzero(both) >= COMMON_SHARE * max(counts.values()):
            return [_ChannelSet(plan.name, both, True, True)], notes
    return [_ChannelSet(plan.name, timed["acceleration"], True, True, timed["force"])], notes


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
    force_time: np.ndarray,
    time_unit: str = "s",
    inferences: list[Inference] | None = None,
) -> tuple[Recording | None, list[str | Note]]:
    warnings: list[str | Note] = []
    count = int(np.count_nonzero(chosen.rows))
    name = chosen.name
    if count < 2:
        warnings.append(f"{name}: only {count} sample(s); run skipped")
        return None, warnings
    # every row: views of the parsed columns, not copies (big files)
    full = count == table.n_rows and chosen.force_rows is None
    idx = np.arange(0) if full else np.flatnonzero(chosen.rows)
    rows: np.ndarray | slice = slice(None) if full else idx
    time = time_all[rows]
    check_time(path, time, lambda i: table.line_of(i if full else idx[i]), header[plan.time])
    force = table.columns[plan.force][rows] if chosen.force and plan.force is not None else None
    if chosen.force_rows is not None and plan.force is not None:
        force, rows, note = _force_onto_accel(
            path, plan, table.columns[plan.force], chosen.force_rows, idx, table, header,
            force_time, time_all,
        )
        warnings.append(f"{name}: {note}")
        if rows.size < 2:
            warnings.append(f"{name}: only {rows.size} sample(s) with force; run skipped")
            return None, warnings
        time = time_all[rows]
    accel, includes_gravity = None, True
    if chosen.accel and plan.accel:
        accel, includes_gravity = _resolved_accel(
            path, plan, table, header, rows, name, accel_unit=accel_unit, g=g,
            inferences=inferences, warnings=warnings,
        )
    extra = {
        label: table.columns[col][rows] for label, col in plan.extra.items() if col in table.columns
    }
    gaps = find_gaps(time)
    warnings += _gap_notes(name, time, gaps)
    rate = sample_rate(time)
    if accel is not None and not RATE_MIN_HZ <= rate <= RATE_MAX_HZ:
        warnings.append(_rate_note(name, rate, header[plan.time], time_unit))
    saturated = _limit_notes(name, force, accel, g, plan, warnings)
    warnings += _repeat_notes(name, accel, force, time, rate)
    rec = Recording(
        name=name,
        time=time,
        force=force,
        accel=accel,
        accel_includes_gravity=includes_gravity,
        accel_axes=plan.accel_axes if accel is not None else ("x", "y", "z"),
        sample_rate_hz=rate,
        gaps=gaps,
        saturated=saturated,
        extra=extra,
    )
    return rec, warnings


def _resolved_accel(
    path: Path,
    plan: RunPlan,
    table: Table,
    header: list[str],
    rows: np.ndarray | slice,
    name: str,
    *,
    accel_unit: str,
    g: float,
    inferences: list[Inference] | None,
    warnings: list[str | Note],
) -> tuple[np.ndarray, bool]:
    """The run's acceleration in m/s^2 and whether it holds gravity (its notes added to
    ``warnings``, its decisions to ``inferences``)."""
    raw = np.column_stack([table.columns[c][rows] for c in plan.accel])
    try:
        accel, includes_gravity, said, decided = resolve_accel(
            raw,
            header_unit=plan.accel_unit,
            includes_gravity=plan.includes_gravity,
            accel_unit=plan.accel_unit if plan.accel_unit_given else accel_unit,
            g=g,
            gravity_given=plan.gravity_given,
        )
        if inferences is not None:
            inferences.extend(replace(d, run=name) for d in decided)
    except UnitMismatch as exc:
        hint = exc.hint
        if exc.spec:
            hint = "give the scale in the column map: --columns " + _counts_map(
                plan, header, exc.spec, exc.counts_per_g is not None
            )
        raise LogReadError(
            path, f"{name}: {exc.message}", column=header[plan.accel[0]], hint=hint
        ) from None
    if isinstance(said, Note):
        warnings.append(Note(said.code, f"{name}: {said.text}", subject=name))
    elif said:
        warnings.append(f"{name}: {said}")
    return accel, includes_gravity


def _gap_notes(name: str, time: np.ndarray, gaps: list[Any]) -> list[str | Note]:
    """What the gaps of the time column say: dropped samples, or a clock that jumped."""
    out: list[str | Note] = []
    if not gaps:
        return out
    longest = max(gap.t_after - gap.t_before for gap in gaps)
    missing = sum(gp.n_missing for gp in gaps)
    if missing > 10 * time.size:  # not dropped samples: a clock jump or a damaged time
        out.append(
            f"{name}: the time jumps by up to {longest:.3g} s ({len(gaps)} jump(s)), far "
            "longer than the run's samples span: the clock restarted or the time column "
            "is damaged (kept as gaps, not interpolated)"
        )
    else:
        out.append(
            Note(
                "read.gap",
                f"{name}: {len(gaps)} gap(s) in the time column, {missing} sample(s) "
                f"missing, longest {longest:.3g} s (kept as gaps, not interpolated)",
                subject=name,
            )
        )
    return out


def _limit_notes(
    name: str,
    force: np.ndarray | None,
    accel: np.ndarray | None,
    g: float,
    plan: RunPlan,
    warnings: list[str | Note],
) -> dict[str, int]:
    """Samples at the sensors' limits, counted (the notes added to ``warnings``)."""
    saturated = count_saturated(force, accel, g)
    if "force" in saturated:
        warnings.append(
            f"{name}: {saturated['force']} force sample(s) at the sensor limit "
            f"(±{FORCE_RANGE_N:g} N)"
        )
    if "accel" in saturated:
        warnings.append(
            Note(
                "read.sensor_limit",
                f"{name}: {saturated['accel']} acceleration sample(s) at the sensor limit (±16 g)",
                subject=name,
            )
        )
    elif accel is not None:
        pinned = pinned_extremes(accel)
        if pinned:
            saturated["accel"] = sum(p[2] for p in pinned)
            axes = plan.accel_axes
            where = "; ".join(
                f"{samples} on {axes[j] if j < len(axes) else j} at {value:.4g} m/s^2 "
                f"({value / g:+.3g} g, {runs} runs)"
                for j, value, samples, runs in pinned
            )
            warnings.append(
                Note(
                    "read.sensor_limit",
                    f"{name}: acceleration pinned at one extreme value in runs of equal "
                    f"samples ({where}): the sensor's range was reached, those samples are "
                    "clipped",
                    subject=name,
                )
            )
    return saturated


def _repeat_notes(
    name: str,
    accel: np.ndarray | None,
    force: np.ndarray | None,
    time: np.ndarray,
    rate: float,
) -> list[str | Note]:
    """Every value repeated in runs of equal samples: the sensor ran slower than the export."""
    repeats = repeat_factor(accel if accel is not None else force if force is not None else time)
    if repeats <= 1:
        return []
    return [Note(
        "read.rate",
        f"{name}: every value is repeated {repeats} times in a row: the sensor ran at "
        f"1/{repeats} of the export's {rate:.4g} Hz ({rate / repeats:.4g} Hz); the "
        "repeats carry no new information",
        subject=name,
    )]


def _rate_note(name: str, rate: float, column: str, unit: str) -> Note:
    """The ``read.rate`` note of an acceleration sampled outside 1 Hz-100 kHz.

    It names the time unit that would bring the rate nearest 100 Hz, if any.
    """
    text = (
        f"{name}: the acceleration is sampled at {rate:.3g} Hz (time read in {unit}), outside "
        f"the {RATE_MIN_HZ:g} Hz-{RATE_MAX_HZ / 1000:g} kHz of any accelerometer log"
    )
    scale = TIME_UNITS.get(unit, 1.0)
    options = [
        (abs(np.log10(rate * scale / s) - 2.0), u)
        for u, s in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9))
        if u != unit and np.isfinite(rate) and RATE_MIN_HZ <= rate * scale / s <= RATE_MAX_HZ
    ]
    if options:
        better = min(options)[1]
        text += f": if the time is in {better}, pass --columns time={column}:{better},..."
    return Note("read.rate", text, subject=name)


def _counts_map(plan: RunPlan, header: list[str], spec: str, counts: bool) -> str:
    """The ``--columns`` value that reads the acceleration with the scale ``spec``."""
    roles = ["a"] if len(plan.accel) == 1 else [f"a{axis}" for axis in plan.accel_axes]
    parts = [f"time={header[plan.time]}"]
    if plan.force is not None:
        parts.append(f"force={header[plan.force]}")
    parts += [f"{role}={header[col]}:{spec}" for role, col in zip(roles, plan.accel, strict=True)]
    tail = "; counts per g follow the sensor's range: 16384 at ±2 g, 8192 at ±4 g"
    return ",".join(parts) + (tail if counts else "")


def _force_onto_accel(
    path: Path,
    plan: RunPlan,
    force_all: np.ndarray,
    force_rows: np.ndarray,
    idx: np.ndarray,
    table: Table,
    header: list[str],
    force_time: np.ndarray,
    time_all: np.ndarray,
) -> tuple[np.ndarray | None, np.ndarray, str]:
    """Force at the acceleration rows ``idx``; rows the force does not cover are dropped."""
    fidx = np.flatnonzero(force_rows)
    t_force = force_time[fidx]
    column = header[plan.force_time if plan.force_time is not None else plan.time]
    check_time(path, t_force, lambda i: table.line_of(fidx[i]), column)
    t_accel = time_all[idx]
    if fidx.size < 2:
        return None, idx, "the force has fewer than 2 samples; left out"
    if t_accel.size and (t_force[-1] < t_accel[0] or t_accel[-1] < t_force[0]):
        raise LogReadError(
            path,
            f"{plan.name}: the force's clock ({t_force[0]:.4g}-{t_force[-1]:.4g} s in "
            f"'{column}') and the acceleration's ({t_accel[0]:.4g}-{t_accel[-1]:.4g} s in "
            f"'{header[plan.time]}') do not overlap: channels on disjoint clocks cannot be "
            "joined",
            column=column,
            hint="export both sensors on one clock, or read each with --columns",
        )
    res = onto_times(t_force, force_all[fidx], t_accel)
    how = (
        "averaged over each acceleration sample period (low-pass)"
        if res.method == "averaged"
        else "interpolated linearly"
    )
    note = (
        f"force ({res.source_rate_hz:.4g} Hz) and acceleration ({res.target_rate_hz:.4g} Hz) "
        f"are sampled at different rates; one run on the acceleration's sample times (the "
        f"acceleration is not interpolated), the force {how} onto them"
    )
    dropped = int(idx.size - np.count_nonzero(res.keep))
    if dropped:
        note += f"; {dropped} acceleration sample(s) outside the force's time span left out"
    gaps = find_gaps(t_force)
    if gaps:
        longest = max(gap.t_after - gap.t_before for gap in gaps)
        note += f"; {len(gaps)} gap(s) in the force (longest {longest:.3g} s) bridged"
    return res.values, idx[res.keep], note
