"""Models compared on logs as one library call: ``balancer-id compare`` is this function.

Every model is fitted to the same trials (or, with ``params``, a saved model is checked on
new logs: MATLAB's ``compare``, with a verdict, issue 20.4); with a robot's reference move
the vibration of each move is set side by side (issue 9). The plots and the series are
written here, after every output was checked, before any work.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from balancer_id.arguments import trajectory
from balancer_id.diagnostics.api import compare
from balancer_id.diagnostics.compare import ModelComparison
from balancer_id.diagnostics.vibration import VibrationComparison, compare_vibration
from balancer_id.errors import UsageError
from balancer_id.files import atomic_write_text, check_outputs, inputs_of
from balancer_id.identify.params_file import params_model, read_params_file
from balancer_id.records import ComparisonRecord, ReadsBack
from balancer_id.status import tell
from balancer_id.trials import ReadOptions, load_trials

__all__ = ["DEFAULT_MODELS", "CompareRun", "compare_logs"]

#: The models compared when none are named.
DEFAULT_MODELS = "viscous,variable_viscosity"


@dataclass(frozen=True)
class CompareRun(ReadsBack):
    """Models compared on the same logs, and the files written.

    Attributes
    ----------
    models : tuple of ModelComparison
        One per model, in the order given.
    validation : Validation or None
        The saved model's verdict on these logs (``params``, one model, every value known).
    vibration : VibrationComparison or None
        Each move's vibration (with a reference move).
    written : tuple of Path
        The files written, in order.
    """

    models: tuple[ModelComparison, ...]
    validation: Any = None
    vibration: VibrationComparison | None = None
    written: tuple[Path, ...] = ()
    #: What the JSON reads back as (:meth:`from_dict`; JSON-ready: ``json_ready(to_dict())``).
    record: ClassVar[type[ComparisonRecord]] = ComparisonRecord

    def to_dict(self) -> dict[str, Any]:
        """The ``compare --json`` object."""
        out: dict[str, Any] = {"models": [r.to_dict() for r in self.models]}
        if self.validation is not None:
            out["validation"] = self.validation.to_dict()
        if self.vibration is not None:
            out["vibration"] = self.vibration.to_dict()
        return out


def compare_logs(
    logs: Sequence[str | Path],
    models: str | None = None,
    *,
    fixed: Mapping[str, float] | None = None,
    params: str | Path | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    trajectory_text: str | None = None,
    plot: str | Path | None = None,
    vibration_plot: str | Path | None = None,
    series: str | Path | None = None,
    overwrite: bool = False,
) -> CompareRun:
    """Fit each model to the logs' trials and compare; write the plots and series asked for.

    Parameters
    ----------
    logs : sequence of str or Path
        The logs.
    models : str, optional
        Specs joined by commas (default :data:`DEFAULT_MODELS`, or ``params``' model).
    fixed : mapping of str to float, optional
        Parameters held (``--fix``); they win over ``params``'.
    params : str or Path, optional
        The JSON of ``fit --save``: its values are held (no refit of them).
    options : ReadOptions, optional
        How the logs are read.
    effects_files : sequence of path
        User effect files.
    trajectory_text : str, optional
        The robot's reference move; the moves' vibration is compared too.
    plot, vibration_plot, series : str or Path, optional
        Measured vs simulated (PNG), the moves' vibration (PNG), the series (CSV).
    overwrite : bool
        Replace outputs that exist.

    Returns
    -------
    CompareRun

    Raises
    ------
    UsageError
        No model named, or an output that may not be written (before any work).
    """
    held = dict(fixed or {})
    if params is not None:  # issue 11: an identified model on new logs
        models = params_model(params, models)
        held = {**read_params_file(params), **held}
    text = models or DEFAULT_MODELS
    specs = [m.strip() for m in text.split(",") if m.strip()]
    if not specs:
        raise UsageError(f"--model '{text}': give one or more models, e.g. viscous,karnopp")
    ins = inputs_of(logs, effects_files, trajectory_text) + ([params] if params else [])
    outputs = {"--plot": plot, "--vibration-plot": vibration_plot, "--series": series}
    check_outputs(outputs, ins, overwrite)
    trials = load_trials(logs, options, trajectory(trajectory_text), trajectory_text)
    tell(f"fitting {len(specs)} model(s): {', '.join(specs)}")
    results = tuple(compare(trials, specs, fixed=held, effects_files=effects_files))
    validation = None
    if params is not None and len(results) == 1:
        validation = results[0].validation  # every value known: a verdict (issue 20.4)
    vibration = compare_vibration(trials.trials) if trajectory_text is not None else None
    written = []
    if vibration is not None and vibration_plot is not None:
        from balancer_id.report.vibration_plot import plot_vibration

        plot_vibration(vibration, vibration_plot)
        written.append(Path(vibration_plot))
    if plot is not None:
        from balancer_id.report.sections import plot_comparison

        plot_comparison(results, plot)
        written.append(Path(plot))
    if series is not None:
        import pandas as pd

        frames = [r.to_frame().assign(model=r.match.model.spec) for r in results]
        atomic_write_text(series, pd.concat(frames, ignore_index=True).to_csv(index=False))
        written.append(Path(series))
    return CompareRun(results, validation, vibration, tuple(written))
