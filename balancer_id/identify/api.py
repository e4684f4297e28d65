"""``balancer_id.identify``: the whole identification, as the ``fit`` command runs it."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from balancer_id.errors import IdentificationError, UsageError
from balancer_id.identify.basins import scaled_starts
from balancer_id.identify.classic import paper_method
from balancer_id.identify.data import TrialData, from_trials
from balancer_id.identify.group_fits import GroupFits
from balancer_id.identify.level_errors import unsteady_zero, widen_by_level_errors
from balancer_id.identify.matching import match_trials
from balancer_id.identify.move_start import refine_move_start
from balancer_id.identify.per_log import PerLogFit
from balancer_id.identify.per_trial import PerTrialFit, fit_each_trial
from balancer_id.identify.reach import settle_unreached
from balancer_id.identify.rest_level import resting_level, resting_offset, sensor_reading
from balancer_id.identify.result import PARAMETER_NOTES, FitResult, fit_match, robot_coupling
from balancer_id.identify.rivals import check_rivals
from balancer_id.identify.starts import fit_start
from balancer_id.identify.structure import structured_residual
from balancer_id.identify.timing import check_timing
from balancer_id.identify.trial_scatter import widen_by_trial_scatter
from balancer_id.model.registry import Registry
from balancer_id.model.spec import Model, resolve_model
from balancer_id.notes import Note
from balancer_id.segment.trial import Trial
from balancer_id.simulation.inputs import Trapezoid
from balancer_id.trials import ReadOptions, TrialSet, as_trial_set

__all__ = [
    "PerTrialFit",
    "fit",
    "fit_each_trial",
    "fit_match",
    "resolve_model",
    "robot_coupling",
    "trial_data",
]

Sources = TrialSet | str | Path | Sequence[str | Path | Trial | TrialData]

#: A profile interval this many times narrower than the Wald one is called out: the
#: Gauss-Newton covariance leaves out the residuals' curvature, which dominates where
#: the model misfits and parameters trade at first order (docs/DECISIONS.md).
NON_QUADRATIC_RATIO = 3.0


def trial_data(trials: TrialSet) -> list[TrialData]:
    """The trials of a set as the fitters see them, renumbered from 0.

    Parameters
    ----------
    trials : TrialSet
        The segmented trials of the logs, then the ready-made ones (segmented
        :class:`Trial` or :class:`TrialData`); the set's reference move is evaluated at
        each trial's sample times.

    Returns
    -------
    list of TrialData
        All trials, their ``index`` renumbered from 0.
    """
    traj = trials.trajectory
    data = from_trials(trials.trials, trajectory=traj)  # chains the trials of a session
    data += from_trials([s for s in trials.loose if isinstance(s, Trial)], trajectory=traj)
    data += [s for s in trials.loose if isinstance(s, TrialData)]
    for k, td in enumerate(data):
        td.index = k
    return data


def from_parameters(
    params: Any, model: Model
) -> tuple[dict[str, float], dict[str, float], dict[str, tuple[float, float]]]:
    """``lmfit.Parameters`` as held values, start values and narrower bounds.

    Parameters
    ----------
    params : lmfit.Parameters
        Any mapping of name to an object with ``value``, ``vary``, ``min`` and ``max``.
    model : Model
        The model they are for.

    Returns
    -------
    (held, start, bounds)

    Raises
    ------
    UsageError
        A name that is not one of the model's parameters, a value that is not finite, or
        an ``expr`` tie (never dropped in silence).
    """
    import math

    held: dict[str, float] = {}
    starts: dict[str, float] = {}
    spans: dict[str, tuple[float, float]] = {}
    for name, p in params.items():
        if name not in model.param_names:
            raise UsageError(
                f"params: {name} is not a parameter of '{model.spec}' "
                f"(its parameters: {', '.join(model.param_names)})"
            )
        expr = getattr(p, "expr", None)
        if expr:  # a tie would be held at its current value in silence: refuse it
            raise UsageError(
                f"params: {name} has expr {expr!r} (a tie to other parameters), which the "
                "fit cannot honour; give it a value with vary=True (fitted) or vary=False "
                "(held), or choose a model without that parameter"
            )
        value = float(p.value)
        if not math.isfinite(value):
            raise UsageError(f"params: {name} = {value}: give a finite value")
        if not p.vary:
            held[name] = value
            continue
        starts[name] = value
        own = model.param(name)
        lo = max(float(p.min), own.min) if math.isfinite(float(p.min)) else own.min
        hi = min(float(p.max), own.max) if math.isfinite(float(p.max)) else own.max
        if (lo, hi) != (own.min, own.max):
            spans[name] = (lo, hi)
    return held, starts, spans


def _held_from_fit(params: FitResult | str | Path, model: Model) -> dict[str, float]:
    """The values of an earlier fit (a result or its JSON file) that ``model`` has."""
    if isinstance(params, FitResult):
        values = {k: float(v) for k, v in params.values.items() if k in model.param_names}
        if not values:
            raise UsageError(
                f"params: the fit of '{params.model}' has none of the parameters of '{model.spec}'"
            )
        return values
    from balancer_id.identify.params_file import held_for_model

    return held_for_model(params, model)


def fit_groups(trials: Sources, by: str, **kwargs: Any) -> GroupFits:
    """Identify each group of trials apart (``fit --group-by``).

    Parameters
    ----------
    trials : TrialSet, str, Path or sequence
        What :func:`fit` takes.
    by : str
        ``run`` (each run), ``log`` (each log) or ``runs:1-3,4-6`` (runs of the logs in
        order, grouped as given).
    **kwargs
        :func:`fit`'s options, the same for every group (``model``, ``fixed``, ...).

    Returns
    -------
    GroupFits
        One :class:`FitResult` per group.

    Raises
    ------
    UsageError
        ``by`` not understood, or an option that follows one fit (``track``,
        ``per_log``, ``posterior``).
    """
    from balancer_id.identify.data import group_trials

    for option in ("track", "per_log", "posterior", "priors"):
        if kwargs.get(option):
            raise UsageError(f"--{option.replace('_', '-')} follows one fit: not with --group-by")
    ts = as_trial_set(trials, kwargs.pop("options", None), kwargs.pop("trajectory", None))
    groups = group_trials(trial_data(ts), by)
    fits = []
    for label, group in groups:
        result = fit(group, **kwargs)
        assert isinstance(result, FitResult)
        fits.append((label, result))
    return GroupFits(by, tuple(fits))


#: Another optimum this many noise variances from the best fits as well at 95 %.
AS_GOOD_SIGMA2 = 4.0
#: A mass within this factor of a bound is pressed against it.
PRESSED = 1.05


def _on_a_bound(mdl, mass) -> bool:
    """Whether a mass (an estimate or a value) lies on m_a's bound or within
    :data:`PRESSED` of it."""
    value = float(getattr(mass, "value", mass))
    lo, hi = mdl.param("m_a").min, mdl.param("m_a").max
    return bool(getattr(mass, "at_bound", None)) or not (PRESSED * lo < value < hi / PRESSED)


def _inside_optimum(mdl, data, match, fixed, max_nfev, bounds):
    """The fit from another optimum about as good whose mass lies inside its bounds, when
    the best ended with m_a on one (else ``match``).

    A step through a drive lag into a viscous mass answers alike with the lag and
    ``m_a / D`` swapped (the mirror); a light cart's mirror ``m_a' = D T_a`` can sit on
    m_a's lower bound (0.2 kg, 0.04 s, 0.25 kg/s: 0.01 kg), and the fit, ending there (or pressed
    against it) as often as in the cart's own valley, said "nothing identified" or gave
    the mirror. The refit keeps the
    other optima and the note that the starts disagree (the trials do not decide).
    """
    for other in match.optima[1:]:
        values = other.values
        if other.delta_sigma2 > AS_GOOD_SIGMA2 or "m_a" not in values:
            continue
        if _on_a_bound(mdl, values["m_a"]):
            continue
        refit = match_trials(
            mdl, data, start={**match.values(), **values}, fixed=fixed, n_starts=1,
            max_nfev=max_nfev, bounds=bounds,
        )  # fmt: skip
        if refit.success and not _on_a_bound(mdl, refit.parameters["m_a"]):
            refit.optima = match.optima
            refit.warnings[:0] = [
                w for w in match.warnings
                if getattr(w, "code", None) in ("fit.starts_disagree", "fit.optima")
            ]  # fmt: skip
            return refit
    return match


def _given_values(
    params: Any,
    mdl: Model,
    fixed: Mapping[str, float] | None,
    start: Mapping[str, float] | None,
    bounds: Mapping[str, tuple[float, float]] | None,
) -> tuple[Any, Any, Any]:
    """``fixed``, ``start`` and ``bounds`` with an earlier fit's or ``lmfit.Parameters``'
    values under them (the explicit ones win)."""
    if isinstance(params, str | Path | FitResult):
        # an earlier fit (its file or the result): its values are held, as the CLI's
        # --params holds them (one meaning, issue 29); --fix (fixed) wins
        fixed = {**_held_from_fit(params, mdl), **(fixed or {})}
    elif params is not None:
        held, starts, spans = from_parameters(params, mdl)
        fixed = {**held, **(fixed or {})}
        start = {**starts, **(start or {})}
        bounds = {**spans, **(bounds or {})}
    return fixed, start, bounds


def _check_followed(
    mdl: Model, track: Sequence[str], per_log: Sequence[str], fixed: Mapping[str, float] | None
) -> None:
    """Refuse ``--track`` with ``--per-log``, and names that are not parameters to follow
    (before any log is read)."""
    if per_log and track:
        raise UsageError("--per-log and --track: give one of them")
    if track:
        from balancer_id.identify.tracking import check_tracked

        check_tracked(mdl, track, dict(fixed or {}))
    for name in per_log:
        if name not in mdl.param_names:
            raise UsageError(
                f"--per-log {name}: not a parameter of '{mdl.spec}' "
                f"(its parameters: {', '.join(mdl.param_names)})"
            )


def _start_values(
    mdl: Model,
    data: list[TrialData],
    classic: Any,
    start: Mapping[str, float] | None,
    bounds: Mapping[str, tuple[float, float]] | None,
) -> tuple[dict[str, float], list[Note | str]]:
    """The fit's start (the scaled defaults, the data's, then the user's) and its notes;
    refuses a start or a bound of a name that is no parameter."""
    user_start = dict(start or {})
    auto_start, start_notes = fit_start(mdl, data, classic)
    for name in [*user_start, *(bounds or {})]:
        if name not in mdl.param_names:
            raise UsageError(
                f"{name} is not a parameter of '{mdl.spec}' "
                f"(its parameters: {', '.join(mdl.param_names)})"
            )
    return {**scaled_starts(mdl, data), **auto_start, **user_start}, [*start_notes]


def _with_move_start(
    mdl: Model,
    ts: TrialSet,
    data: list[TrialData],
    start: Mapping[str, float],
    fixed: Mapping[str, float] | None,
    notes: list[Note | str],
) -> list[TrialData]:
    """The trials with the robot's move start refined by the fit, where the move's start
    was not given (a note says by how much)."""
    if not (mdl.needs_reference_move and ts.trajectory is not None):
        return data
    from balancer_id.segment.move import start_given

    if start_given(ts.trajectory):
        return data
    data, shift = refine_move_start(mdl, data, start, fixed)
    notes.append(
        Note(
            "fit.other",
            f"move start found in the log, refined by the fit ({shift * 1e3:+.0f} ms)",
            severity="info",
        )
    )
    return data


def _settled_match(
    mdl: Model,
    data: list[TrialData],
    start: Mapping[str, float],
    fixed: Mapping[str, float] | None,
    n_starts: int | None,
    seed: int,
    max_nfev: int,
    bounds: Mapping[str, tuple[float, float]] | None,
    ts: TrialSet | None = None,
) -> Any:
    """Match the simulation to the trials; refuse a fit that did not converge or whose
    mass ends on a bound the data did not choose (after looking for an optimum inside),
    naming the sensor's calibration first when the rest says it is off (``ts``); limits
    not reached become bounds."""
    match = match_trials(
        mdl, data, start=start, fixed=fixed, n_starts=n_starts, seed=seed,
        max_nfev=max_nfev, bounds=bounds,
    )  # fmt: skip
    if not match.success:
        raise IdentificationError(
            f"the fit of '{mdl.spec}' did not converge: {match.message} "
            f"(after {match.nfev} evaluations); hold known parameters with --fix NAME=VALUE, "
            "try --starts 4, or check the trials with 'balancer-id inspect --plot'"
        )
    mass = match.parameters.get("m_a")
    if mass is None or not mass.vary or "m_a" in (bounds or {}):
        return settle_unreached(match, bounds or {})[0]  # a limit not reached is a bound
    if _on_a_bound(mdl, mass):
        match = _inside_optimum(mdl, data, match, fixed, max_nfev, bounds)
        mass = match.parameters["m_a"]
    if mass.vary and mass.at_bound:
        offset = resting_offset(match, ts) if ts is not None else None
        if offset is not None:  # the sensor before the balancer (issue 31.4)
            level, _, g = offset
            raise IdentificationError(
                f"nothing identified: {sensor_reading(level, g)}, and the model "
                f"'{mdl.spec}' has no offset to follow it: m_a ended at its "
                f"{mass.at_bound}imum bound ({mass.value:.4g} kg); divide the acceleration "
                f"by {1.0 + level / g:.3f} (or subtract the offset) and refit, or add "
                f"the offset with --model {mdl.spec}+bias"
            )
        raise IdentificationError(
            f"nothing identified: m_a ended at its {mass.at_bound}imum bound "
            f"({mass.value:.4g} kg), a limit the data did not choose; the model '{mdl.spec}' "
            "does not describe these trials (check them with 'balancer-id inspect --plot', "
            "give the stretches where only the measured force acts with --window, or hold "
            "known values with --fix)"
        )
    match, _ = settle_unreached(match, bounds or {})  # a limit not reached is a bound
    return match


def _sensor_checks(match: Any, ts: TrialSet) -> list[Note | str]:
    """The notes of the checks on the sensor, which lead the fit's: an accelerometer that
    does not read g at rest (its gain or zero, :func:`resting_level`)."""
    level = resting_level(match, ts)
    return [level] if level is not None else []


def _fit_checks(match: Any) -> list[Note | str]:
    """The notes of the checks on a settled fit: a misfit beyond the noise seen at rest,
    errors shared by a whole trial, a drive late or early against the acceleration."""
    notes: list[Note | str] = []
    structured = structured_residual(match)
    if structured is not None:
        notes.append(structured)
    zero = unsteady_zero(match)  # a force that moves where its zero is read
    if zero is not None:
        notes.append(zero)
    notes.extend(widen_by_level_errors(match))  # errors in variables, then the scatter
    notes.extend(widen_by_trial_scatter(match))
    notes.extend(check_timing(match))
    return notes


def _profile_notes(match: Any) -> list[Note | str]:
    """Profile-likelihood intervals where Wald's do not hold (issue 11), each with its note."""
    from balancer_id.identify.intervals import (
        CLOSE_TRADE,
        attach_profile_intervals,
        wald_crosses_bound,
    )

    notes: list[Note | str] = []
    for name in attach_profile_intervals(match):
        ci = match.parameters[name].ci95
        if ci is None:
            continue
        lo, hi = ci
        if wald_crosses_bound(match, name):
            note = (
                f"{name}: the Wald 95 % interval crosses the parameter's bounds; "
                f"the profile-likelihood interval {lo:.4g} .. {hi:.4g} is given instead"
            )
        else:
            note = (
                f"{name}: the Wald 95 % interval does not hold where the parameter "
                f"trades with another beyond a correlation of {CLOSE_TRADE}; the "
                f"profile-likelihood interval, each end no narrower than Wald's, "
                f"{lo:.4g} .. {hi:.4g} is given instead"
            )
        wald = match.parameters[name].wald_ci95
        if wald is not None and (hi - lo) < (wald[1] - wald[0]) / NON_QUADRATIC_RATIO:
            note += (
                f" ({(hi - lo) / (wald[1] - wald[0]):.0%} of the Wald width: the cost is "
                "far from quadratic here, as where parameters trade at first order and "
                "the model misfits; its standard error is no uncertainty)"
            )
        notes.append(Note("fit.other", note, subject=name, severity="info"))
    return notes


def _rival_notes(match: Any, notes: Sequence[Note | str], fixed: Any) -> list[Note]:
    """A fit's trusted values checked against rival models that fit as well (issue 31,
    :mod:`~balancer_id.identify.rivals`); not when a note takes every value's trust."""
    for n in [*notes, *match.warnings]:
        if getattr(n, "severity", None) == "error" and n.code not in PARAMETER_NOTES:
            return []
    return check_rivals(match, fixed)


def _posterior(match: Any, priors: Sequence[Any], seed: int) -> Any:
    """The posterior sampled with the given priors (issue 34.2: tens of seconds)."""
    from balancer_id.identify.posterior import Prior, parse_prior, sample_posterior

    given = [p if isinstance(p, Prior) else parse_prior(str(p)) for p in priors]
    return sample_posterior(match, priors=given, seed=seed)


def fit(
    trials: Sources,
    *,
    model: str | Model | None = None,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    registry: Registry | None = None,
    trajectory: Trapezoid | None = None,
    per_trial: bool = False,
    n_starts: int | None = None,
    seed: int = 0,
    max_nfev: int = 2000,
    profile: bool = True,
    start: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    params: Any = None,
    track: Sequence[str] = (),
    per_log: Sequence[str] = (),
    held_out: bool = True,
    posterior: bool = False,
    priors: Sequence[Any] = (),
) -> FitResult | PerLogFit:
    """Identify a balancer from its step trials: the paper's method, then simulation matching.

    Parameters
    ----------
    trials : TrialSet, str, Path or sequence
        A :class:`~balancer_id.trials.TrialSet` from
        :func:`~balancer_id.trials.load_trials`, one log path, or log paths, segmented
        :class:`Trial` objects and :class:`TrialData`, mixed (paths are read first).
    model : str or Model, optional
        Spec (default ``variable_viscosity``).
    fixed : mapping, optional
        Parameters held at known values (nameplate figures).
    options : ReadOptions, optional
        Reading and segmentation options when ``trials`` holds paths.
    effects_files : sequence of path
        User effect files.
    registry : Registry, optional
        A registry to resolve effect names in (tests, plug-ins).
    trajectory : Trapezoid, optional
        The robot's reference move (``servo``) when ``trials`` holds paths.
    per_trial : bool
        Also fit each trial alone, so drift with thrust and direction shows.
    n_starts : int or None
        Optimizer starts (see :func:`~balancer_id.identify.matching.match_trials`);
        None (default): one from the data, plus spread ones where the model has limits,
        friction or delays or the first ends suspect (issue 31).
    seed : int
        Seed of the extra starts.
    max_nfev : int
        Budget of model evaluations per start.
    profile : bool
        For each fitted parameter whose Wald 95 % interval crosses its bounds, compute
        the profile-likelihood interval and report it instead (``ci95_method``).
    start : mapping of str to float, optional
        Start values (``--start``), instead of the paper's method's and the defaults.
    bounds : mapping of str to (float, float), optional
        Narrower bounds of some parameters (``--bounds NAME=MIN:MAX``).
    params : lmfit.Parameters, FitResult, str or Path, optional
        An earlier fit (a :class:`FitResult`, or the file of ``fit --save`` / ``--json``):
        its values of this model's parameters are **held**, as the CLI's ``--params``
        holds them (a balancer identified first, then the robot's servo with it).
        ``lmfit.Parameters``: "Parameters in, Parameters out": each parameter's
        ``value`` is a start (``vary``) or a held value (``vary=False``), and its
        ``min``/``max`` bound the fit where they are narrower than the model's own.
        ``fixed``, ``start`` and ``bounds`` win over it. The result's
        :attr:`~FitResult.params` gives Parameters back.
    track : sequence of str
        Parameters to track in time within the session (``--track``): each as a function
        of time with a 95 % band, in :attr:`FitResult.tracking`
        (:func:`~balancer_id.identify.tracking.track_parameters`).
    per_log : sequence of str
        Parameters each log has its own value of, the rest shared over all logs
        (``--per-log``): one fit over all logs, compared with everything shared and
        nothing shared; returns a :class:`~balancer_id.identify.per_log.PerLogFit`.
    held_out : bool
        With ``per_log``: also score the sharings on held-out halves of logs.
    posterior : bool
        Also sample the posterior of the free parameters with emcee (issue 34.2; tens of
        seconds): credible intervals beside the Wald and profile ones, convergence
        figures, and the response band drawn from the samples.
    priors : sequence of Prior or str
        Normal priors for the posterior (``"m_a=normal:15,1"`` or
        :class:`~balancer_id.identify.posterior.Prior`; giving any implies
        ``posterior``); the others are uniform inside the bounds.

    Returns
    -------
    FitResult or PerLogFit
        A :class:`PerLogFit` when ``per_log`` is given.

    Raises
    ------
    IdentificationError
        No trial, or no convergence (with the optimizer's reason and a hint).
    """
    mdl = resolve_model(model, effects_files, registry)
    fixed, start, bounds = _given_values(params, mdl, fixed, start, bounds)
    track = [track] if isinstance(track, str) else track
    per_log = [per_log] if isinstance(per_log, str) else per_log
    _check_followed(mdl, track, per_log, fixed)
    given = trials.trajectory if isinstance(trials, TrialSet) else trajectory
    mdl.require_reference_move(given)  # before any log is read
    ts = as_trial_set(trials, options, trajectory)
    data = trial_data(ts)
    if not data:
        raise IdentificationError("no step trial found in the given logs; nothing to fit")
    classic = paper_method([t for t in data if t.thrust_N != 0])  # moves: no step
    start, notes = _start_values(mdl, data, classic, start, bounds)
    if per_log:
        from balancer_id.identify.per_log import fit_per_log

        return fit_per_log(mdl, data, per_log, start=start, fixed=fixed, held_out=held_out)
    data = _with_move_start(mdl, ts, data, start, fixed, notes)
    match = _settled_match(mdl, data, start, fixed, n_starts, seed, max_nfev, bounds, ts)
    notes[:0] = _sensor_checks(match, ts)  # the sensor before the balancer: leads
    notes.extend(_fit_checks(match))
    if profile:
        notes.extend(_profile_notes(match))
    notes.extend(_rival_notes(match, notes, fixed))
    tracking = None
    if track:
        from balancer_id.identify.tracking import track_parameters

        tracking = track_parameters(mdl, match.data.trials, track, match.values(), fixed)
    post = None
    if posterior or priors:  # issue 34.2: only on request (tens of seconds)
        post = _posterior(match, priors, seed)
        notes.extend(post.notes)
    return fit_match(
        match, ts, classic=classic, fixed=fixed, effects_files=effects_files,
        warnings=notes, per_trial=per_trial, tracking=tracking, posterior=post,
    )  # fmt: skip
