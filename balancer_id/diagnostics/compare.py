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
    residual_tests: Mapping[str, object] | None = None
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


class Comparisons(list[ModelComparison]):
    """The models of one comparison, in the order given: a list that a notebook shows as
    one table (model, RMSE, fit %, AIC, BIC, and the verdict of a validated model)."""

    def rows(self) -> list[dict[str, object]]:
        """One row per model: its spec and error metrics."""
        out = []
        for c in self:
            m = c.match.metrics
            out.append(
                {
                    "model": c.match.model.spec,
                    "rmse": m["rmse"],
                    "nrmse_fit_percent": m["nrmse_fit_percent"],
                    "aic": m["aic"],
                    "bic": m["bic"],
                    "verdict": None if c.validation is None else c.validation.verdict,
                }
            )
        return out

    def lines(self) -> list[str]:
        """The table as text, best BIC marked."""
        rows = self.rows()
        best = min(range(len(rows)), key=lambda i: float(rows[i]["bic"]), default=None)  # type: ignore[arg-type]
        out = [f"{'model':<34} {'RMSE (m/s²)':>12} {'fit %':>7} {'BIC':>10}"]
        for i, r in enumerate(rows):
            mark = "  <- lowest BIC" if i == best and len(rows) > 1 else ""
            verdict = f"  ({r['verdict']})" if r["verdict"] else ""
            out.append(
                f"{r['model']:<34} {r['rmse']:>12.4g} {r['nrmse_fit_percent']:>7.2f} "
                f"{r['bic']:>10.1f}{mark}{verdict}"
            )
        return out

    def __repr__(self) -> str:
        return "\n".join(self.lines())

    def _repr_html_(self) -> str:
        import html

        return "<pre>" + html.escape("\n".join(self.lines())) + "</pre>"


def compare_models(
    models: Sequence[Model],
    trials: Sequence[TrialData],
    fixed: Mapping[str, float] | None = None,
) -> Comparisons:
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
    Comparisons
        A list of ModelComparison in the order given; a model whose every value is
        held is simulated, not fitted, and carries its
        :class:`~balancer_id.diagnostics.validate.Validation`.
    """
    classic = paper_method(trials)
    out = Comparisons()
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
