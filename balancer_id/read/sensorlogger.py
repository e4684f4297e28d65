"""Sensor Logger (Kelvin Choi's app) exports: ``time,seconds_elapsed,z,y,x``.

One file per sensor (``Accelerometer.csv``, ``AccelerometerUncalibrated.csv``, ...):
``time`` is the clock time in ns since 1970 (19 digits), ``seconds_elapsed`` the time
since the recording started, and the axes come in the order ``z, y, x`` without units.
``Accelerometer`` is acceleration without g in m/s^2; ``AccelerometerUncalibrated``
(iOS) includes gravity and is in g: whether the values include gravity and their unit are
decided from the data (:mod:`~balancer_id.read.units`). A copy re-saved by pandas has a
blank index column first (``,seconds_elapsed,z,y,x``). The time is ``seconds_elapsed``;
the clock time of the first sample, from ``time``, is kept as the recording's start.
"""

from __future__ import annotations

from pathlib import Path

from balancer_id.errors import LogReadError
from balancer_id.read.header import Column
from balancer_id.read.plan import RunPlan

#: Name of the single run.
RUN_NAME = "Run 1"
#: Sensor Logger files with the same header that hold no acceleration (from the file name).
NOT_ACCELERATION = ("gyroscope", "magnetometer", "orientation", "gravity", "compass")


def _names(columns: list[Column]) -> dict[str, Column]:
    return {c.raw.strip().lower(): c for c in columns}


def looks_like_sensor_logger(columns: list[Column]) -> bool:
    """Say whether a header is a Sensor Logger per-sensor file.

    Parameters
    ----------
    columns : list of Column
        The classified header.

    Returns
    -------
    bool
        True for ``seconds_elapsed`` with bare ``x``, ``y``, ``z`` columns.
    """
    names = _names(columns)
    return "seconds_elapsed" in names and {"x", "y", "z"} <= set(names)


def plan_sensor_logger(path: Path, columns: list[Column]) -> list[RunPlan]:
    """Plan the single run of a Sensor Logger file.

    Parameters
    ----------
    path : pathlib.Path
        The file (unused: the header says everything).
    columns : list of Column
        The classified header.

    Returns
    -------
    list of RunPlan
        One plan: time ``seconds_elapsed`` (s), acceleration x, y, z in that order;
        ``time`` (ns since 1970) as the recording's start.

    Raises
    ------
    LogReadError
        The file is named after a sensor that is no accelerometer (``Gyroscope.csv``,
        ``Gravity.csv``, ...): its x, y, z are no acceleration.
    """
    stem = path.stem.lower()
    other = next((word for word in NOT_ACCELERATION if word in stem), None)
    if other is not None:
        raise LogReadError(
            path,
            f"a Sensor Logger '{other}' file (from its name): its x, y, z are no acceleration",
            line=1,
            hint="give the recording's Accelerometer.csv (or AccelerometerUncalibrated.csv), "
            "or --columns if this file does hold acceleration",
        )
    names = _names(columns)
    plan = RunPlan(name=RUN_NAME, time=names["seconds_elapsed"].index)
    plan.time_unit, plan.time_unit_from = "s", "layout"
    plan.accel = tuple(names[a].index for a in ("x", "y", "z"))
    plan.accel_axes = ("x", "y", "z")
    if "time" in names:
        plan.clock = names["time"].index
    return [plan]
