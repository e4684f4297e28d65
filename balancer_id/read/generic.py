"""Any other CSV: columns given by the user, or guessed from their names.

The column map has the keys ``time``, ``force``, ``ax``, ``ay``, ``az`` (or ``a`` for one
vertical acceleration column); names match the header case-insensitively. Without a map,
names are split into words (``acc_x`` -> ``acc``, ``x``) and matched against time, force
and acceleration keywords.
"""

from __future__ import annotations

import re
from pathlib import Path

from balancer_id.errors import LogReadError, UsageError
from balancer_id.read.header import ACCEL_WORDS, FORCE_WORDS, TIME_WORDS, Column, split_name
from balancer_id.read.plan import RunPlan

#: Keys a column map may use.
MAP_KEYS = ("time", "force", "ax", "ay", "az", "a")
#: Name of the single run of a generic log.
RUN_NAME = "Run 1"
#: What to tell a user whose columns cannot be found.
COLUMNS_HINT = "pass --columns time=...,force=...,ax=...,ay=...,az=... (or a=... for one axis)"

_MAX_LISTED = 20
_TIME_TOKENS = TIME_WORDS | {"sec", "secs", "seconds", "elapsed", "zeit_s"}
_FORCE_TOKENS = {*FORCE_WORDS, "f", "load", "fz"}
_ACCEL_TOKENS = {*ACCEL_WORDS, "a", "acc", "accel", "accelerometer", "acceleration", "accz"}
_AXIS_TOKENS = {"ax": "x", "ay": "y", "az": "z", "accx": "x", "accy": "y", "accz": "z"}


def _tokens(name: str) -> list[str]:
    name = re.sub(r"([a-z])([A-Z])", r"\1 \2", name)
    return [t for t in re.split(r"[^\w²^]+|_", name.lower()) if t]


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


def plan_from_map(path: Path, columns: list[Column], mapping: dict[str, str]) -> list[RunPlan]:
    """Plan a log from a user's column map.

    Parameters
    ----------
    path : pathlib.Path
        The file (for error messages).
    columns : list of Column
        The classified header.
    mapping : dict
        Role -> column name; roles are :data:`MAP_KEYS`.

    Returns
    -------
    list of RunPlan
        One plan.

    Raises
    ------
    UsageError
        The map has an unknown role, no ``time``, no force or acceleration, or mixes
        ``a`` with ``ax``/``ay``/``az``.
    LogReadError
        A mapped name is not in the header.
    """
    roles = {k.strip().lower(): v for k, v in mapping.items()}
    unknown = sorted(set(roles) - set(MAP_KEYS))
    if unknown:
        raise UsageError(
            f"unknown column role(s) {', '.join(unknown)} in the column map; "
            f"use {', '.join(MAP_KEYS)}"
        )
    if "time" not in roles:
        raise UsageError("the column map needs a time column: --columns time=NAME,...")
    axes = [k for k in ("ax", "ay", "az") if k in roles]
    if "a" in roles and axes:
        raise UsageError("the column map gives both a and ax/ay/az; give one or the other")
    if "force" not in roles and "a" not in roles and not axes:
        raise UsageError("the column map needs force=NAME or acceleration (ax=,ay=,az= or a=)")
    by_name = {c.raw.strip().lower(): c for c in columns}
    found: dict[str, Column] = {}
    for role, name in roles.items():
        col = by_name.get(str(name).strip().lower())
        if col is None:
            raise LogReadError(
                path,
                f"column '{name}' given for {role} is not in the header",
                line=1,
                column=str(name),
                hint=f"columns present: {listed_columns(columns)}",
            )
        found[role] = col
    time = found["time"]
    plan = RunPlan(name=RUN_NAME, time=time.index, time_scale=time.time_scale)
    if "force" in found:
        plan.force = found["force"].index
    accel_cols: list[Column] = []
    if "a" in found:
        accel_cols, plan.accel_axes = [found["a"]], ("z",)
    elif axes:
        accel_cols = [found[k] for k in axes]
        plan.accel_axes = tuple(k[1] for k in axes)
    _set_accel(plan, accel_cols)
    return [plan]


def _set_accel(plan: RunPlan, cols: list[Column]) -> None:
    plan.accel = tuple(c.index for c in cols)
    if not cols:
        return
    units = {_unit_of(c) for c in cols}
    plan.accel_unit = units.pop() if len(units) == 1 else ""
    if any(c.linear for c in cols):
        plan.includes_gravity = False


def _unit_of(col: Column) -> str:
    if col.accel_unit:
        return col.accel_unit
    tokens = _tokens(col.raw)
    if tokens and tokens[-1] == "g":
        return "g"
    if tokens and tokens[-1] in ("ms2", "mps2"):
        return "m/s^2"
    return ""


def guess_plan(columns: list[Column]) -> list[RunPlan]:
    """Guess time, force and acceleration from the column names.

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
    time = force = None
    axes: dict[str, Column] = {}
    single = None
    for col in columns:
        quantity = split_name(col.raw)[0]
        tokens = _tokens(quantity) or _tokens(col.raw)
        if not tokens:
            continue
        if time is None and (col.kind == "time" or tokens[0] in _TIME_TOKENS):
            time = col
            continue
        if col.kind in ("ignore", "gyro", "datetime"):
            continue
        if force is None and (col.kind == "force" or any(t in _FORCE_TOKENS for t in tokens)):
            force = col
            continue
        axis = _accel_axis(col, tokens)
        if axis and axis not in axes:
            axes[axis] = col
        elif axis == "" and single is None:
            single = col
    if time is None or (force is None and not axes and single is None):
        return []
    plan = RunPlan(name=RUN_NAME, time=time.index, time_scale=time.time_scale)
    if force is not None:
        plan.force = force.index
    if len(axes) == 3:
        plan.accel_axes = ("x", "y", "z")
        _set_accel(plan, [axes[a] for a in plan.accel_axes])
    elif single is not None:
        plan.accel_axes = ("z",)
        _set_accel(plan, [single])
    elif len(axes) == 1:
        (axis, col), *_ = axes.items()
        plan.accel_axes = (axis,)
        _set_accel(plan, [col])
    return [plan] if plan.has_signal else []


def _accel_axis(col: Column, tokens: list[str]) -> str | None:
    """Return the axis of an acceleration column, ``""`` for one without axis, else None."""
    if col.kind == "accel":
        return col.axis
    if len(tokens) == 1 and tokens[0] in _AXIS_TOKENS:
        return _AXIS_TOKENS[tokens[0]]
    if tokens[0] in _ACCEL_TOKENS or any(t.startswith("accel") for t in tokens):
        rest = [t for t in tokens[1:] if t in ("x", "y", "z")]
        if rest:
            return rest[0]
        if len(tokens) == 1 or all(t in ("g", "ms2", "mps2", "m", "s", "s2") for t in tokens[1:]):
            return ""
    return None


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
    return LogReadError(
        path,
        f"{what} (columns found: {listed_columns(columns)})",
        line=1,
        hint=COLUMNS_HINT,
    )
