"""The library candidates refitted and scored: ``diagnose``'s suggestions."""

from __future__ import annotations

import contextlib
import os
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.arena import BIC_THRESHOLD, MIN_EXCESS_DROP
from balancer_id.diagnostics.candidates import Candidate, Refit, candidates, quick_refit
from balancer_id.diagnostics.signatures import Signature, signature_of
from balancer_id.simulation.kernel import get_kernel
from balancer_id.simulation.kernel_compile import compile_models
from balancer_id.status import tell

if TYPE_CHECKING:
    from balancer_id.diagnostics.context import DiagnosisContext
    from balancer_id.identify.classic import ClassicResult
    from balancer_id.identify.data import TrialData
    from balancer_id.identify.matching import MatchResult
    from balancer_id.identify.result import FitResult


@dataclass
class Suggestion:
    """One candidate effect, scored by the improvement its quick refit brings."""

    effect: str
    label: str
    score: float
    delta_bic: float
    rmse: float
    excess_drop: float
    signature: Signature
    command: str
    model: str
    refit: MatchResult | None = field(default=None, repr=False)
    #: The added effect's parameters sit where it does nothing (dead time 0): no benefit.
    null: bool = False

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md suggestion record."""
        return {
            "effect": self.effect,
            "change": self.label,
            "model": self.model,
            "score": self.score,
            "delta_bic": self.delta_bic,
            "rmse_after": self.rmse,
            "excess_error_drop": self.excess_drop,
            "signature_strength": self.signature.strength,
            "evidence": self.signature.evidence,
            "command": self.command,
        }


def is_missing(s: Suggestion) -> bool:
    """Whether a suggestion's improvement is large enough to call its effect missing.

    Parameters
    ----------
    s : Suggestion
        A scored candidate.

    Returns
    -------
    bool
        True when its BIC improvement exceeds :data:`BIC_THRESHOLD` and it removes more
        than :data:`MIN_EXCESS_DROP` of the error above the noise floor.
    """
    return s.delta_bic > BIC_THRESHOLD and s.excess_drop > MIN_EXCESS_DROP


def suggest(
    fit: FitResult, ctx: DiagnosisContext, threads: int | None
) -> tuple[list[Suggestion], list[str]]:
    """Every library candidate refitted and scored, best first, and the named failures.

    Parameters
    ----------
    fit : FitResult
        The fit diagnosed.
    ctx : DiagnosisContext
        Its residuals (the candidates' signatures read them).
    threads : int or None
        Refits at once; None: one per core.

    Returns
    -------
    suggestions : list of Suggestion
    failures : list of str
    """
    match = fit.match
    cands = candidates(match.model, with_trajectory=fit.trial_set.trajectory is not None)
    suggestions: list[Suggestion] = []
    failures: list[str] = []
    trials = list(match.data.trials)
    fixed = dict(fit.fixed) or None
    refitted = _refit_candidates(cands, ctx, trials, match, fixed, fit.classic, threads)
    se_zero = arena.zero_stderr(match)  # an added offset within it is no finding
    for cand, sig, refit, sig_failure in refitted:
        if sig_failure:
            failures.append(sig_failure)
        if refit.match is None:
            failures.append(refit.error or cand.effect.name)
            continue
        new = refit.match.metrics
        # BIC counts every sample as independent; with coloured noise they are not, so the
        # improvement is scaled by the effective share of independent samples.
        d_bic = float(match.metrics["bic"] - new["bic"]) * arena.independence(refit.match)
        drop = arena.excess_drop(match.metrics["rmse"], new["rmse"], ctx.noise_floor)
        suggestions.append(
            Suggestion(
                effect=cand.effect.name,
                label=cand.label,
                score=round(d_bic, 2),
                delta_bic=d_bic,
                rmse=new["rmse"],
                excess_drop=float(drop),
                signature=sig,
                command=fit.command(cand.model),
                model=cand.model.spec,
                refit=refit.match,
                null=arena.is_null(refit.match, cand.effect.name)
                or arena.within_sensor_zero(refit.match, cand.effect.name, se_zero),
            )
        )
    suggestions.sort(key=lambda s: -s.score)
    return suggestions, failures


#: A candidate, its signature, its refit and why its signature check failed (or None).
Refitted = tuple[Candidate, Signature, Refit, str | None]


def _refit_candidates(
    cands: list[Candidate],
    ctx: DiagnosisContext,
    trials: list[TrialData],
    match: MatchResult,
    fixed: dict[str, float] | None,
    classic: ClassicResult | None,
    threads: int | None = None,
) -> list[Refitted]:
    """Check each candidate's signature and refit it, candidates in parallel threads.

    The refits are independent and their simulations run in compiled kernels that
    release the GIL, so threads use every core without copying the trials to other
    processes. Results come back in the candidates' order, the same as one by one; each
    finished refit is told to the status listener ("candidate 3/7: karnopp").
    """
    compile_models([c.model for c in cands])  # a first run says so, with a count
    for cand in cands:  # load every kernel before the threads share them
        with contextlib.suppress(Exception):  # a broken effect fails in its own refit
            get_kernel(cand.model, quiet=True)

    def one(cand: Candidate) -> Refitted:
        failure = None
        try:
            sig = signature_of(cand.effect, ctx)
        except Exception as exc:  # a user's check must not stop the others
            sig = Signature(0.0, "signature check failed")
            failure = f"signature check of '{cand.effect.name}' failed: {exc!r}"
        return cand, sig, quick_refit(cand, trials, match, sig.start, fixed, classic), failure

    threads = min(len(cands), threads or os.cpu_count() or 1)
    if threads <= 1:
        done = []
        for k, cand in enumerate(cands, 1):
            tell(f"candidate {k}/{len(cands)}: {cand.effect.name}")
            done.append(one(cand))
        return done
    with ThreadPoolExecutor(threads, thread_name_prefix="balancer-id-refit") as pool:
        futures = {pool.submit(one, cand): i for i, cand in enumerate(cands)}
        results: list[Refitted | None] = [None] * len(cands)
        for k, future in enumerate(as_completed(futures), 1):
            i = futures[future]
            results[i] = future.result()
            tell(f"candidate {k}/{len(cands)}: {cands[i].effect.name} refitted")
    return [r for r in results if r is not None]
