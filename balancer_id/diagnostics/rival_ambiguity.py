"""An adequate residual is no verdict when a rival model fits as well (issue 31).

The fit checks its trusted values against rival models, each with one library effect
more (:mod:`balancer_id.identify.rivals`). A rival that fits as well as the fit and moves
a value beyond its interval leaves the residual as white as the noise: the arena's
explanations gain too little BIC to stand (a friction below the noise mimicked by the
variable viscosity), and the diagnosis would say ``adequate`` of a fit whose ``D0`` depends
on whether a friction is present. The verdict is then ``ambiguous`` between the model as
fitted and its rival, with the step trial that tells them apart.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from balancer_id.notes import Note
from balancer_id.verdicts import Verdict

if TYPE_CHECKING:
    from balancer_id.diagnostics.verdict import Judgement
    from balancer_id.identify.result import FitResult

__all__ = ["ambiguous_by_rival"]


def ambiguous_by_rival(judgement: Judgement, fit: FitResult) -> None:
    """Make an ``adequate`` judgement ``ambiguous`` when the fit has a rival.

    Parameters
    ----------
    judgement : Judgement
        The verdict so far (changed in place).
    fit : FitResult
        The fit diagnosed; its ``match.rivals`` (best supported first).
    """
    rivals = list(getattr(fit.match, "rivals", ()) or ())
    if judgement.verdict != Verdict.ADEQUATE or not rivals:
        return
    rival = rivals[0]
    spec = fit.match.model.spec
    moved = "; ".join(f"{k} {lo:.4g} .. {hi:.4g}" for k, (lo, hi) in rival.ranges.items())
    record = rival.record or "record more thrust levels in both directions"
    ahead = rival.delta_bic < 0
    judgement.ambiguity = {
        "best": rival.label if ahead else spec,
        "runner_up": spec if ahead else rival.label,
        "delta_bic": [abs(rival.delta_bic), 0.0] if ahead else [0.0, -rival.delta_bic],
        "confounded_by": None,
        "record": record,
    }
    text = (
        f"{spec} as fitted and {rival.label} ({rival.summary}) explain the log alike "
        f"(BIC {rival.delta_bic:+.1f} on independent samples) and give {moved}: {record}"
    )
    judgement.notes.append(Note("diagnose.ambiguous", text, None, "warning"))
    judgement.verdict = Verdict.AMBIGUOUS
    judgement.summary = f"{text}. Otherwise: {judgement.summary}"
