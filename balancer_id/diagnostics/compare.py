"""``compare``: several models against the same measurements, overall and per trial."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from balancer_id.diagnostics.context import build_context
from balancer_id.diagnostics.residual_tests import input_correlation, whiteness, worst_windows
from balancer_id.diagnostics.validate import Validation, judge
from balancer_id.identify.classic import paper_method
from balancer_id.identify.data import TrialData
from balancer_id.identify.display import Displayable
from balancer_id.identify.matching import MatchResult, evaluate_trials, match_trials
from balancer_id.identify.metrics import error_metrics
from balancer_id.model.spec import Model


@dataclass(repr=False)
class ModelComparison(Displayable):
    """One model's fit and errors."""

    match: MatchResult
    worst: list[dict[str, object]]
    #: Whiteness and cross-correlation with the thrust of the residual (validation).
    residual_tests: dict[str, object] | None = None
    #: With every value known (nothing fitted): does the model hold on these trials?
    validation: Validation | None = None

    def _shown_match(self) -> MatchResult:
        return self.match

    def _headline(self) -> str:
        m = self.match.metrics
        return (
            f"{self.match.model.spec}: RMSE {m['rmse']:.4g} m/s^2, BIC {m['bic']:.1f},"
            f" fit {m['nrmse_fit_percent']:.1f} %"
        )

    def trial_rows(self) -> list[dict[str, object]]:
        """RMSE and NRMSE fit % per trial."""
        rows = []
        for td, sl in zip(self.match.data.trials, self.match.data.slices(), strict=True):
            m = error_metrics(self.match.y[sl], self.match.y_model[sl], 0)
            rows.append(
                {
                    "index": td.index,
                    "thrust_N": td.thrust_N,
                    "direction": td.direction,
                    "rmse": m["rmse"],
                    "nrmse_fit_percent": m["nrmse_fit_percent"],
                }
            )
        return rows

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md ``compare`` model record."""
        return {
            "model": self.match.model.spec,
            "metrics": self.match.metrics,
            "parameters": {k: p.to_dict() for k, p in self.match.parameters.items()},
            "trials": self.trial_rows(),
            "worst": self.worst,
            "fitted": any(p.vary for p in self.match.parameters.values()),
            "residual_tests": self.residual_tests,
        }


def compare_models(
    models: Sequence[Model],
    trials: Sequence[TrialData],
    fixed: Mapping[str, float] | None = None,
) -> list[ModelComparison]:
    """Fit each model to the same trials (started from the paper's method).

    Parameters
    ----------
    models : sequence of Model
        The models to compare.
    trials : sequence of TrialData
        The trials.
    fixed : mapping, optional
        Parameters held in every model that has them.

    Returns
    -------
    list of ModelComparison
        In the order given; a model whose every value is held is simulated, not fitted,
        and carries its :class:`~balancer_id.diagnostics.validate.Validation`.
    """
    classic = paper_method(trials)
    out = []
    for model in models:
        s = classic.start_values(model)
        fx = {k: v for k, v in (fixed or {}).items() if k in model.param_names}
        known = set(model.param_names) <= set(fx)
        if known:  # every value known: validate, no fit
            match = evaluate_trials(model, trials, fx)
        else:
            match = match_trials(model, trials, start=s, fixed=fx)
        ctx = build_context(match)
        thrust = input_correlation(ctx)
        tests = {"whiteness": whiteness(ctx), "input_cross_correlation": thrust}
        verdict = judge(ctx, thrust, fx) if known else None
        out.append(ModelComparison(match, worst_windows(ctx), tests, verdict))
    return out
