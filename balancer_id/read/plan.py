"""What to read from which column: one :class:`RunPlan` per run of a log.

The layout readers (:mod:`~balancer_id.read.pasco`, :mod:`~balancer_id.read.phyphox`,
:mod:`~balancer_id.read.generic`) only decide the plans; :mod:`~balancer_id.read.assemble`
turns plans plus the parsed numbers into :class:`~balancer_id.read.recording.Recording`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from balancer_id.read.header import TIME_UNITS, Column
from balancer_id.read.timebase import unit_of_column

_AXES = ("x", "y", "z")


@dataclass
class RunPlan:
    """The columns of one run.

    Attributes
    ----------
    name : str
        Run name for the :class:`Recording`.
    time : int
        Column index of the time.
    force : int or None
        Column index of the force, or None.
    force_time : int or None
        Column index of the force's own time column when it is not ``time`` (a sensor
        at another rate in columns of its own); the force is then brought onto the
        acceleration's sample times.
    force_time_scale : float
        Factor to seconds of ``force_time``.
    accel : tuple of int
        Column indexes of the acceleration axes (empty when none).
    accel_axes : tuple of str
        Axis labels of ``accel``.
    accel_unit : str
        ``"m/s^2"``, ``"g"`` or ``""`` (not stated in the header).
    includes_gravity : bool or None
        True/False when the layout says so; None to decide from the data.
    extra : dict
        Label -> column index of other numeric channels (gyro, position, ...).
    time_unit : str
        The time's unit when known (``"s"``, ``"ms"``, ``"us"``, ``"ns"``), else ``""``
        (decided from the values, :mod:`~balancer_id.read.timebase`).
    time_unit_from : str
        Where ``time_unit`` comes from: ``"map"``, ``"layout"``, ``"header"``, ``"name"``.
    accel_unit_given : bool
        True when the column map gave the acceleration's unit: it is then taken as
        forced (checked against the resting magnitude, never guessed).
    gravity_given : bool
        True when the column map said whether the acceleration includes gravity
        (``gravity=yes|no``): never overruled by the data.
    scales : dict
        Column index -> ``(factor, offset)`` from the column map: value = raw * factor +
        offset, in the unit of ``time_unit``/``accel_unit`` (N for force).
    clock : int or None
        Column index of a clock time (ns since 1970, Sensor Logger's ``time``) that gives
        the recording's start when the time column is a time since the start.
    clock_start : float or None
        The run's start (s since 1970) read from a date-and-time column (SPARKvue), to the
        second, when its time column is no clock time.
    guessed : bool
        True when the columns were guessed from their names (a generic CSV without a
        column map); the choice is stated in a ``read.column_guess`` note.
    notes : list of str
        Warnings found while planning (duplicate channels, ...).
    """

    name: str
    time: int
    force: int | None = None
    force_time: int | None = None
    force_time_scale: float = 1.0
    accel: tuple[int, ...] = ()
    accel_axes: tuple[str, ...] = ()
    accel_unit: str = ""
    includes_gravity: bool | None = None
    extra: dict[str, int] = field(default_factory=dict)
    time_unit: str = ""
    time_unit_from: str = ""
    accel_unit_given: bool = False
    gravity_given: bool = False
    scales: dict[int, tuple[float, float]] = field(default_factory=dict)
    clock: int | None = None
    clock_start: float | None = None
    guessed: bool = False
    notes: list[str] = field(default_factory=list)

    @property
    def columns(self) -> list[int]:
        """Every column index this plan reads."""
        cols = [self.time, *self.accel, *self.extra.values()]
        if self.force is not None:
            cols.append(self.force)
        if self.force_time is not None:
            cols.append(self.force_time)
        if self.clock is not None:
            cols.append(self.clock)
        return cols

    @property
    def has_signal(self) -> bool:
        """True when the run has a force or an acceleration column."""
        return self.force is not None or bool(self.accel)


def plan_from_columns(
    name: str,
    time: Column,
    members: list[Column],
    *,
    with_gravity_name: bool | None = None,
) -> RunPlan:
    """Build a run plan from its time column and its measurement columns.

    Parameters
    ----------
    name : str
        The run's name.
    time : Column
        Its time column.
    members : list of Column
        Its other columns (any kind; datetime and ignored columns are skipped).
    with_gravity_name : bool, optional
        What an ``"Acceleration x"`` name (not "Linear") says about gravity: True for
        phyphox (it names the variant), None to decide from the data.

    Returns
    -------
    RunPlan
        The plan; ``accel`` holds three axes, one axis, or nothing.
    """
    plan = RunPlan(name=name, time=time.index)
    set_time_unit(plan, time)
    axes, single = _sort_members(plan, members)
    chosen = _choose_accel(plan, axes, single)
    plan.accel = tuple(c.index for c in chosen)
    if chosen:
        units = {c.accel_unit for c in chosen}
        plan.accel_unit = units.pop() if len(units) == 1 else ""
        if all(c.unit.strip().lower() == "mg" for c in chosen):  # thousandths of g
            plan.accel_unit = "g"
            plan.scales.update({c.index: (1e-3, 0.0) for c in chosen})
        if any(c.linear for c in chosen):
            plan.includes_gravity = False
        elif with_gravity_name is not None and len(chosen) == 3:
            plan.includes_gravity = with_gravity_name
    return plan


def _sort_members(
    plan: RunPlan, members: list[Column]
) -> tuple[dict[str, Column], list[Column]]:
    """The force (a second one: an extra channel), the acceleration axes and a single
    acceleration column; gyroscopes and the rest as extra channels."""
    axes: dict[str, Column] = {}
    single: list[Column] = []
    for col in members:
        if col.kind == "force":
            if plan.force is None:
                plan.force = col.index
            else:
                plan.extra[_unique(plan.extra, col.label)] = col.index
                plan.notes.append(f"second force column '{col.raw}' kept as an extra channel")
        elif col.kind == "accel":
            if col.axis and col.axis not in axes:
                axes[col.axis] = col
            elif not col.axis and not single:
                single.append(col)
            else:
                plan.extra[_unique(plan.extra, col.label)] = col.index
        elif col.kind in ("gyro", "other"):
            plan.extra[_unique(plan.extra, col.label)] = col.index
    return axes, single


def _choose_accel(plan: RunPlan, axes: dict[str, Column], single: list[Column]) -> list[Column]:
    """The acceleration: three axes, or one column; the others kept as extra channels."""
    chosen: list[Column]
    if len(axes) == 3:
        chosen = [axes[a] for a in _AXES]
        for col in single:
            plan.extra[_unique(plan.extra, col.label)] = col.index
        plan.accel_axes = _AXES
    elif single or len(axes) == 1:
        if single:
            chosen, plan.accel_axes = [single[0]], ("z",)
        else:
            (axis, col), *_ = axes.items()
            chosen, plan.accel_axes = [col], (axis,)
        for col in axes.values() if single else []:
            plan.extra[_unique(plan.extra, col.label)] = col.index
    else:
        chosen = []
        for col in axes.values():
            plan.extra[_unique(plan.extra, col.label)] = col.index
        if axes:
            plan.notes.append(
                "acceleration has only the axes "
                + ", ".join(sorted(axes))
                + "; kept as extra channels, not as the acceleration"
            )
    return chosen


def set_time_unit(plan: RunPlan, time: Column) -> None:
    """Set the plan's time unit from what its time column states (header or name).

    Parameters
    ----------
    plan : RunPlan
        The plan (changed in place).
    time : Column
        Its time column.
    """
    plan.time_unit, plan.time_unit_from = unit_of_column(time)


def _unique(existing: dict[str, int], label: str) -> str:
    key, n = label, 2
    while key in existing:
        key, n = f"{label} #{n}", n + 1
    return key


def plans_by_time(
    name: str, columns: list[Column], *, with_gravity_name: bool | None = None
) -> list[RunPlan]:
    """Plan one run whose channels may sit under time columns of their own.

    Each measurement column takes the time column that comes last before it (the
    first time column when none does): a force on its own clock beside an event-timed
    photogate, or sensors at different rates, each keep their own time. A force-only
    plan is joined to the acceleration-only plan (the force brought onto the
    acceleration's times, :func:`join_rates`); other groups with a force or an
    acceleration make runs of their own (``"<name> (2)"``).

    Parameters
    ----------
    name : str
        The run's name.
    columns : list of Column
        Its columns, time columns included, in file order.
    with_gravity_name : bool, optional
        Passed to :func:`plan_from_columns`.

    Returns
    -------
    list of RunPlan
        The plans with a force or an acceleration (empty when none has one).
    """
    times = [c for c in columns if c.kind == "time"]
    if not times:
        return []
    groups: dict[int, list[Column]] = {}
    current = times[0]
    for col in columns:
        if col.kind == "time":
            current = col
            continue
        if col.kind in ("datetime", "ignore"):
            continue
        groups.setdefault(current.index, []).append(col)
    by_index = {c.index: c for c in times}
    plans = [
        plan_from_columns(name, by_index[t], cols, with_gravity_name=with_gravity_name)
        for t, cols in groups.items()
    ]
    plans = join_rates([p for p in plans if p.has_signal])
    for k, plan in enumerate(plans[1:], start=2):
        plan.name = f"{name} ({k})"
    return plans


def join_rates(plans: list[RunPlan]) -> list[RunPlan]:
    """Join a force-only plan into the acceleration-only plan of the same run.

    Parameters
    ----------
    plans : list of RunPlan
        The plans of one run, one per time column.

    Returns
    -------
    list of RunPlan
        The plans, the force-only one folded into the acceleration-only one (its force
        and the force's own time column, :attr:`RunPlan.force_time`).
    """
    force = next((p for p in plans if p.force is not None and not p.accel), None)
    accel = next((p for p in plans if p.accel and p.force is None), None)
    if force is None or accel is None:
        return plans
    accel.force, accel.force_time, accel.force_time_scale = (
        force.force,
        force.time,
        TIME_UNITS.get(force.time_unit, 1.0),
    )
    accel.notes.extend(force.notes)
    if force.extra:
        accel.notes.append(
            "channel(s) "
            + ", ".join(f"'{k}'" for k in force.extra)
            + " on the force's time column ignored"
        )
    return [p for p in plans if p is not force]
