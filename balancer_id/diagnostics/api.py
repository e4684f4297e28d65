"""Library entry points of ``compare``, ``diagnose`` and ``improve`` (the CLI calls these)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from balancer_id.diagnostics.compare import ModelComparison, compare_models
from balancer_id.diagnostics.diagnosis import Diagnosis, diagnose_match
from balancer_id.diagnostics.improve import ImproveResult, improve_model
from balancer_id.identify.api import fit, resolve_model, trial_data
from balancer_id.identify.result import FitResult
from balancer_id.model.registry import Registry, default_registry
from balancer_id.simulation.inputs import Trapezoid
from balancer_id.trials import ReadOptions

Source = str | Path


def _strs(items: Sequence[object]) -> list[str]:
    return [str(x) for x in items if isinstance(x, str | Path)]


def _fit_with_context(
    sources: Sequence[Source],
    model: str | None,
    fixed: Mapping[str, float] | None,
    options: ReadOptions | None,
    effects_files: Sequence[Source],
    registry: Registry | None,
    trajectory: Trapezoid | None,
    per_trial: bool = False,
) -> tuple[FitResult, dict[str, Any]]:
    """Fit ``model`` and return the keyword arguments the diagnosis of that fit needs."""
    registry = registry or default_registry(effects_files)
    result = fit(
        sources,
        model=model,
        fixed=fixed,
        options=options,
        registry=registry,
        trajectory=trajectory,
        per_trial=per_trial,
    )
    context = {
        "paths": _strs(sources),
        "effects_files": _strs(effects_files),
        "with_trajectory": trajectory is not None,
        "fixed": dict(fixed or {}),
    }
    return result, context


def fit_and_diagnose(
    sources: Sequence[Source],
    *,
    model: str | None = None,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[Source] = (),
    registry: Registry | None = None,
    trajectory: Trapezoid | None = None,
    per_trial: bool = False,
) -> tuple[FitResult, Diagnosis]:
    """Fit ``model`` and diagnose its residual; return both (for reports).

    Parameters
    ----------
    sources : sequence of str or Path
        The logs to fit; their trials are fitted together.
    model : str, optional
        Model spec; None uses the default (``variable_viscosity``).
    fixed : mapping of str to float, optional
        Parameters held at the given values instead of fitted (MODEL.md names, SI units).
    options : ReadOptions, optional
        How the logs are read and segmented; None uses the defaults.
    effects_files : sequence of str or Path
        Python files with user effects to register next to the built-in ones.
    registry : Registry, optional
        The effect registry; None builds the default registry plus ``effects_files``.
    trajectory : Trapezoid, optional
        The robot's reference motion (makes ``servo`` available).
    per_trial : bool
        Also fit each trial alone.

    Returns
    -------
    tuple of (FitResult, Diagnosis)
        The identification and the diagnosis of its residual.
    """
    result, context = _fit_with_context(
        sources, model, fixed, options, effects_files, registry, trajectory, per_trial
    )
    return result, diagnose_match(result.match, **context)


def diagnose(
    sources: Sequence[Source],
    *,
    model: str | None = None,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[Source] = (),
    registry: Registry | None = None,
    trajectory: Trapezoid | None = None,
) -> Diagnosis:
    """Fit ``model`` and diagnose its residual (see :func:`diagnose_match`).

    Parameters
    ----------
    sources : sequence of str or Path
        The logs to fit; their trials are fitted together.
    model : str, optional
        Model spec such as ``"viscous+karnopp"``; None uses the default
        (``variable_viscosity``).
    fixed : mapping of str to float, optional
        Parameters held at the given values instead of fitted (MODEL.md names, SI units).
    options : ReadOptions, optional
        How the logs are read and segmented; None uses the defaults.
    effects_files : sequence of str or Path
        Python files with user effects to register next to the built-in ones.
    registry : Registry, optional
        The effect registry to resolve model specs in; None builds the default registry
        plus ``effects_files``.
    trajectory : Trapezoid, optional
        The robot's reference motion, when a robot held the load; it makes effects with
        an ``operating_force`` hook (``servo``) available.

    Returns
    -------
    Diagnosis
        The fit, its residual tests and the ranked suggestions of missing effects.

    Raises
    ------
    IdentificationError
        When the logs hold no step trial or the fit does not converge.
    """
    return fit_and_diagnose(
        sources,
        model=model,
        fixed=fixed,
        options=options,
        effects_files=effects_files,
        registry=registry,
        trajectory=trajectory,
    )[1]


def improve(
    sources: Sequence[Source],
    *,
    start: str | None = None,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[Source] = (),
    registry: Registry | None = None,
    trajectory: Trapezoid | None = None,
    max_steps: int = 4,
) -> ImproveResult:
    """Fit the start model and add effects while they help (see :func:`improve_model`).

    Parameters
    ----------
    sources : sequence of str or Path
        The logs to fit; their trials are fitted together.
    start : str, optional
        Spec of the model to start from; None uses the default (``variable_viscosity``).
    fixed : mapping of str to float, optional
        Parameters held at the given values instead of fitted (MODEL.md names, SI units).
    options : ReadOptions, optional
        How the logs are read and segmented; None uses the defaults.
    effects_files : sequence of str or Path
        Python files with user effects to register next to the built-in ones.
    registry : Registry, optional
        The effect registry to resolve model specs in; None builds the default registry
        plus ``effects_files``.
    trajectory : Trapezoid, optional
        The robot's reference motion, when a robot held the load; it makes effects with
        an ``operating_force`` hook (``servo``) available.
    max_steps : int
        Effects to add at most.

    Returns
    -------
    ImproveResult
        The ladder of accepted models and the diagnosis of the last one.

    Raises
    ------
    IdentificationError
        When the logs hold no step trial or the fit of the start model does not converge.
    """
    result, context = _fit_with_context(
        sources, start, fixed, options, effects_files, registry, trajectory
    )
    return improve_model(result.match, max_steps=max_steps, **context)


def compare(
    sources: Sequence[Source],
    models: Sequence[str],
    *,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[Source] = (),
    registry: Registry | None = None,
    trajectory: Trapezoid | None = None,
) -> list[ModelComparison]:
    """Fit every model in ``models`` to the same trials and compare their errors.

    Parameters
    ----------
    sources : sequence of str or Path
        The logs to fit; every model sees the same trials.
    models : sequence of str
        Model specs to compare (``"viscous"``, ``"viscous+karnopp"`` ...).
    fixed : mapping of str to float, optional
        Parameters held at the given values instead of fitted (MODEL.md names, SI units).
    options : ReadOptions, optional
        How the logs are read and segmented; None uses the defaults.
    effects_files : sequence of str or Path
        Python files with user effects to register next to the built-in ones.
    registry : Registry, optional
        The effect registry to resolve model specs in; None builds the default registry
        plus ``effects_files``.
    trajectory : Trapezoid, optional
        The robot's reference motion, when a robot held the load; it makes effects with
        an ``operating_force`` hook (``servo``) available.

    Returns
    -------
    list of ModelComparison
        One row per model (see :func:`~balancer_id.diagnostics.compare.compare_models`).

    Raises
    ------
    ModelSpecError
        When a spec names an unknown effect or an invalid combination.
    """
    registry = registry or default_registry(effects_files)
    parsed = [resolve_model(spec, registry=registry) for spec in models]
    trials, _ = trial_data(sources, options, trajectory)
    return compare_models(parsed, trials, fixed)
