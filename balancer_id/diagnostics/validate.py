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

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from balancer_id.diagnostics.adequacy import colour_test, level_test
from balancer_id.diagnostics.context import DiagnosisContext
from balancer_id.jsonsafe import json_ready

__all__ = ["Validation", "judge"]


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
    fit_percent : float
        NRMSE fit (%) of the model on the new trials.
    """

    model: str
    values: dict[str, float]
    holds: bool
    tests: list[dict[str, Any]] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)
    fit_percent: float = float("nan")

    @property
    def verdict(self) -> str:
        """``holds`` or ``does not hold``."""
        return "holds" if self.holds else "does not hold"

    def lines(self) -> list[str]:
        """The verdict and its reasons, one sentence each."""
        head = (
            f"model {self.model} {self.verdict} on these logs "
            f"(fit {self.fit_percent:.1f} %, nothing refitted)"
        )
        if self.holds:
            return [head + ": " + "; ".join(str(t["text"]) for t in self.tests)]
        return [head + ":", *(f"- {r}" for r in self.reasons)]

    def __repr__(self) -> str:
        return "\n".join(self.lines())

    def _repr_html_(self) -> str:
        """The verdict and its tests as text, in a notebook (not a dataclass dump)."""
        import html

        return "<pre>" + html.escape("\n".join(self.lines())) + "</pre>"

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
                "values": self.values,
            }
        )

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Validation:
        """The validation a :meth:`to_dict` object describes (``to_dict`` gives it back).

        Parameters
        ----------
        data : mapping
            A ``validation`` object (``compare --params --json``).

        Returns
        -------
        Validation
        """
        fit = data.get("fit_percent")
        return cls(
            model=str(data["model"]),
            values={k: float(v) for k, v in (data.get("values") or {}).items()},
            holds=bool(data["holds"]),
            tests=[dict(t) for t in data.get("tests") or []],
            reasons=[str(r) for r in data.get("reasons") or []],
            fit_percent=float("nan") if fit is None else float(fit),
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


def judge(
    ctx: DiagnosisContext, thrust_correlation: Mapping[str, Any], values: Mapping[str, float]
) -> Validation:
    """The verdict on a model simulated with every value known (nothing refitted).

    Parameters
    ----------
    ctx : DiagnosisContext
        The simulation on the new trials and its residuals.
    thrust_correlation : mapping
        The residual's cross-correlation with the thrust (already computed for the
        comparison).
    values : mapping of str to float
        The values simulated.

    Returns
    -------
    Validation
    """
    colour = colour_test(ctx)
    tests = [level_test(ctx, colour), colour, _thrust_test(thrust_correlation)]
    reasons = [str(t["text"]) for t in tests if not t["passed"]]
    match = ctx.match
    return Validation(
        model=match.model.spec,
        values=dict(values),
        holds=not reasons,
        tests=[_record(t) for t in tests],
        reasons=reasons,
        fit_percent=float(match.metrics["nrmse_fit_percent"]),
    )
