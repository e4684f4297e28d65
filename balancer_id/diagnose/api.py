"""Library entry points of ``compare``, ``diagnose`` and ``improve`` (the CLI calls these)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from balancer_id.diagnose.compare import ModelComparison, compare_models
from balancer_id.diagnose.diagnosis import Diagnosis, diagnose_match
from balancer_id.diagnose.improve import ImproveResult, improve_model
from balancer_id.fit.api import fit, resolve_model, trial_data
from balancer_id.model.registry import Registry, default_registry
from balancer_id.pipeline import ReadOptions
from balancer_id.simulate.inputs import Trapezoid

Source = str | Path


def _strs(items: Sequence[object]) -> list[str]:
    return [str(x) for x in items if isinstance(x, str | Path)]


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
    """Fit ``model`` and diagnose its residual (see :func:`diagnose_match`)."""
    registry = registry or default_registry(effects_files)
    result = fit(
        sources, model=model, fixed=fixed, options=options, registry=registry, trajectory=trajectory
    )
    return diagnose_match(
        result.match,
        paths=_strs(sources),
        effects_files=_strs(effects_files),
        with_trajectory=trajectory is not None,
        fixed=dict(fixed or {}),
    )


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
    """Fit the start model and add effects while they help (see :func:`improve_model`)."""
    registry = registry or default_registry(effects_files)
    result = fit(
        sources, model=start, fixed=fixed, options=options, registry=registry, trajectory=trajectory
    )
    return improve_model(
        result.match,
        max_steps=max_steps,
        paths=_strs(sources),
        effects_files=_strs(effects_files),
        with_trajectory=trajectory is not None,
        fixed=dict(fixed or {}),
    )


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
    """Fit every model in ``models`` to the same trials and compare their errors."""
    registry = registry or default_registry(effects_files)
    parsed = [resolve_model(spec, registry=registry) for spec in models]
    trials, _ = trial_data(sources, options, trajectory)
    return compare_models(parsed, trials, fixed)
