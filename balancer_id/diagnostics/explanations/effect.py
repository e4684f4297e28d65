"""A library effect added: each candidate's refit (from ``diagnose``'s suggestions)."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Verdict,
    head,
)

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.result import FitResult


class LibraryEffect(ExplanationKind):
    """A library effect the model lacks (``+karnopp``), refitted with the whole model.

    Proposed: every candidate of :func:`~balancer_id.diagnostics.candidates.candidates`
    (refitted by ``diagnose`` for its suggestions); scored by the arena's criterion on
    the refit's residual. It mimics a parameter changing between runs when the recording
    orders the runs by direction or thrust level.
    """

    key = "effect"
    kind = "effect"
    verdict = Verdict.EFFECT_MISSING
    tried = "library effects"
    mimics: ClassVar[str] = "a parameter changing between runs (when the runs' order follows it)"
    separating_trial: ClassVar[str] = "record more thrust levels in both directions"

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """The library candidates' refits as explanations.

        Parameters
        ----------
        inp : ArenaInput
            Its ``effect_fits`` are the refits.

        Returns
        -------
        list of Explanation
        """
        out = []
        _, _, k0 = arena.current(inp)
        se_zero = arena.zero_stderr(inp.match)
        for name, refit in inp.effect_fits:
            r = refit.residual
            k = len([n for n in refit.model.param_names if n not in arena.held(refit)])
            d, rmse = arena.score(inp, [r[sl] for sl in refit.data.slices()], k - k0)
            out.append(
                self.make(
                    f"+{name}",
                    d,
                    rmse,
                    effects=[name],
                    detail={"values": refit.values()},
                    null=arena.is_null(refit, name)
                    or arena.within_sensor_zero(refit, name, se_zero),
                )
            )
        return out

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """``adding <effect>: ... Fit it: <command>``."""
        return f"adding {e.effects[0]}: {head(e)}. Fit it: {fit.command(model_for(fit, e))}"


def model_for(fit: FitResult, e: Explanation) -> str:
    """The model spec of ``fit`` with the effects ``e`` adds.

    Parameters
    ----------
    fit : FitResult
    e : Explanation

    Returns
    -------
    str
    """
    v = e.detail.get("values")
    spec = fit.model
    return f"{spec}+{e.effects[0]}" if e.effects and v is not None else spec
