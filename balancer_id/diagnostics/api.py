"""Library entry points of ``compare``, ``validate``, ``diagnose`` and ``improve``.

``diagnose`` and ``improve`` take a :class:`~balancer_id.identify.result.FitResult` and
reuse what it computed (trials, paper's method, per-trial fits). For convenience they
also take what :func:`~balancer_id.identify.api.fit` takes (paths, a TrialSet) and fit
first.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from balancer_id.diagnostics.compare import Comparisons, compare_models
from balancer_id.diagnostics.diagnosis import Diagnosis
from balancer_id.diagnostics.diagnosis import diagnose as diagnose_fit
from balancer_id.diagnostics.improve import ImproveResult
from balancer_id.diagnostics.improve import improve as improve_fit
from balancer_id.diagnostics.validate import Validation
from balancer_id.errors import UsageError
from balancer_id.identify.api import Sources, fit, resolve_model, trial_data
from balancer_id.identify.params_file import read_params_file
from balancer_id.identify.result import FitResult
from balancer_id.model.registry import Registry, default_registry
from balancer_id.simulation.inputs import Trapezoid
from balancer_id.trials import ReadOptions, as_trial_set


def _fitted(
    source: FitResult | Sources, model: str | None, fit_options: dict[str, Any]
) -> FitResult:
    if isinstance(source, FitResult):
        if model is not None or any(v not in (None, (), {}) for v in fit_options.values()):
            raise UsageError(
                "a FitResult carries its model, options and trials; give fit options to fit()"
            )
        return source
    result = fit(source, model=model, **fit_options)
    assert isinstance(result, FitResult), "a fit without per_log is one fit"
    return result


def diagnose(
    source: FitResult | Sources,
    *,
    model: str | None = None,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    registry: Registry | None = None,
    trajectory: Trapezoid | None = None,
) -> Diagnosis:
    """Diagnose a fit's residual (see :func:`~balancer_id.diagnostics.diagnosis.diagnose`).

    Parameters
    ----------
    source : FitResult, TrialSet, str, Path or sequence
        A fit to diagnose, or what :func:`~balancer_id.identify.api.fit` takes (the
        logs are then fitted first with the options below).
    model : str, optional
        Model spec when fitting; None uses the default (``variable_viscosity``).
    fixed : mapping of str to float, optional
        Parameters held at the given values when fitting (MODEL.md names, SI units).
    options : ReadOptions, optional
        How the logs are read and segmented when fitting.
    effects_files : sequence of str or Path
        Python files with user effects when fitting.
    registry : Registry, optional
        The effect registry when fitting; None builds the default plus ``effects_files``.
    trajectory : Trapezoid, optional
        The robot's reference motion when fitting (makes ``servo`` available).

    Returns
    -------
    Diagnosis
        The fit, its residual tests and the ranked suggestions of missing effects.

    Raises
    ------
    IdentificationError
        When the logs hold no step trial or the fit does not converge.
    UsageError
        Fit options given with a ready FitResult.
    """
    kw = {
        "fixed": fixed,
        "options": options,
        "effects_files": effects_files,
        "registry": registry,
        "trajectory": trajectory,
    }
    return diagnose_fit(_fitted(source, model, kw))


def improve(
    source: FitResult | Sources,
    *,
    start: str | None = None,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    registry: Registry | None = None,
    trajectory: Trapezoid | None = None,
    max_steps: int = 4,
    diagnosis: Diagnosis | None = None,
    discover_to: str | Path | None = None,
    overwrite: bool = False,
) -> ImproveResult:
    """Add effects to a fit while they help (see :func:`~balancer_id.diagnostics.improve.improve`).

    Parameters
    ----------
    source : FitResult, TrialSet, str, Path or sequence
        The fit to start from, or what :func:`~balancer_id.identify.api.fit` takes (the
        start model is then fitted first).
    start : str, optional
        Spec of the model to start from when fitting; None uses the default.
    fixed : mapping of str to float, optional
        Parameters held at the given values when fitting (MODEL.md names, SI units).
    options : ReadOptions, optional
        How the logs are read and segmented when fitting.
    effects_files : sequence of str or Path
        Python files with user effects when fitting.
    registry : Registry, optional
        The effect registry when fitting; None builds the default plus ``effects_files``.
    trajectory : Trapezoid, optional
        The robot's reference motion when fitting (makes ``servo`` available).
    max_steps : int
        Effects to add at most.
    diagnosis : Diagnosis, optional
        The diagnosis of a given FitResult, when already made (not made again).
    discover_to : str or Path, optional
        ``improve --discover --effects-out FILE.py``: when, after the library's effects, a
        force is still missing, discover it, write it to this file as a user effect, add
        it and refit.
    overwrite : bool
        Replace ``discover_to`` when an earlier discovery wrote it (a file of yours never).

    Returns
    -------
    ImproveResult
        The ladder of accepted models and the diagnosis of the last one.

    Raises
    ------
    IdentificationError
        When the logs hold no step trial or the fit of the start model does not converge.
    UsageError
        Fit options given with a ready FitResult.
    """
    kw = {
        "fixed": fixed,
        "options": options,
        "effects_files": effects_files,
        "registry": registry,
        "trajectory": trajectory,
    }
    return improve_fit(
        _fitted(source, start, kw),
        max_steps=max_steps,
        diagnosis=diagnosis,
        discover_to=discover_to,
        overwrite=overwrite,
    )


def compare(
    trials: Sources,
    models: Sequence[str],
    *,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    registry: Registry | None = None,
    trajectory: Trapezoid | None = None,
) -> Comparisons:
    """Fit every model in ``models`` to the same trials and compare their errors.

    Parameters
    ----------
    trials : TrialSet, str, Path or sequence
        The trials (or logs) to fit; every model sees the same trials.
    models : sequence of str
        Model specs to compare (``"viscous"``, ``"viscous+karnopp"`` ...).
    fixed : mapping of str to float, optional
        Parameters held at the given values instead of fitted (MODEL.md names, SI units).
    options : ReadOptions, optional
        How logs are read and segmented when ``trials`` holds paths.
    effects_files : sequence of str or Path
        Python files with user effects to register next to the built-in ones.
    registry : Registry, optional
        The effect registry to resolve model specs in; None builds the default registry
        plus ``effects_files``.
    trajectory : Trapezoid, optional
        The robot's reference motion when ``trials`` holds paths (``servo``).

    Returns
    -------
    Comparisons
        A list of one ModelComparison per model, shown in a notebook as one table (see
        :func:`~balancer_id.diagnostics.compare.compare_models`).

    Raises
    ------
    ModelSpecError
        When a spec names an unknown effect or an invalid combination.
    """
    if isinstance(models, str):
        models = [models]
    registry = registry or default_registry(effects_files)
    parsed = [resolve_model(spec, registry=registry) for spec in models]
    data = trial_data(as_trial_set(trials, options, trajectory))
    return compare_models(parsed, data, fixed)


def held_values(
    params: FitResult | Mapping[str, float] | str | Path, model: str | None
) -> tuple[str, dict[str, float]]:
    """The model spec and values of an identified model.

    Parameters
    ----------
    params : FitResult, mapping of str to float, str or Path
        A fit, its values, or a file written by ``fit --json`` / ``fit --save``.
    model : str or None
        The model's spec; None takes the fit's or the file's.

    Returns
    -------
    (str, dict of str to float)

    Raises
    ------
    UsageError
        No model given or found, or values that are not a model's.
    """
    if isinstance(params, FitResult):
        return model or params.model, dict(params.values)
    if isinstance(params, str | Path):
        values = read_params_file(params)
        if model is None:
            try:
                data = json.loads(Path(params).read_text(encoding="utf-8"))
            except (OSError, ValueError):
                data = None
            spec = data.get("model") if isinstance(data, dict) else None
            model = spec if isinstance(spec, str) else None
        if model is None:
            raise UsageError(f"--params {params}: the file names no model; give --model")
        return model, values
    if model is None:
        raise UsageError("validate: give the model's spec with values given as a mapping")
    return model, {str(k): float(v) for k, v in params.items()}


def validate(
    params: FitResult | Mapping[str, float] | str | Path,
    trials: Sources,
    *,
    model: str | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    trajectory: Any = None,
) -> Validation:
    """Simulate an identified model on new logs and say whether it holds.

    Parameters
    ----------
    params : FitResult, mapping of str to float, str or Path
        The identified model: a fit, its values (with ``model``), or a ``fit --json`` file.
    trials : TrialSet, str, Path or sequence
        The new logs (or their trials).
    model : str, optional
        The model's spec (default: the fit's or the file's).
    options : ReadOptions, optional
        How the logs are read.
    effects_files : sequence of str or Path
        User effect files the model needs.
    trajectory : optional
        The robot's reference move for ``servo`` models (text as for ``--trajectory``).

    Returns
    -------
    Validation

    Raises
    ------
    UsageError
        A value the model lacks (then the model is refitted, not validated: use
        :func:`~balancer_id.diagnostics.api.compare`).
    """
    spec, values = held_values(params, model)
    mdl = resolve_model(spec, effects_files)
    missing = [n for n in mdl.param_names if n not in values]
    if missing:
        raise UsageError(
            f"cannot validate {spec}: no value for {', '.join(missing)}; give a fit of this "
            "model (its --json), or compare to refit"
        )
    held = {n: float(values[n]) for n in mdl.param_names}
    data = trial_data(as_trial_set(trials, options, trajectory))
    (comparison,) = compare_models([mdl], data, held)
    assert comparison.validation is not None  # every value held: simulated and judged
    return comparison.validation
