"""phyphox exports: one time base, ``Time (s)`` then ``Acceleration x (m/s^2)``, ...

Variants: "Acceleration with g" (``Acceleration x (m/s^2)``), "Acceleration without g"
(``Linear Acceleration x (m/s^2)``), and multi-sensor exports with one file per sensor
named after it (``Accelerometer.csv``: ``X (m/s^2)``, ``Y (m/s^2)``, ``Z (m/s^2)``).
``Absolute acceleration`` is ignored; ``Gyroscope x (rad/s)`` goes to ``extra``.
"""

from __future__ import annotations

from pathlib import Path

from balancer_id.read.header import ACCEL_WORDS, Column
from balancer_id.read.plan import RunPlan, plan_from_columns, plans_by_time

#: Name of phyphox's single run.
RUN_NAME = "Run 1"


def looks_like_phyphox(columns: list[Column]) -> bool:
    """Say whether a header is a phyphox export.

    phyphox writes ``Time (s)`` first, no run suffixes, and units with ``^`` (``m/s^2``)
    or the gyroscope's ``rad/s``.

    Parameters
    ----------
    columns : list of Column
        The classified header.

    Returns
    -------
    bool
        True for a phyphox header.
    """
    if not columns or columns[0].kind != "time" or any(c.run for c in columns):
        return False
    rest = columns[1:]
    return bool(rest) and any(
        c.kind in ("accel", "gyro", "ignore") and ("^" in c.unit or c.unit == "rad/s") for c in rest
    )


def plan_phyphox(path: Path, columns: list[Column]) -> list[RunPlan]:
    """Plan the single run of a phyphox export.

    Parameters
    ----------
    path : pathlib.Path
        The file; a per-sensor file named ``Linear Accelerometer.csv`` marks its bare
        ``X (m/s^2)`` columns as acceleration without g.
    columns : list of Column
        The classified header.

    Returns
    -------
    list of RunPlan
        One plan, or none when the file has neither force nor acceleration.
    """
    time = columns[0]
    members = [c for c in columns[1:] if c.kind != "time"]
    accel = [c for c in members if c.kind == "accel"]
    named = any(any(w in c.quantity.lower() for w in ACCEL_WORDS) for c in accel)
    with_g: bool | None = True if named else None
    if not named and "linear" in path.stem.lower():
        with_g = False
    if any(c.kind == "time" for c in columns[1:]):  # channels under time columns of their own
        return plans_by_time(RUN_NAME, columns, with_gravity_name=with_g)
    plan = plan_from_columns(RUN_NAME, time, members, with_gravity_name=with_g)
    return [plan] if plan.has_signal else []
