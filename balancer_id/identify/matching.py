"""Simulation matching: one bounded least-squares fit of a model over all trials at once."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from balancer_id.errors import IdentificationError
from balancer_id.identify.data import FitData, TrialData, thrust_levels
from balancer_id.identify.display import Displayable
from balancer_id.identify.metrics import error_metrics
from balancer_id.model.spec import Model


@dataclass
class ParameterEstimate:
    """One fitted (or held) parameter."""

    name: str
    value: float
    stderr: float | None
    unit: str
    vary: bool
    at_bound: str | None = None
    #: The profile-likelihood 95 % interval, where the Wald one crosses a bound
    #: (:func:`~balancer_id.identify.intervals.attach_profile_intervals`).
    profile: tuple[float, float] | None = None

    @property
    def wald_ci95(self) -> tuple[float, float] | None:
        """The Wald 95 % confidence interval (value ± 1.96 stderr)."""
        if self.stderr is None or not np.isfinite(self.stderr):
            return None
        return (self.value - 1.96 * self.stderr, self.value + 1.96 * self.stderr)

    @property
    def ci95(self) -> tuple[float, float] | None:
        """The 95 % confidence interval: the profile one when computed, else Wald's."""
        return self.profile if self.profile is not None else self.wald_ci95

    @property
    def ci95_method(self) -> str | None:
        """``"profile"`` or ``"wald"`` (None without an interval)."""
        if self.profile is not None:
            return "profile"
        return "wald" if self.wald_ci95 is not None else None

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "value": self.value,
            "stderr": self.stderr,
            "unit": self.unit,
            "vary": self.vary,
            "ci95": list(self.ci95) if self.ci95 else None,
            "ci95_method": self.ci95_method,
            "at_bound": self.at_bound,
        }


@dataclass(repr=False)
class MatchResult(Displayable):
    """The outcome of :func:`match_trials`."""

    model: Model
    parameters: dict[str, ParameterEstimate]
    correlations: dict[str, dict[str, float]]
    metrics: dict[str, float]
    trial_rmse: list[float]
    y: np.ndarray
    y_model: np.ndarray
    data: FitData
    success: bool
    message: str
    nfev: int
    warnings: list[str] = field(default_factory=list)

    def _shown_match(self) -> MatchResult:
        return self

    def _headline(self) -> str:
        values = ", ".join(f"{k}={p.value:.4g}" for k, p in list(self.parameters.items())[:4])
        fit = self.metrics.get("nrmse_fit_percent", float("nan"))
        return f"{self.model.spec}: {values}; fit {fit:.1f} %"

    def values(self) -> dict[str, float]:
        """Parameter name -> value."""
        return {k: p.value for k, p in self.parameters.items()}

    @property
    def residual(self) -> np.ndarray:
        """Measured minus simulated acceleration over all samples."""
        return self.y - self.y_model


def _residual_function(model: Model, data: FitData):
    y = data.y

    def residual(params) -> np.ndarray:
        vals = params.valuesdict()
        pvec = np.array([vals[n] for n in model.param_names], dtype=float)
        out = data.packed.run(model, pvec)
        r = out[:, 0] - y
        if not np.all(np.isfinite(r)):
            r = np.where(np.isfinite(r), r, 1e3)
        return r

    return residual


def match_trials(
    model: Model,
    trials: Sequence[TrialData],
    *,
    start: Mapping[str, float] | None = None,
    fixed: Mapping[str, float] | None = None,
    n_starts: int = 1,
    seed: int = 0,
    max_nfev: int = 2000,
    diff_step: float | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
) -> MatchResult:
    """Fit every free parameter of ``model`` to all ``trials`` at once.

    Parameters
    ----------
    model : Model
        The model to fit.
    trials : sequence of TrialData
        Step trials (any number of logs).
    start : mapping, optional
        Start values (the paper's method gives ``m_a`` and ``T_a``).
    fixed : mapping, optional
        Parameters held at the given values (``--fix``).
    n_starts : int
        Starts in all; the extra ones are drawn around ``start`` (seeded) and the lowest
        cost wins, for costs with more than one minimum.
    seed : int
        Seed of the extra starts.
    max_nfev : int
        Budget of model evaluations per start.
    diff_step : float, optional
        Relative step of the finite-difference Jacobian, passed to
        :func:`scipy.optimize.least_squares` (the actual step is ``x * diff_step``);
        None uses its default, the square root of the machine epsilon for the two-point
        differences used here.
    bounds : mapping of str to (float, float), optional
        Narrower bounds of some parameters (``--bounds NAME=MIN:MAX``), inside the
        model's own.

    Returns
    -------
    MatchResult

    Raises
    ------
    IdentificationError
        No trial, or the optimizer failed on every start.
    """
    import lmfit

    if not trials:
        raise IdentificationError("no trial to fit; check the log with 'balancer-id inspect'")
    fixed = dict(fixed or {})
    notes: list[str] = []
    levels = thrust_levels(trials)
    for name in model.thrust_level_names:
        if name in model.param_names and name not in fixed and len(levels) < 2:
            value = dict(start or {}).get(name, model.param(name).value)
            fixed[name] = value
            notes.append(
                f"{name} is only identifiable from trials at two or more thrust levels "
                f"(found {len(levels)}: {', '.join(f'{x:g} N' for x in levels)}); held at {value:g}"
            )
    values = dict(start or {})
    values.update(fixed)
    params = model.lmfit_parameters(values, fixed=tuple(fixed))
    for name, (lo, hi) in (bounds or {}).items():
        spec = model.param(name)
        if not (spec.min <= lo < hi <= spec.max):
            raise IdentificationError(
                f"--bounds {name}={lo:g}:{hi:g}: give MIN < MAX inside the parameter's own "
                f"range {spec.min:g}:{spec.max:g}"
            )
        params[name].set(min=lo, max=hi)
        params[name].set(value=float(np.clip(params[name].value, lo, hi)))
    data = FitData.build(trials)
    residual = _residual_function(model, data)

    start_vec = np.array([params[n].value for n in model.param_names], dtype=float)
    if not np.all(np.isfinite(data.packed.run(model, start_vec)[:, 0])):
        raise IdentificationError(
            f"model '{model.spec}' gives a non-finite acceleration at its start values; "
            "check the effects' terms (a user effect returning NaN or inf?)"
        )
    starts = [params]
    rng = np.random.default_rng(seed)
    for _ in range(max(n_starts, 1) - 1):
        p2 = params.copy()
        for p in p2.values():
            if p.vary:
                lo, hi = p.min, p.max
                x = (
                    p.value * float(np.exp(rng.normal(0.0, 0.5)))
                    if p.value != 0
                    else rng.normal(0.0, 0.1)
                )
                p.value = float(np.clip(x, lo, hi))
        starts.append(p2)

    best = None
    for p0 in starts:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                out = lmfit.minimize(
                    residual,
                    p0,
                    method="least_squares",
                    max_nfev=max_nfev,
                    x_scale="jac",
                    diff_step=diff_step,
                )
            except (ValueError, FloatingPointError) as exc:
                notes.append(f"a start failed: {exc}")
                continue
        if best is None or out.chisqr < best.chisqr:
            best = out
    if best is None:
        raise IdentificationError(
            f"fit of '{model.spec}' did not converge from any start; "
            "check the trials with 'balancer-id inspect' or fix known parameters with --fix"
        )
    return _collect(model, best, data, notes)


def evaluate_trials(
    model: Model, trials: Sequence[TrialData], values: Mapping[str, float]
) -> MatchResult:
    """Simulate ``model`` at known ``values`` on ``trials``, without fitting (validation).

    What MATLAB's ``compare(valdata, sys)`` does: a model identified on some logs, run on
    others; its errors (fit %, RMSE) and residual say whether it still holds.

    Parameters
    ----------
    model : Model
        The identified model.
    trials : sequence of TrialData
        New trials.
    values : mapping of str to float
        Every parameter of ``model`` (those missing take their defaults).

    Returns
    -------
    MatchResult
        Every parameter held (``vary`` False, no standard error), one evaluation.

    Raises
    ------
    IdentificationError
        No trial, or the model gives a non-finite acceleration at ``values``.
    """
    from types import SimpleNamespace

    if not trials:
        raise IdentificationError("no trial to simulate; check the log with 'balancer-id inspect'")
    params = model.lmfit_parameters(dict(values), fixed=tuple(model.param_names))
    data = FitData.build(trials)
    residual = _residual_function(model, data)(params)
    if np.any(np.abs(residual) >= 1e3):
        raise IdentificationError(
            f"model '{model.spec}' gives a non-finite acceleration at the given values"
        )
    out = SimpleNamespace(
        residual=residual,
        params=params,
        success=True,
        message="evaluated at the given values (no fit)",
        nfev=1,
    )
    return _collect(model, out, data, [])


def _collect(model: Model, out, data: FitData, notes: list[str]) -> MatchResult:
    y_model = data.y + out.residual
    n_free = sum(1 for p in out.params.values() if p.vary)
    metrics = error_metrics(data.y, y_model, n_free)
    estimates: dict[str, ParameterEstimate] = {}
    correlations: dict[str, dict[str, float]] = {}
    for spec in model.params:
        p = out.params[spec.name]
        at_bound = None
        if p.vary:
            span = spec.max - spec.min
            if p.value <= spec.min + 1e-6 * span:
                at_bound = "min"
            elif p.value >= spec.max - 1e-6 * span:
                at_bound = "max"
        stderr = float(p.stderr) if (p.vary and p.stderr is not None) else None
        estimates[spec.name] = ParameterEstimate(
            spec.name, float(p.value), stderr, spec.unit, bool(p.vary), at_bound
        )
        if p.vary and p.correl:
            correlations[spec.name] = {k: float(v) for k, v in p.correl.items()}
        if at_bound:
            notes.append(
                f"{spec.name} stopped at its {at_bound}imum bound ({p.value:g} {spec.unit}): "
                "the data push it out of range or it is not in the data"
            )
    poorly = [
        e.name
        for e in estimates.values()
        if e.vary
        and e.at_bound is None
        and (e.stderr is None or not np.isfinite(e.stderr) or e.stderr > abs(e.value))
    ]
    if poorly:
        notes.append(
            f"the data cannot determine {', '.join(poorly)} (standard error larger than the value "
            "or undefined); fix them with --fix NAME=VALUE or add trials that excite them"
        )
    strong = sorted(
        {
            tuple(sorted((a, b)))
            for a, row in correlations.items()
            for b, c in row.items()
            if abs(c) > 0.98
        }
    )
    for a, b in strong:
        notes.append(f"{a} and {b} are almost fully correlated ({correlations[a][b]:+.3f})")
    trial_rmse = [float(np.sqrt(np.mean((data.y[s] - y_model[s]) ** 2))) for s in data.slices()]
    return MatchResult(
        model=model,
        parameters=estimates,
        correlations=correlations,
        metrics=metrics,
        trial_rmse=trial_rmse,
        y=data.y,
        y_model=y_model,
        data=data,
        success=bool(out.success),
        message=str(out.message),
        nfev=int(out.nfev),
        warnings=notes,
    )
