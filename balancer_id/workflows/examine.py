"""Looking at logs as library calls: ``inspect``, ``diagnose`` and ``improve`` of the CLI.

Each function checks what it will write before any work, reads the logs once, and writes
the plots and reports asked for; the command only renders what it returns.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from balancer_id.arguments import at_least, trajectory
from balancer_id.errors import BalancerIdError, NoTrialError, UsageError, error_record
from balancer_id.files import check_outputs, inputs_of
from balancer_id.identify.result import FitResult
from balancer_id.status import tell
from balancer_id.text import one_line
from balancer_id.trials import ReadOptions, describe_log, load_trials, read, segment

__all__ = ["Examined", "diagnose_logs", "fit_for_diagnosis", "improve_logs", "inspect_log"]


@dataclass(frozen=True)
class Examined:
    """What a look at logs found, and the files it wrote.

    Attributes
    ----------
    out : dict
        The command's JSON object.
    written : tuple of Path
        The files written, in order.
    problem : BalancerIdError or None
        Why the look stopped short (``inspect``: no trial found; the log was still shown).
    result : object
        The library's result (a Diagnosis, an ImproveResult), when there is one.
    """

    out: dict[str, Any]
    written: tuple[Path, ...] = ()
    problem: BalancerIdError | None = None
    result: Any = None


def inspect_log(
    log: str | Path,
    options: ReadOptions | None = None,
    *,
    trajectory_text: str | None = None,
    plot: str | Path | None = None,
    overwrite: bool = False,
) -> Examined:
    """What was read from ``log`` and the trials (or the robot's move) found in it.

    Parameters
    ----------
    log : str or Path
        The log.
    options : ReadOptions, optional
        How it is read.
    trajectory_text : str, optional
        The robot's reference move.
    plot : str or Path, optional
        Draw the channels to this PNG.
    overwrite : bool
        Replace ``plot`` when it exists.

    Returns
    -------
    Examined
        ``problem`` is the :class:`~balancer_id.errors.NoTrialError` when no trial was
        found (the log is still described, with its ``error`` record).
    """
    options = options or ReadOptions()
    check_outputs({"--plot": plot}, inputs_of([log], None, trajectory_text), overwrite)
    data = read(log, options)
    problem: NoTrialError | None = None
    try:
        trials = segment(data, options, trajectory(trajectory_text))
    except NoTrialError as exc:
        trials, problem = [], exc
    info = describe_log(data, trials)
    if problem is not None:
        info["error"] = error_record(one_line(problem), problem.exit_code, problem)
    written = []
    if plot is not None:
        from balancer_id.report.inspect_plot import plot_inspection

        plot_inspection(data, trials, plot, g=options.g, vertical=options.vertical)
        written.append(Path(plot))
    return Examined(info, tuple(written), problem)


def fit_for_diagnosis(
    logs: Sequence[str | Path],
    options: ReadOptions | None = None,
    *,
    model: str | None = None,
    fixed: Mapping[str, float] | None = None,
    effects_files: Sequence[str | Path] = (),
    trajectory_text: str | None = None,
) -> FitResult:
    """Load the trials and fit, the kernels of the diagnosis' candidates compiled first.

    The kernels of the model and of the candidates a diagnosis refits are compiled all at
    once (several processes) when the disk cache lacks them.

    Parameters
    ----------
    logs : sequence of str or Path
        The logs.
    options : ReadOptions, optional
        How they are read.
    model : str, optional
        The model (default ``variable_viscosity``).
    fixed : mapping of str to float, optional
        Held values.
    effects_files : sequence of path
        User effect files.
    trajectory_text : str, optional
        The robot's reference move.

    Returns
    -------
    FitResult
    """
    from balancer_id.diagnostics.candidates import candidates
    from balancer_id.identify.api import fit, resolve_model
    from balancer_id.simulation.kernel_compile import compile_models

    trials = load_trials(list(logs), options, trajectory(trajectory_text), trajectory_text)
    start = resolve_model(model, effects_files)
    cands = candidates(start, with_trajectory=trajectory_text is not None)
    compile_models([start, *(c.model for c in cands)])
    tell(f"fitting {model or 'variable_viscosity'}")
    result = fit(trials, model=model, fixed=fixed, effects_files=effects_files)
    assert isinstance(result, FitResult)
    return result


def diagnose_logs(logs: Sequence[str | Path], options: ReadOptions | None = None,
                  **fit_options: Any) -> Examined:
    """Fit the logs and diagnose the fit (residual tests, ranked explanations).

    Parameters
    ----------
    logs : sequence of str or Path
        The logs.
    options : ReadOptions, optional
        How they are read.
    **fit_options
        :func:`fit_for_diagnosis`' options (``model``, ``fixed``...).

    Returns
    -------
    Examined
        ``result`` is the :class:`~balancer_id.diagnostics.diagnosis.Diagnosis`.
    """
    from balancer_id.diagnostics.diagnosis import diagnose

    fitted = fit_for_diagnosis(logs, options, **fit_options)
    tell("diagnosing")
    result = diagnose(fitted)
    return Examined(result.to_dict(), result=result)


def improve_logs(
    logs: Sequence[str | Path],
    options: ReadOptions | None = None,
    *,
    max_steps: int = 4,
    report: str | Path | None = None,
    plot: str | Path | None = None,
    effects_out: str | Path | None = None,
    overwrite: bool = False,
    **fit_options: Any,
) -> Examined:
    """Fit, then add effects one by one while they help; write the ladder and the report.

    Parameters
    ----------
    logs : sequence of str or Path
        The logs.
    options : ReadOptions, optional
        How they are read.
    max_steps : int
        Effects to add at most (>= 0).
    report, plot : str or Path, optional
        The report (HTML/PDF) and the error ladder (PNG).
    effects_out : str or Path, optional
        Discover a missing force in the states and write it here as an effect.
    overwrite : bool
        Replace outputs that exist.
    **fit_options
        :func:`fit_for_diagnosis`' options (``model`` is the start).

    Returns
    -------
    Examined
        ``result`` is the :class:`~balancer_id.diagnostics.improve.ImproveResult`.
    """
    from balancer_id.diagnostics.improve import improve

    at_least(max_steps, 0, "--max-steps")
    ins = inputs_of(logs, fit_options.get("effects_files"), fit_options.get("trajectory_text"))
    check_outputs({"--report": report, "--plot": plot}, ins, overwrite)
    if report is not None:
        from balancer_id.report.document import check_report_path

        check_report_path(report, logs)
    if effects_out is not None:
        from balancer_id.diagnostics.discovery.files import check_effects_out

        check_effects_out(effects_out, inputs=ins, overwrite=overwrite)
    fitted = fit_for_diagnosis(logs, options, **fit_options)
    tell(f"improving {fitted.model}: adding effects (at most {max_steps})")
    result = improve(fitted, max_steps=max_steps, discover_to=effects_out, overwrite=overwrite)
    out: dict[str, Any] = result.to_dict()
    written = []
    if plot is not None:
        from balancer_id.report.plots import plot_error_ladder

        plot_error_ladder(out["steps"], plot)
        written.append(Path(plot))
    if report is not None:
        from balancer_id.report.sections import write_improve_report

        tell(f"writing {report}")
        write_improve_report(result, report)
        written.append(Path(report))
    return Examined(out, tuple(written), result=result)


def check_discover(discover: bool, effects_out: Path | None) -> None:
    """``--discover`` and ``--effects-out FILE.py`` go together.

    Parameters
    ----------
    discover : bool
        ``--discover``.
    effects_out : Path or None
        ``--effects-out``.

    Raises
    ------
    UsageError
        When one is given without the other.
    """
    if discover != (effects_out is not None):
        raise UsageError("--discover and --effects-out FILE.py go together; give both")
