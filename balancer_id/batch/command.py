"""``balancer-id batch`` as one library call: the batch, its shared fit, its fleet report."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from balancer_id.arguments import trajectory
from balancer_id.batch.rows import BatchResult

__all__ = ["BatchRun", "batch_logs"]


@dataclass(frozen=True)
class BatchRun:
    """A batch run, what it has to say and the fleet report written.

    Attributes
    ----------
    result : BatchResult
        The rows, the summary, the shared fit.
    said : tuple of str
        Lines for the user (the shared fit's verdict and file, the fleet report written).
    """

    result: BatchResult
    said: tuple[str, ...] = ()


def batch_logs(
    paths: Sequence[str | Path],
    out: str | Path,
    *,
    report: str | Path | None = None,
    trajectory_text: str | None = None,
    effects_files: Sequence[str | Path] = (),
    overwrite: bool = False,
    **batch_options: Any,
) -> BatchRun:
    """Check the fleet report's path, run the batch, write the fleet report.

    Parameters
    ----------
    paths : sequence of str or Path
        Logs and folders of logs.
    out : str or Path
        The output folder.
    report : str or Path, optional
        The fleet view of the logs (HTML/PDF).
    trajectory_text : str, optional
        The robot's reference move, the same for every log.
    effects_files : sequence of path
        User effect files.
    overwrite : bool
        Replace earlier results and a report that exists.
    **batch_options
        :func:`~balancer_id.batch.run_batch`'s other options.

    Returns
    -------
    BatchRun
    """
    from balancer_id.batch import run_batch

    if report is not None:
        from balancer_id.files import check_outputs, inputs_of
        from balancer_id.report.document import check_report_path

        check_report_path(report)
        ins = inputs_of(paths, effects_files, trajectory_text)
        check_outputs({"--report": report}, ins, overwrite)
    result = run_batch(paths, out, effects_files=effects_files, overwrite=overwrite,
                       trajectory=trajectory(trajectory_text), **batch_options)
    said = []
    shared = result.shared_fit
    if shared is not None:
        from balancer_id.batch.shared import SHARED_NAME

        verdict = shared.get("error") or f"shared fit: {shared.get('verdict')}"
        said.append(f"{verdict}; wrote {Path(out) / SHARED_NAME}")
    if report is not None:
        from balancer_id.report.fleet import write_fleet_report

        write_fleet_report(result.rows, report, shared)
        said.append(f"wrote {report}")
    return BatchRun(result, tuple(said))
