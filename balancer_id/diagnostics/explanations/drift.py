"""A parameter drifting linearly over the runs: oil warming, wear."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, ClassVar

from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Verdict,
    head,
)
from balancer_id.diagnostics.explanations.run_changes import Change, fit_changes
from balancer_id.diagnostics.explanations.split import REPEAT_FIRST_RUN

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.result import FitResult


class Drift(ExplanationKind):
    """One parameter changes linearly with the run's number (four runs at least).

    Fitted as ``base + c * run / (runs - 1)``; scored with one added parameter. It
    mimics a split near the middle of the session, and another parameter's drift when
    both change the response alike.
    """

    key = "drift"
    kind = "drift"
    verdict = Verdict.PARAMETER_DRIFT
    stands_alone = True
    changes_parameter = True
    tried = "a parameter drifting over the runs"
    mimics: ClassVar[str] = "a change at one run, or another parameter's drift"
    separating_trial: ClassVar[str] = REPEAT_FIRST_RUN

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """Each free parameter drifting over the runs."""
        return fit_changes(inp, lambda c: drift_of(self, c), splits=False)

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """``D0 drifts from 8 in the first run to 5 in the last (oil warming, wear)``."""
        return drift_sentence(e)


def drift_of(
    kind: ExplanationKind, c: Change, prefix: str = "", effects: Sequence[str] = ()
) -> Explanation:
    """The explanation of a drift ``c`` (a pair's when ``prefix`` names its effect).

    Parameters
    ----------
    kind : ExplanationKind
    c : Change
    prefix : str
    effects : sequence of str

    Returns
    -------
    Explanation
    """
    return kind.make(
        f"{prefix}{c.name} drifting over the runs",
        c.delta_bic,
        c.rmse,
        effects=list(effects),
        parameters=[c.name],
        detail={
            "first_run": c.first,
            "last_run": c.second,
            "relative_change": c.relative,
            "drift": True,
        },
        null=c.null,
    )


def drift_sentence(e: Explanation) -> str:
    """The verdict's paragraph of a drift (or a pair with one).

    Parameters
    ----------
    e : Explanation

    Returns
    -------
    str
    """
    d = e.detail
    p = e.parameters[0]
    return (
        f"{p} drifts from {float(d['first_run']):.3g} in the first run to "  # type: ignore[arg-type]
        f"{float(d['last_run']):.3g} in the last (oil warming, wear)"  # type: ignore[arg-type]
        + (f", with {e.effects[0]} added" if e.effects else "")
        + f"; {head(e)}"
    )
