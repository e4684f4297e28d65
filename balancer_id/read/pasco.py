"""PASCO Capstone and SPARKvue exports: runs side by side, grouped by their name suffix.

Capstone writes ``Time (s) Run #1``, ``Force (N) Run #1``, ``Acceleration x (m/s²) Run #1``
..., or one time column shared by several runs (``Time (s) Auto``, ``Time (s)``).
SPARKvue writes ``Date and Time Run 1``, ``Time (s) Run 1``, ... where ``Run 1`` may be any
name the user typed (``Force (N) 9.9`` is quantity ``Force (N)`` of run ``9.9``).
"""

from __future__ import annotations

import re
from pathlib import Path

from balancer_id.errors import LogReadError
from balancer_id.read.header import Column
from balancer_id.read.plan import RunPlan, join_rates, plan_from_columns

_SHARED_RUNS = ("", "auto")
#: Capstone's run suffix in any language: ``Run #1``, ``Lauf #1``, ``Ejecución #1``.
_CAPSTONE_RUN = re.compile(r"^[^\W\d_]+\s*#\s*\d+$", re.IGNORECASE)
_SPARKVUE_RUN = re.compile(r"^run\s+\d+$", re.IGNORECASE)


def looks_like_pasco(columns: list[Column]) -> str | None:
    """Say whether a header is a PASCO export, and which program wrote it.

    Parameters
    ----------
    columns : list of Column
        The classified header.

    Returns
    -------
    str or None
        ``"pasco-sparkvue"``, ``"pasco-capstone"`` or None when the header is not PASCO's.
    """
    runs = [c.run for c in columns if c.run]
    dated = [c for c in columns if c.kind == "datetime"]
    timed = any(c.kind == "time" and c.run for c in columns)
    if dated and timed and any(c.run for c in dated):  # "Date and Time Run 1", "Time (s) Run 1"
        return "pasco-sparkvue"
    if any(_CAPSTONE_RUN.match(r) for r in runs) or any(r.lower() == "auto" for r in runs):
        return "pasco-capstone"
    if any(_SPARKVUE_RUN.match(r) for r in runs):
        return "pasco-sparkvue"
    return None


def plan_runs(path: Path, columns: list[Column]) -> list[RunPlan]:
    """Group a PASCO header into runs.

    A run is the set of columns sharing a suffix. A measurement column takes the time
    column of its run that comes last before it in the header (Capstone writes one time
    column per rate: ``Time (s) Run #1, Force (N) Run #1, Time (s) Run #1, Position (m)
    Run #1``), else the shared one before it (``Time (s) Auto``, ``Time (s)``), else the
    first time column of its run, the shared one, or the only time column of the file.
    A run whose force and acceleration sit under different time columns (sensors at
    different rates) gives one plan: the acceleration's, with the force and its own time
    column (:attr:`RunPlan.force_time`). Other measurement groups under further time
    columns give plans of their own, named ``"<run> (force)"``, ``"<run> (acceleration)"``
    or ``"<run> (N)"``.

    Parameters
    ----------
    path : pathlib.Path
        The file (for error messages).
    columns : list of Column
        The classified header.

    Returns
    -------
    list of RunPlan
        One per run (and time column) that has a force or an acceleration column, in
        file order.

    Raises
    ------
    LogReadError
        A run has force or acceleration but no time column can be found for it.
    """
    first_time: dict[str, Column] = {}
    for col in columns:
        if col.kind == "time":
            first_time.setdefault(col.run, col)
    shared_first = next((t for k, t in first_time.items() if k.lower() in _SHARED_RUNS), None)
    only = next(iter(first_time.values())) if len(first_time) == 1 else None
    last_time: dict[str, Column] = {}
    last_shared: Column | None = None
    groups: dict[str, dict[int, list[Column]]] = {}
    for col in columns:
        if col.kind == "time":
            if col.run.lower() in _SHARED_RUNS:
                last_shared = col
            else:
                last_time[col.run] = col
            continue
        if col.kind in ("datetime", "ignore"):
            continue
        time = _time_of(col, last_time, last_shared, first_time, shared_first, only)
        if time is None:
            if col.kind not in ("force", "accel"):
                continue
            raise LogReadError(
                path,
                f"no time column for run '{col.run or '(unnamed)'}'",
                column=col.raw,
                line=1,
                hint="add a 'Time (s) <run>' column or pass --columns time=...,force=...",
            )
        groups.setdefault(col.run, {}).setdefault(time.index, []).append(col)
    by_index = {c.index: c for c in columns}
    plans: list[RunPlan] = []
    for key, by_time in groups.items():
        name = _run_name(key, groups)
        run_plans = [plan_from_columns(name, by_index[t], cols) for t, cols in by_time.items()]
        plans.extend(_named(join_rates([p for p in run_plans if p.has_signal]), name))
    return plans


def _named(run_plans: list[RunPlan], name: str) -> list[RunPlan]:
    """A run's plans after its first named by what they hold (force, acceleration, k)."""
    for k, plan in enumerate(run_plans[1:], start=2):
        if plan.force is not None and not plan.accel:
            plan.name = f"{name} (force)"
        elif plan.accel and plan.force is None:
            plan.name = f"{name} (acceleration)"
        else:
            plan.name = f"{name} ({k})"
    return run_plans


def _time_of(
    col: Column,
    last_time: dict[str, Column],
    last_shared: Column | None,
    first_time: dict[str, Column],
    shared_first: Column | None,
    only: Column | None,
) -> Column | None:
    """The time column of ``col``: its run's last before it, a shared one before it, its
    run's first, the first shared one, the only one."""
    return (
        last_time.get(col.run) or last_shared or first_time.get(col.run) or shared_first or only
    )


def _run_name(key: str, members: dict[str, dict[int, list[Column]]]) -> str:
    if key and key.lower() != "auto":
        return key
    return "Run 1" if "Run 1" not in members else "Run (unnamed)"
