"""Vernier exports: Graphical Analysis, Logger Pro and LabQuest.

Columns are named ``<data set>:<quantity>(<unit>)`` (Graphical Analysis: ``Data Set
1:Time(s)``, ``Latest: Time (s)``; LabQuest and Logger Pro: ``Run 1: Time (s)``). Each
data set is a run with its own time column; a ``Latest`` or ``Run N`` prefix names it.
A motion detector's ``Acceleration(m/s²)`` is one kinematic axis (no gravity); a force
sensor's ``Force(N)`` the force; a 3-axis accelerometer's ``X-axis acceleration`` and so
on make the three axes.
"""

from __future__ import annotations

import re
from pathlib import Path

from balancer_id.read.header import Column, classify
from balancer_id.read.plan import RunPlan, plans_by_time

_PREFIX = re.compile(r"^(?P<set>[^:]{1,40}?)\s*:\s*(?P<rest>.+)$")


def _split(col: Column) -> tuple[str, Column] | None:
    """The data set and the column as if it had no prefix, or None."""
    match = _PREFIX.match(col.raw)
    if match is None:
        return None
    inner = classify(col.index, match.group("rest"))
    return match.group("set").strip(), inner


def looks_like_vernier(columns: list[Column]) -> bool:
    """Say whether a header is a Vernier export.

    Parameters
    ----------
    columns : list of Column
        The classified header.

    Returns
    -------
    bool
        True when every column has a ``<data set>:`` prefix and one is a time.
    """
    split = [_split(c) for c in columns if c.raw.strip()]
    return (
        bool(split)
        and all(s is not None for s in split)
        and any(s is not None and s[1].kind == "time" for s in split)
    )


def plan_vernier(path: Path, columns: list[Column]) -> list[RunPlan]:
    """Plan one run per Vernier data set.

    Parameters
    ----------
    path : pathlib.Path
        The file (unused).
    columns : list of Column
        The classified header.

    Returns
    -------
    list of RunPlan
        One plan per data set with a time and a force or acceleration column; a data
        set whose channels sit under time columns of their own (a force beside a
        photogate's event times) keeps each on its own time
        (:func:`~balancer_id.read.plan.plans_by_time`).
    """
    sets: dict[str, list[Column]] = {}
    for col in columns:
        split = _split(col)
        if split is not None:
            sets.setdefault(split[0], []).append(split[1])
    plans = []
    for name, members in sets.items():
        plans.extend(plans_by_time(name, members))
    return plans
