"""Does an identified model hold on new logs? (MATLAB's ``compare`` with a verdict.)

An identified model (a saved fit, its values) is simulated, without refitting, on the
trials of logs it was not fitted to. It *holds* when the new logs leave nothing it does
not explain, judged by the tests an "adequate" diagnosis must pass
(:mod:`~balancer_id.diagnostics.adequacy`), plus the residual's correlation with the
thrust:

- *level*: the error above the new logs' own noise floor (measured at rest) is within
  what the floor's uncertainty allows;
- *whiteness*: the residual is no more coloured than the resting noise;
- *thrust correlation*: the residual does not follow the thrust (a gain or a lag that
  changed) beyond its confidence band.

Otherwise it does not hold, and the reasons say which test failed and by how much.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from balancer_id.diagnostics.adequacy import colour_test, level_test
from balancer_id.diagnostics.compare import ModelComparison, compare_models
from balancer_id.diagnostics.context import build_context
from balancer_id.diagnostics.residual_tests import input_correlation
from balancer_id.errors import UsageError
from balancer_id.identify.api import resolve_model, trial_data
from balancer_id.identify.params_file import read_params_file
from balancer_id.identify.result import FitResult
from balancer_id.jsonsafe import json_ready
from balancer_id.trials import ReadOptions, TrialSet, as_trial_set

__all__ = ["Validation", "validate"]


@dataclass(frozen=True)
class Validation:
    """Whether an identified model explains new logs, and why (not).

    Attributes
    ----------
    model : str
        The model's spec.
    values : dict of str to float
        The values simulated (nothing is refitted).
    holds : bool
        Every test passed.
    tests : list of dict
        ``level``, ``whiteness`` and ``thrust_correlation`` records, each ``{name,
        passed, value, limit, text}``.
    reasons : list of str
        The failed tests' texts (empty when it holds).
    comparison : ModelComparison
        The simulation on the new trials (errors per trial, worst windows).
    """

    model: str
    values: dict[str, float]
    holds: bool
    tests: list[dict[str, Any]] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)
    comparison: ModelComparison | None = None

    @property
    def verdict(self) -> str:
        """``holds`` or ``does not hold``."""
        return "holds" if self.holds else "does not hold"

    @property
    def fit_percent(self) -> float:
        """NRMSE fit (%) of the model on the new trials."""
        if self.comparison is None:
            return float("nan")
        return float(self.comparison.match.metrics["nrmse_fit_percent"])

    def lines(self) -> list[str]:
        """The verdict and its reasons, one sentence each."""
        head = (
            f"model {self.model} {self.verdict} on these logs "
            f"(fit {self.fit_percent:.1f} %, nothing refitted)"
        )
        if self.holds:
            return [head + ": " + "; ".join(str(t["text"]) for t in self.tests)]
        return [head + ":", *(f"- {r}" for r in self.reasons)]

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md ``compare --params`` ``validation`` object."""
        return json_ready(
            {
                "model": self.model,
                "verdict": self.verdict,
                "holds": self.holds,
                "fit_percent": self.fit_percent,
                "tests": self.tests,
                "reasons": self.reasons,
            }
        )


def _record(test: Mapping[str, Any]) -> dict[str, Any]:
    """A test as ``{name, passed, value, limit, text}`` (whiteness: the mean excess)."""
    value = test.get("value", test.get("mean_acf_excess"))
    return {
        "name": test["name"],
        "passed": bool(test["passed"]),
        "value": value,
        "limit": test.get("limit"),
        "text": test["text"],
    }


def _thrust_test(record: Mapping[str, Any]) -> dict[str, Any]:
    """The residual-thrust cross-correlation as a pass/fail record."""
    peak = float(record.get("peak_value") or 0.0)
    band = float(record.get("band") or 0.0)
    lag = float(record.get("peak_lag_s") or 0.0)
    significant = bool(record.get("significant"))
    return {
        "name": "thrust_correlation",
        "passed": not significant,
        "value": abs(peak),
        "limit": band,
        "text": (
            f"the residual's correlation with the thrust peaks at {peak:+.2f} at lag "
            f"{lag:.2f} s (band +-{band:.2f})"
        ),
    }


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
    trials: TrialSet | str | Path | Sequence[object],
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
    ctx = build_context(comparison.match)
    colour = colour_test(ctx)
    tests = [level_test(ctx, colour), colour, _thrust_test(input_correlation(ctx))]
    reasons = [str(t["text"]) for t in tests if not t["passed"]]
    return Validation(
        model=spec,
        values=held,
        holds=not reasons,
        tests=[_record(t) for t in tests],
        reasons=reasons,
        comparison=comparison,
    )
