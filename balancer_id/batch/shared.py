"""A fleet of one balancer type fitted together (``batch --per-log``, issue 33).

After the logs are identified one by one, the logs the fleet view counts (identified,
trusted, no effect missing: :func:`~balancer_id.report.fleet.not_counted`) are fitted
once more, together: the ``per_log`` parameters each log's own, the rest shared over the
fleet (:func:`~balancer_id.identify.per_log.fit_per_log`). The result goes to
``shared_fit.json`` in the output folder and into the fleet report.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from balancer_id.errors import BalancerIdError
from balancer_id.files import atomic_write_text
from balancer_id.report.fleet import not_counted
from balancer_id.trials import ReadOptions

#: The shared fit's file in a batch's output folder.
SHARED_NAME = "shared_fit.json"


def _doc(row: Any) -> dict[str, Any]:
    try:
        doc = json.loads(Path(row.json).read_text(encoding="utf-8")) if row.json else {}
    except (OSError, ValueError):
        return {}
    return doc if isinstance(doc, dict) else {}


def fit_fleet_shared(
    rows: Sequence[Any],
    out_dir: str | Path,
    per_log: Sequence[str],
    *,
    model: str | None = None,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    trajectory: Any = None,
) -> dict[str, Any]:
    """Fit the counted logs of a batch together, ``per_log`` parameters each log's own.

    Parameters
    ----------
    rows : sequence of BatchRow
        The batch's rows (their per-log JSON says which logs are counted).
    out_dir : str or Path
        The batch's output folder: ``shared_fit.json`` is written there.
    per_log : sequence of str
        The parameters each log has its own value of.
    model, fixed, options, effects_files, trajectory
        As the batch was run with.

    Returns
    -------
    dict
        The ``fit --per-log`` JSON object plus ``left_out`` (each log not in the fit and
        why), or ``{"error": ..., "left_out": ...}`` when fewer than two logs are counted
        or the fit fails.
    """
    from balancer_id.identify.api import fit

    counted, left_out = [], []
    for row in rows:
        if not row.ok:
            left_out.append({"file": row.file, "why": "not identified"})
            continue
        why = not_counted(row, _doc(row))
        if why is not None:
            left_out.append({"file": row.file, "why": why})
        else:
            counted.append(row.file)
    if len(counted) < 2:
        doc: dict[str, Any] = {
            "error": f"--per-log: {len(counted)} log(s) counted; a shared fit needs two or more",
            "left_out": left_out,
        }
    else:
        try:
            result = fit(
                counted,
                model=model,
                fixed=fixed,
                options=options,
                effects_files=effects_files,
                trajectory=trajectory,
                per_log=list(per_log),
            )
            doc = {**result.to_dict(), "left_out": left_out}  # type: ignore[union-attr]
        except BalancerIdError as exc:
            doc = {"error": f"--per-log: the shared fit failed: {exc}", "left_out": left_out}
    atomic_write_text(
        Path(out_dir) / SHARED_NAME, json.dumps(doc, indent=2, allow_nan=False, default=str) + "\n"
    )
    return doc
