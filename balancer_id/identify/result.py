"""The result of an identification: it owns its data; rendering lives in ``report``."""

from __future__ import annotations

from dataclasses import dataclass, field

from balancer_id.identify.classic import ClassicResult
from balancer_id.identify.coupling import Coupling
from balancer_id.identify.matching import MatchResult
from balancer_id.jsonsafe import json_ready


@dataclass
class PerTrialFit:
    """The model fitted to one trial alone (``--per-trial``)."""

    index: int
    thrust_N: float
    direction: str
    values: dict[str, float]
    stderr: dict[str, float | None]
    rmse: float

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "index": self.index,
            "thrust_N": self.thrust_N,
            "direction": self.direction,
            "parameters": {
                k: {"value": v, "stderr": self.stderr.get(k)} for k, v in self.values.items()
            },
            "rmse": self.rmse,
        }


@dataclass
class FitResult:
    """Everything ``balancer-id fit`` reports.

    Attributes
    ----------
    match : MatchResult
        The simulation-matching fit over all trials.
    classic : ClassicResult
        The paper's method.
    sources : list of str
        The logs fitted.
    coupling : Coupling or None
        Robot-balancer loop figures when the model has ``servo``.
    per_trial : list of PerTrialFit
        Per-trial refits when asked for.
    warnings : list of str
        What the user should know (fixed parameters, poorly determined ones, ...).
    """

    match: MatchResult
    classic: ClassicResult
    sources: list[str]
    coupling: Coupling | None = None
    per_trial: list[PerTrialFit] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def model(self) -> str:
        """The model's spec."""
        return self.match.model.spec

    @property
    def values(self) -> dict[str, float]:
        """Fitted parameter values by name."""
        return self.match.values()

    @property
    def metrics(self) -> dict[str, float]:
        """CONTRACT.md error figures."""
        return self.match.metrics

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``fit`` JSON object (plus details)."""
        trials = []
        for td, rmse in zip(self.match.data.trials, self.match.trial_rmse, strict=True):
            trials.append(
                {
                    "index": td.index,
                    "thrust_N": td.thrust_N,
                    "direction": td.direction,
                    "rmse": rmse,
                    "source": td.source,
                }
            )
        out: dict[str, object] = {
            "model": self.model,
            "files": self.sources,
            "parameters": {k: p.to_dict() for k, p in self.match.parameters.items()},
            "correlations": self.match.correlations,
            "classic": self.classic.to_dict(),
            "trials": trials,
            "metrics": self.metrics,
            "converged": self.match.success,
            "optimizer_message": self.match.message,
            "warnings": self.warnings + self.match.warnings,
        }
        if self.coupling is not None:
            out["coupling"] = self.coupling.to_dict()
        if self.per_trial:
            out["per_trial"] = [p.to_dict() for p in self.per_trial]
        return json_ready(out)
