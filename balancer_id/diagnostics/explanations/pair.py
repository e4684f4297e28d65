"""The best library effect plus a split or drift, refitted together."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Stage,
    Verdict,
)
from balancer_id.diagnostics.explanations.drift import drift_of, drift_sentence
from balancer_id.diagnostics.explanations.effect import LibraryEffect
from balancer_id.diagnostics.explanations.run_changes import REFINE_NFEV, fit_changes
from balancer_id.diagnostics.explanations.split import REPEAT_FIRST_RUN, split_of, split_sentence

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.matching import MatchResult
    from balancer_id.identify.result import FitResult


class Pair(ExplanationKind):
    """A library effect and a parameter changing between runs, both at once.

    Proposed after the first stage on the best valid library effect (polished first, so
    that the pair beats its effect alone fairly), and on the second best when the best
    explanation leaves a tenth of the error above the floor (friction and a payload
    change, where a dead time mimics part of both). It stands only when it beats both
    its parts by the threshold (:meth:`parts`).
    """

    key = "pair"
    kind = "pair"
    verdict = Verdict.PARAMETER_CHANGED
    stage = Stage.PAIRED
    changes_parameter = True
    mimics: ClassVar[str] = "its effect alone, or its split or drift alone"
    separating_trial: ClassVar[str] = REPEAT_FIRST_RUN

    def verdict_of(self, e: Explanation) -> Verdict:
        """``parameter drift`` for an effect with a drift, else ``parameter changed``."""
        return Verdict.PARAMETER_DRIFT if e.detail.get("drift") else Verdict.PARAMETER_CHANGED

    def parts(self, e: Explanation, by_label: dict[str, Explanation]) -> list[float]:
        """The BIC falls of its effect alone and of its split or drift alone (0 if absent)."""
        effect = by_label.get(f"+{e.effects[0]}") if e.effects else None
        alone = by_label.get(e.label.split(" and ", 1)[-1])
        return [x.delta_bic if x is not None else 0.0 for x in (effect, alone)]

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """The best effect (and perhaps the second) paired with each split and drift."""
        effects = [e for e in inp.found if e.kind == LibraryEffect.kind and arena.valid(e, True)]
        if not effects:
            return []
        top = max(effects, key=lambda e: e.delta_bic)
        out = self._pairs(inp, top, polish=True)
        # a best that leaves much of the error above the floor is misspecified: the
        # second effect (one that lowers BIC by the threshold, whatever its share) may
        # be the one a split or drift completes (friction and a payload change, where a
        # dead time mimics part of both)
        every = [*inp.found, *(inp.polish(e) for e in out)]
        best = max((e for e in every if arena.valid(e, True)), key=lambda e: e.delta_bic)
        second = sorted(
            (
                e
                for e in inp.found
                if e.kind == LibraryEffect.kind
                and e is not top
                and not e.null
                and e.delta_bic > arena.BIC_THRESHOLD
            ),
            key=lambda e: -e.delta_bic,
        )
        if best.excess_drop < arena.FLOOR_DROP and second:
            out += self._pairs(inp, second[0], polish=False)
        return out

    def _pairs(self, inp: ArenaInput, effect: Explanation, polish: bool) -> list[Explanation]:
        """``effect`` paired with each split and drift (``effect`` polished first)."""
        refit = dict(inp.effect_fits).get(effect.effects[0])
        if refit is None:
            return []
        if polish:
            try:
                polished = polish_effect(inp, effect, refit)
                if polished.delta_bic > effect.delta_bic:  # the same model, fitted better
                    effect.delta_bic, effect.rmse = polished.delta_bic, polished.rmse
                    effect.detail = polished.detail
                    inp.polish(effect)
            except Exception as exc:
                inp.failures.append(f"polishing {effect.label} failed: {exc!r}")
        prefix = f"{effect.label} and "
        try:
            return fit_changes(
                inp,
                lambda c: (
                    drift_of(self, c, prefix, effect.effects)
                    if c.after_run is None
                    else split_of(self, c, prefix, effect.effects)
                ),
                model=refit.model,
                start=refit.values(),
                k_base=len(refit.model.param_names) - len(inp.match.model.param_names),
            )
        except Exception as exc:
            inp.failures.append(f"explanations of pairs failed: {exc!r}")
            return []

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """The split's or the drift's paragraph, with the effect named."""
        return split_sentence(e, fit) if "split_after_run" in e.detail else drift_sentence(e)


def polish_effect(inp: ArenaInput, effect: Explanation, refit: MatchResult) -> Explanation:
    """The effect alone, refitted from its refit by the optimiser the pairs use.

    A pair counts only when it beats its effect alone; the pairs' fits start from the
    effect's refit and may end in a better optimum of the shared parameters than the
    refit found, a gain the split or drift did not bring. Fitted the same way, with more
    iterations and nothing split, the effect alone is the fair part to beat.

    Parameters
    ----------
    inp : ArenaInput
        The current fit.
    effect : Explanation
        The library effect.
    refit : MatchResult
        Its refit (the start).

    Returns
    -------
    Explanation
        The effect alone, as fitted here.
    """
    model = refit.model
    fixed = {k: v for k, v in arena.held(inp.match).items() if k in model.param_names}
    free = [n for n in model.param_names if n not in fixed]
    parts, base, _, _ = arena.fit_varying(
        model,
        arena.Trials(inp.trials),
        refit.values(),
        fixed,
        free[0],
        np.zeros((len(inp.trials), 0)),
        max_nfev=REFINE_NFEV,
    )
    d, rmse = arena.score(inp, parts, len(model.param_names) - len(inp.match.model.param_names))
    return effect.explainer.make(
        effect.label,
        d,
        rmse,
        effects=list(effect.effects),
        detail={"values": base},
        null=effect.null,
    )
