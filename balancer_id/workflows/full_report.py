"""The full report as one library call: identify, diagnose, improve, write.

``balancer-id report`` is this function; a notebook or a script calls it the same way::

    import balancer_id as bid
    bid.full_report("sample_logs/paper_balancer.csv", "report.html")
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from balancer_id.diagnostics.diagnosis import Diagnosis, diagnose
from balancer_id.diagnostics.improve import ImproveResult, improve
from balancer_id.files import check_output
from balancer_id.identify.api import fit
from balancer_id.identify.result import FitResult
from balancer_id.report.document import check_report_path
from balancer_id.report.sections import write_full_report
from balancer_id.status import tell
from balancer_id.trials import ReadOptions, TrialSet, as_trial_set

__all__ = ["FullReport", "full_report"]


@dataclass(frozen=True)
class FullReport:
    """What a full report shows, and where it was written."""

    path: Path
    fit: FitResult
    diagnosis: Diagnosis
    improved: ImproveResult


def full_report(
    logs: TrialSet | str | Path | Sequence[str | Path],
    out: str | Path,
    *,
    model: str | None = None,
    fixed: dict[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    trajectory: Any = None,
    overwrite: bool = False,
) -> FullReport:
    """Identify the logs, diagnose the fit, add effects while they help, write the report.

    Parameters
    ----------
    logs : TrialSet, str, Path or sequence
        The logs (or their trials).
    out : str or Path
        ``FILE.html`` or ``FILE.pdf``; written whole or not at all, never over an input.
    model : str, optional
        The model to start from (default ``variable_viscosity``).
    fixed : dict of str to float, optional
        Parameters held at known values.
    options : ReadOptions, optional
        How the logs are read.
    effects_files : sequence of str or Path
        User effect files.
    trajectory : optional
        The robot's reference move (``servo``), as an object or as ``--trajectory`` text.
    overwrite : bool
        Replace ``out`` if it exists (never an input).

    Returns
    -------
    FullReport

    Raises
    ------
    UsageError
        An output that may not be written, or a format not known by its suffix.
    """
    paths = [] if isinstance(logs, TrialSet) else [logs] if isinstance(logs, str | Path) else logs
    inputs = [p for p in paths if isinstance(p, str | Path)] + list(effects_files)
    if isinstance(trajectory, str | Path) and not str(trajectory).startswith("trapezoid"):
        inputs.append(trajectory)  # a time,position file
    check_output(Path(out), inputs=inputs, overwrite=overwrite, option="--out")
    check_report_path(out, [Path(p) for p in inputs])
    trials = as_trial_set(logs, options, trajectory)
    tell("fitting")
    result = fit(trials, model=model, fixed=fixed, effects_files=effects_files, per_trial=True)
    assert isinstance(result, FitResult), "a fit without per_log is one fit"
    tell("diagnosing")
    diagnosis = diagnose(result)
    tell("improving: adding the suggested effects while they help")
    improved = improve(result, diagnosis=diagnosis)
    tell(f"writing {out}")
    written = write_full_report(result, diagnosis, out, improved)
    return FullReport(Path(written), result, diagnosis, improved)
