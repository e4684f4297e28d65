"""Any other CSV: columns given by the user, or guessed from their names.

The column map has the keys ``time``, ``force``, ``ax``, ``ay``, ``az`` (or ``a`` for one
vertical acceleration column); names match the header case-insensitively. Without a map,
names are split into words (``acc_x`` -> ``acc``, ``x``) and matched against time, force
and acceleration keywords.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from balancer_id.errors import LogReadError, UsageError
from balancer_id.read.header import Column, name_tokens
from balancer_id.read.inference import Inference
from balancer_id.read.plan import RunPlan, plan_from_columns, plans_by_time, set_time_unit
from balancer_id.read.timebase import canonical

#: Keys a column map may use.
MAP_KEYS = ("time", "force", "ax", "ay", "az", "a", "gravity")
#: Values of the map's ``gravity`` entry: does the acceleration include gravity?
_GRAVITY_VALUES = {
    "yes": True,
    "no": False,
    "true": True,
    "false": False,
    "with": True,
    "without": False,
}
#: Name of the single run of a generic log.
RUN_NAME = "Run 1"
#: What to tell a user whose columns cannot be found.
COLUMNS_HINT = "pass --columns time=...,force=...,ax=...,ay=...,az=... (or a=... for one axis)"

_MAX_LISTED = 20


def listed_columns(columns: list[Column]) -> str:
    """Return the header names for an error message (at most 20, quoted).

    Parameters
    ----------
    columns : list of Column
        The header.

    Returns
    -------
    str
        ``"'t', 'F', 'acc_x'"``, with ``..., N more`` when long.
    """
    names = [repr(c.raw) for c in columns[:_MAX_LISTED]]
    if len(columns) > _MAX_LISTED:
        names.append(f"... {len(columns) - _MAX_LISTED} more")
    return ", ".join(names)


_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_SPEC = re.compile(
    rf"^(?:counts?\s*/\s*(?P<div>{_NUM})|(?P<fac>{_NUM})\s*\*?)?\s*"
    rf"(?P<unit>[^\d\s+*][^+]*?)?\s*(?P<off>[+-]\s*{_NUM})?$"
)
#: Units the column map takes per role, with their factor to the reader's unit.
MAP_UNITS: dict[str, dict[str, float]] = {
    "time": {u: 1.0 for u in ("s", "sec", "ms", "msec", "us", "µs", "μs", "ns", "min")},
    "accel": {"g": 1.0, "mg": 1e-3, "m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0},
    "force": {"N": 1.0, "kN": 1e3, "mN": 1e-3, "kgf": 9.80665, "lbf": 4.4482216152605},
}


#: A unit word ending a name after a separator: ``force_mN``, ``Force kN``, ``F-lbf``.
_UNIT_SUFFIX = re.compile(r"[\s_\-.]([A-Za-z]+)$")


def force_unit_of(col: Column) -> str:
    """The force unit a column's name states (``Force (lbf)``, ``force_mN``), as written
    in :data:`MAP_UNITS`, or ``""`` when it states none.

    Parameters
    ----------
    col : Column
        The force column.

    Returns
    -------
    str
    """
    units = {k.lower(): k for k in MAP_UNITS["force"]}
    if col.unit.strip():
        return units.get(col.unit.strip().lower(), "")
    suffix = _UNIT_SUFFIX.search(col.quantity.strip())
    return units.get(suffix.group(1).lower(), "") if suffix else ""


def scale_stated_force_units(plans: list[RunPlan], header: list[Column]) -> list[Inference]:
    """Scale each run's force to N where its name states another unit (``Force (lbf)``,
    ``force_mN``, ``Kraft (kN)``) and the column map gave none; say so for ``inspect``.

    Parameters
    ----------
    plans : list of RunPlan
        The runs' plans (their ``scales`` gain the force's factor).
    header : list of Column
        The classified header.

    Returns
    -------
    list of Inference
        A ``force unit`` decision per run whose force is not in N.
    """
    by_index = {c.index: c for c in header}
    out = []
    for plan in plans:
        if plan.force is None or plan.force in plan.scales:
            continue
        col = by_index[plan.force]
        unit = force_unit_of(col)
        if not unit or unit == "N":
            continue
        factor = MAP_UNITS["force"][unit]
        plan.scales[plan.force] = (factor, 0.0)
        out.append(
            Inference(
                "force unit",
                unit,
                f"the name '{col.raw}' says {unit}: values x{factor:.6g} to N",
                f"--columns force={col.raw}:N",
                run=plan.name,
            )
        )
    return out


def parse_spec(role: str, text: str) -> tuple[str, float, float]:
    """Parse the unit or scale of a column-map entry (the part after ``NAME:``).

    ``ms`` (a unit), ``counts/4096g`` (4096 counts per g), ``0.00315N`` (N per count),
    ``3.15e-6N+0.30`` (N per count plus an offset in N), ``1.22e-4g``, ``mg``.

    Parameters
    ----------
    role : str
        ``time``, ``force`` or an acceleration role (``ax``, ``ay``, ``az``, ``a``).
    text : str
        The spec.

    Returns
    -------
    unit : str
        ``"s"``/``"ms"``/``"us"``/``"ns"``/``"min"`` (time), ``"g"`` or ``"m/s^2"``
        (acceleration), ``"N"`` (force).
    factor, offset : float
        Value = raw * factor + offset, in ``unit``.

    Raises
    ------
    UsageError
        The spec is not understood, or its unit does not fit the role.
    """
    kind = "time" if role == "time" else "force" if role == "force" else "accel"
    units = MAP_UNITS[kind]
    match = _SPEC.match(text.strip())
    unit = (match.group("unit") or "").strip() if match else ""
    key = unit if kind == "time" else unit.lower()
    if match is None or key not in {k.lower() if kind != "time" else k for k in units}:
        raise UsageError(
            f"--columns {role}=...:{text}: give a unit of "
            + ", ".join(units)
            + ", optionally with a scale (e.g. "
            + {
                "time": "time=Time_ms:ms",
                "accel": "ax=AccX:counts/4096g",
                "force": "force=Force:0.00315N or Force:3.15e-6N+0.30",
            }[kind]
            + ")"
        )
    factor, offset = _scale_of(match)
    if not (np.isfinite(factor) and factor != 0.0 and np.isfinite(offset)):
        raise UsageError(f"--columns {role}=...:{text}: the scale must be finite and not zero")
    if kind == "time":
        return canonical(key), factor, offset
    scale = next(v for k, v in units.items() if k.lower() == key)
    if kind == "force":
        return "N", factor * scale, offset * scale
    return ("g" if key in ("g", "mg") else "m/s^2"), factor * scale, offset * scale


def _scale_of(match: re.Match[str]) -> tuple[float, float]:
    """A spec's factor (``/4096`` or ``0.00315``) and offset (``+0.30``)."""
    factor = 1.0
    if match.group("div"):
        divisor = float(match.group("div"))
        factor = 1.0 / divisor if divisor else float("inf")
    elif match.group("fac"):
        factor = float(match.group("fac"))
    offset = float(match.group("off").replace(" ", "")) if match.group("off") else 0.0
    return factor, offset


def _find(
    path: Path, columns: list[Column], role: str, value: str
) -> tuple[Column, tuple[str, float, float] | None]:
    """The header column a map entry names, and its parsed unit spec (None when none)."""
    by_name = {c.raw.strip().lower(): c for c in columns}
    name = str(value).strip()
    col = by_name.get(name.lower())
    if col is not None:
        return col, None
    left, sep, spec = name.rpartition(":")
    if sep and left.strip().lower() in by_name:
        return by_name[left.strip().lower()], parse_spec(role, spec)
    raise LogReadError(
        path,
        f"column '{name}' given for {role} is not in the header",
        line=1,
        column=name,
        hint=f"columns present: {listed_columns(columns)}",
    )


def plan_from_map(path: Path, columns: list[Column], mapping: dict[str, str]) -> list[RunPlan]:
    """Plan a log from a user's column map.

    Each entry is ``ROLE=NAME`` or ``ROLE=NAME:SPEC``, SPEC a unit and optional scale
    (:func:`parse_spec`): ``time=Time_ms:ms``, ``ax=AccX:counts/4096g``,
    ``force=Force:3.15e-6N+0.30``. A unit given here is forced: it is not guessed from
    the values (a contradiction with the resting magnitude is refused).

    Parameters
    ----------
    path : pathlib.Path
        The file (for error messages).
    columns : list of Column
        The classified header.
    mapping : dict
        Role -> column name (with an optional ``:SPEC``); roles are :data:`MAP_KEYS`
        (``gravity=yes|no`` says whether the acceleration includes gravity).

    Returns
    -------
    list of RunPlan
        One plan.

    Raises
    ------
    UsageError
        The map has an unknown role, no ``time``, no force or acceleration, mixes
        ``a`` with ``ax``/``ay``/``az``, or a spec that is not understood.
    LogReadError
        A mapped name is not in the header.
    """
    roles, axes = _checked_roles(mapping)
    gravity = roles.pop("gravity", None)
    if gravity is not None and str(gravity).strip().lower() not in _GRAVITY_VALUES:
        raise UsageError("--columns gravity=...: give yes (gravity in the values) or no")
    found: dict[str, Column] = {}
    specs: dict[str, tuple[str, float, float]] = {}
    for role, name in roles.items():
        found[role], spec = _find(path, columns, role, name)
        if spec is not None:
            specs[role] = spec
    time = found["time"]
    plan = RunPlan(name=RUN_NAME, time=time.index)
    set_time_unit(plan, time)
    if "time" in specs:
        unit, factor, offset = specs["time"]
        plan.time_unit, plan.time_unit_from = unit, "map"
        if (factor, offset) != (1.0, 0.0):
            plan.scales[time.index] = (factor, offset)
    if "force" in found:
        plan.force = found["force"].index
        if "force" in specs:
            plan.scales[plan.force] = specs["force"][1:]
    accel_cols: list[Column] = []
    accel_roles: list[str] = []
    if "a" in found:
        accel_cols, plan.accel_axes, accel_roles = [found["a"]], ("z",), ["a"]
    elif axes:
        accel_cols = [found[k] for k in axes]
        plan.accel_axes = tuple(k[1] for k in axes)
        accel_roles = list(axes)
    _set_accel(plan, accel_cols)
    if gravity is not None:
        plan.includes_gravity = _GRAVITY_VALUES[str(gravity).strip().lower()]
        plan.gravity_given = True
    _accel_specs(plan, specs, accel_roles, accel_cols)
    return [plan]


def _checked_roles(mapping: dict[str, str]) -> tuple[dict[str, str], list[str]]:
    """The map's roles (lower case) and acceleration axes, refused when incomplete."""
    roles = {k.strip().lower(): v for k, v in mapping.items()}
    unknown = sorted(set(roles) - set(MAP_KEYS))
    if unknown:
        raise UsageError(
            f"unknown column role(s) {', '.join(unknown)} in the column map; "
            f"use {', '.join(MAP_KEYS)}"
        )
    if "time" not in roles:
        raise UsageError("the column map needs a time column: --columns time=NAME,...")
    axes: list[str] = [k for k in ("ax", "ay", "az") if k in roles]
    if "a" in roles and axes:
        raise UsageError("the column map gives both a and ax/ay/az; give one or the other")
    if "force" not in roles and "a" not in roles and not axes:
        raise UsageError("the column map needs force=NAME or acceleration (ax=,ay=,az= or a=)")
    return roles, axes


def _accel_specs(
    plan: RunPlan,
    specs: dict[str, tuple[str, float, float]],
    accel_roles: list[str],
    accel_cols: list[Column],
) -> None:
    """The acceleration's unit and scales from the map (one unit for every axis)."""
    given = [specs[r] for r in accel_roles if r in specs]
    if not given:
        return
    if len(given) != len(accel_roles) or len({u for u, _, _ in given}) != 1:
        raise UsageError(
            "--columns: give the same unit to every acceleration axis "
            "(e.g. ax=AccX:counts/4096g,ay=AccY:counts/4096g,az=AccZ:counts/4096g)"
        )
    plan.accel_unit, plan.accel_unit_given = given[0][0], True
    for role, col in zip(accel_roles, accel_cols, strict=True):
        if specs[role][1:] != (1.0, 0.0):
            plan.scales[col.index] = specs[role][1:]


def _set_accel(plan: RunPlan, cols: list[Column]) -> None:
    plan.accel = tuple(c.index for c in cols)
    if not cols:
        return
    units = {c.accel_unit for c in cols}
    plan.accel_unit = units.pop() if len(units) == 1 else ""
    if any(c.linear for c in cols):
        plan.includes_gravity = False


#: Words in a time column's name that make it the run's time rather than a clock.
_ELAPSED_WORDS = frozenset({"elapsed", "relative", "rel", "since", "start"})


def _run_time(times: list[Column]) -> Column:
    """The time column of a run: one counted from the start when the file has several."""
    for col in times:
        if set(name_tokens(col.quantity)) & _ELAPSED_WORDS:
            return col
    return times[0]


def guess_plan(columns: list[Column]) -> list[RunPlan]:
    """Plan a file no layout claims from its classified columns.

    The columns' kinds come from :func:`~balancer_id.read.header.classify`, the one
    column recognition every layout uses; the run is built by
    :func:`~balancer_id.read.plan.plan_from_columns` as for every layout (axis
    families grouped by their axis letter whatever their naming).

    Parameters
    ----------
    columns : list of Column
        The classified header.

    Returns
    -------
    list of RunPlan
        One plan, or an empty list when no time column or neither force nor acceleration
        can be recognised.
    """
    times = [c for c in columns if c.kind == "time"]
    if not times:
        return []
    if _own_clocks(columns, times):
        plans = plans_by_time(RUN_NAME, columns)
    else:
        time = _run_time(times)
        members = [c for c in columns if c.kind not in ("time", "datetime", "ignore")]
        plans = [plan_from_columns(RUN_NAME, time, members)]
    for plan in plans:
        plan.extra = {}  # a generic log keeps time, force and acceleration
        plan.guessed = True
    return [p for p in plans if p.has_signal]


def _own_clocks(columns: list[Column], times: list[Column]) -> bool:
    """True when measurement columns follow more than one time column (each its clock)."""
    followed = 0
    current = None
    for col in columns:
        if col.kind == "time":
            current = col
        elif col.kind in ("force", "accel") and current is not None:
            followed |= 1 << times.index(current)
    return bin(followed).count("1") > 1


def no_columns_error(path: Path, columns: list[Column], what: str) -> LogReadError:
    """Build the error for a header in which ``what`` cannot be found.

    Parameters
    ----------
    path : pathlib.Path
        The file.
    columns : list of Column
        The header.
    what : str
        What is missing, e.g. ``"no force or acceleration column"``.

    Returns
    -------
    LogReadError
        Names the file, line 1 and the columns present, and tells the user to pass
        ``--columns``.
    """
    hint = COLUMNS_HINT
    if what == "no force or acceleration column":
        hint = (
            "record or export the force sensor or the accelerometer; if a column here is a "
            "force or an acceleration under another name, " + COLUMNS_HINT
        )
    return LogReadError(
        path, f"{what} (columns found: {listed_columns(columns)})", line=1, hint=hint
    )
