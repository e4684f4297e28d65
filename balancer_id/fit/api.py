"""``balancer_id.fit``: the whole identification, as the ``fit`` command runs it."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from balancer_id.errors import IdentificationError
from balancer_id.fit.classic import paper_method
from balancer_id.fit.coupling import coupling_of
from balancer_id.fit.data import TrialData, from_trials
from balancer_id.fit.matching import match_trials
from balancer_id.fit.move_start import refine_move_start
from balancer_id.fit.result import FitResult, PerTrialFit
from balancer_id.model.registry import Registry, default_registry
from balancer_id.model.spec import DEFAULT_SPEC, Model, parse_model
from balancer_id.pipeline import ReadOptions, load_trials
from balancer_id.segment.move import start_given
from balancer_id.segment.trial import Trial
from balancer_id.simulate.inputs import Trapezoid


def resolve_model(
    model: str | Model | None,
    effects_files: Sequence[str | Path] = (),
    registry: Registry | None = None,
) -> Model:
    """A Model from a spec string (loading user effect files) or a ready Model.

    Parameters
    ----------
    model : str or Model or None
        A spec such as ``"viscous+karnopp"``, a ready Model (returned as is), or None for
        the default spec (``variable_viscosity``).
    effects_files : sequence of str or Path
        Python files with user effects; only read when ``registry`` is None.
    registry : Registry, optional
        The registry to resolve effect names in; None builds the default registry plus
        ``effects_files``.

    Returns
    -------
    Model

    Raises
    ------
    ModelSpecError
        When the spec names an unknown effect or an invalid combination.
    """
    if isinstance(model, Model):
        return model
    registry = registry or default_registry(effects_files)
    return parse_model(model or DEFAULT_SPEC, registry)


def trial_data(
    sources: Sequence[str | Path | Trial | TrialData],
    options: ReadOptions | None = None,
    trajectory: Trapezoid | None = None,
) -> tuple[list[TrialData], list[str]]:
    """Turn log paths, segmented trials or ready TrialData into TrialData (renumbered).

    Parameters
    ----------
    sources : sequence of str, Path, Trial or TrialData
        Log paths (read and segmented, in order), segmented trials and ready TrialData,
        mixed freely. The trials of the logs come first, then the others in order.
    options : ReadOptions, optional
        How the logs are read and segmented; None uses the defaults.
    trajectory : Trapezoid, optional
        The robot's reference move, evaluated at each trial's sample times (``servo``).

    Returns
    -------
    trials : list of TrialData
        All trials, their ``index`` renumbered from 0.
    names : list of str
        The paths of the logs read.
    """
    paths = [s for s in sources if isinstance(s, str | Path)]
    data: list[TrialData] = []
    names: list[str] = []
    if paths:
        for item in load_trials(paths, options, trajectory):
            names.append(str(item.log.path))
            data.extend(from_trials(item.trials, trajectory=trajectory))
    given = [s for s in sources if isinstance(s, Trial)]
    data.extend(from_trials(given, trajectory=trajectory))
    data.extend(s for s in sources if isinstance(s, TrialData))
    for k, td in enumerate(data):
        td.index = k
    return data, names


def fit(
    sources: Sequence[str | Path | Trial | TrialData],
    *,
    model: str | Model | None = None,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    registry: Registry | None = None,
    trajectory: Trapezoid | None = None,
    per_trial: bool = False,
    n_starts: int = 1,
    seed: int = 0,
    max_nfev: int = 2000,
) -> FitResult:
    """Identify a balancer from its step trials: the paper's method, then simulation matching.

    Parameters
    ----------
    sources : sequence
        Log paths, segmented :class:`Trial` objects or :class:`TrialData`.
    model : str or Model, optional
        Spec (default ``variable_viscosity``).
    fixed : mapping, optional
        Parameters held at known values (nameplate figures).
    options : ReadOptions, optional
        Reading and segmentation options (column map, thrusts, force sign, ...).
    effects_files : sequence of path
        User effect files.
    registry : Registry, optional
        A registry to resolve effect names in (tests, plug-ins).
    trajectory : Trapezoid, optional
        The robot's reference move (``servo``).
    per_trial : bool
        Also fit each trial alone, so drift with thrust and direction shows.
    n_starts : int
        Optimizer starts (see :func:`~balancer_id.fit.matching.match_trials`).
    seed : int
        Seed of the extra starts.
    max_nfev : int
        Budget of model evaluations per start.

    Returns
    -------
    FitResult

    Raises
    ------
    IdentificationError
        No trial, or no convergence (with the optimizer's reason and a hint).
    """
    mdl = resolve_model(model, effects_files, registry)
    if mdl.has("servo") and trajectory is None:
        raise IdentificationError(
            "a model with 'servo' needs the robot's reference move: give --trajectory "
            "'trapezoid:distance=...,speed=...,accel=...' or a CSV of time,position"
        )
    trials, names = trial_data(sources, options, trajectory)
    if not trials:
        raise IdentificationError("no step trial found in the given logs; nothing to fit")
    classic = paper_method([t for t in trials if t.thrust_N != 0])  # moves: no step
    start: dict[str, float] = {}
    for name in ("m_a", "T_a"):
        value = getattr(classic, name)
        spec_param = mdl.param(name) if name in mdl.param_names else None
        if spec_param is not None and value == value and spec_param.min < value < spec_param.max:
            start[name] = float(value)
    notes = []
    if mdl.has("servo") and trajectory and not start_given(trajectory):  # issue 9: by fit
        trials, shift = refine_move_start(mdl, trials, start, fixed)
        notes.append(f"move start found in the log, refined by the fit ({shift * 1e3:+.0f} ms)")
    match = match_trials(
        mdl, trials, start=start, fixed=fixed, n_starts=n_starts, seed=seed, max_nfev=max_nfev
    )
    if not match.success:
        raise IdentificationError(
            f"the fit of '{mdl.spec}' did not converge: {match.message} "
            f"(after {match.nfev} evaluations); hold known parameters with --fix NAME=VALUE, "
            "try --starts 4, or check the trials with 'balancer-id inspect --plot'"
        )
    result = FitResult(match=match, classic=classic, sources=names, warnings=notes)
    if mdl.has("servo"):
        result.coupling = coupling_of(match.values())
    if per_trial:
        result.per_trial = fit_each_trial(mdl, trials, match.values(), fixed)
    return result


def fit_each_trial(
    model: Model,
    trials: Sequence[TrialData],
    start: Mapping[str, float],
    fixed: Mapping[str, float] | None = None,
) -> list[PerTrialFit]:
    """Fit ``model`` to each trial alone, starting from the joint fit.

    Parameters
    ----------
    model : Model
        The model to fit.
    trials : sequence of TrialData
        The trials; each is fitted on its own.
    start : mapping of str to float
        Start values of every fit (the joint fit's values).
    fixed : mapping of str to float, optional
        Parameters held at these values.

    Returns
    -------
    list of PerTrialFit
        One per trial whose fit succeeded; a trial that cannot be fitted is left out.
    """
    out = []
    for td in trials:
        try:
            m = match_trials(model, [td], start=start, fixed=fixed)
        except IdentificationError:
            continue
        out.append(
            PerTrialFit(
                index=td.index,
                thrust_N=td.thrust_N,
                direction=td.direction,
                values=m.values(),
                stderr={k: p.stderr for k, p in m.parameters.items()},
                rmse=m.metrics["rmse"],
            )
        )
    return out
