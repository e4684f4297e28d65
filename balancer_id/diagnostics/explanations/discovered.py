"""A force found in the states: the residual as a sparse sum of candidate terms."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Stage,
    Verdict,
)
from balancer_id.status import step

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.result import FitResult


class Discovered(ExplanationKind):
    """A missing force outside the library, found by sparse regression
    (:func:`~balancer_id.diagnostics.discover.discover`).

    Proposed last, on a trusted fit, when a test failed and the arena's best leaves error
    above the noise floor, or when the best is a change between runs (a force depending
    on the speed or the thrust mimics one), or a library friction law the discovery's
    terms generalize (then it must beat it by
    :data:`~balancer_id.diagnostics.discover.CHALLENGE_BIC`). The
    :class:`~balancer_id.diagnostics.discover.Discovery` is kept on the explanation
    (``detail["found"]`` is not in the JSON: :attr:`Explanation.source`).
    """

    key = "discovered"
    kind = "discovered"
    verdict = Verdict.EFFECT_MISSING
    stage = Stage.LAST
    mimics: ClassVar[str] = "a library law (friction, a dead time) or a change between runs"
    separating_trial: ClassVar[str] = "record more thrust levels in both directions"

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """The discovered force, when the search is due and finds one that pays."""
        from balancer_id.diagnostics import discover as discovery

        fit, ctx = inp.fit, inp.context
        if not inp.discover or fit is None or ctx is None:
            return []
        standing = arena.standing(inp.found, inp.tests_failed)
        best = standing[0] if standing else None
        margin = 0.0
        if not discovery.should_try(best, ctx.noise_floor, inp.tests_failed):
            if not (inp.tests_failed and discovery.challenges(best, inp.match.model.registry)):
                return []
            margin = discovery.CHALLENGE_BIC  # the library's law reached the floor
        if fit.stuck:  # a fit stuck on a bound: a force found would only patch it
            return []
        command = fit.command(subcommand="improve") + " --discover --effects-out discovered.py"
        try:
            with step("discovering the missing term"):
                found = discovery.discover(
                    inp,
                    ctx,
                    rival=best,
                    command=command,
                    extra_terms=inp.extra_terms,  # type: ignore[arg-type]
                    margin=margin,
                )
        except Exception as exc:  # the search must not stop the diagnosis
            inp.failures.append(f"discovery failed: {exc!r}")
            return []
        if found is None:
            return []
        found.excess_drop = arena.excess_drop(
            inp.match.metrics["rmse"], found.rmse, inp.noise_floor
        )
        e = found.explanation()
        e.source = found
        return [e]

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """``no library effect explains the residual; a force found in the states does``."""
        d = e.detail
        alts = list(d.get("alternatives", []) or [])  # type: ignore[call-overload]
        also = (
            " (" + ", ".join(f"{a['expression']}" for a in alts) + " fits about as well: the "
            "data cannot tell them apart; record faster or longer trials)"
            if alts
            else ""
        )
        return (
            f"no library effect explains the residual; a force found in the states does: "
            f"{d['formula']} (N){also} lowers BIC by {e.delta_bic:.0f} and removes "
            f"{e.excess_drop:.0%} of the error above the noise floor. Write it as an effect "
            f"and refit: {fit.command(subcommand='improve')} --discover --effects-out "
            "discovered.py"
        )
