"""The verdict: from the tests and the arena's standing explanations, with the runner-up
the recording cannot tell apart from the best."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from balancer_id.diagnostics import adequacy, arena
from balancer_id.diagnostics.arena import CLOSE_BIC, FLOOR_DROP, ArenaInput, Explanation
from balancer_id.diagnostics.explanations import KINDS, Verdict
from balancer_id.diagnostics.explanations.discovered import Discovered
from balancer_id.diagnostics.explanations.effect import LibraryEffect
from balancer_id.diagnostics.explanations.pair import Pair
from balancer_id.diagnostics.explanations.split import confound, record_hint
from balancer_id.diagnostics.suggest import Suggestion, is_missing
from balancer_id.notes import Note

if TYPE_CHECKING:
    from balancer_id.diagnostics.context import DiagnosisContext
    from balancer_id.diagnostics.residual_tests import ResidualTests
    from balancer_id.identify.result import FitResult

#: A runner-up of another kind within this share of the best's BIC fall is "close".
CLOSE_SHARE = 0.05
#: At most this many close explanations are refitted before an ambiguity is declared.
MAX_REFINED = 4


@dataclass
class Judgement:
    """The verdict, its paragraph, its notes, the ambiguity (or None) and the best."""

    verdict: Verdict
    summary: str
    notes: list[Note] = field(default_factory=list)
    ambiguity: dict[str, object] | None = None
    best: Explanation | None = None


def judge(
    ctx: DiagnosisContext,
    tests: ResidualTests,
    checks: list[dict[str, object]],
    inp: ArenaInput,
    fit: FitResult,
) -> Judgement:
    """The verdict from the tests and the best standing explanation of the arena.

    Parameters
    ----------
    ctx : DiagnosisContext
    tests : ResidualTests
    checks : list of dict
        The tests an adequate verdict must pass.
    inp : ArenaInput
        The arena, its explanations fitted (``inp.found``, refined here in place).
    fit : FitResult

    Returns
    -------
    Judgement
    """
    notes = adequacy.failed_notes(checks)
    failed = [t for t in checks if not t["passed"]]
    explanations = inp.found
    standing = arena.standing(explanations, bool(failed))
    if not standing:
        return _nothing_stands(ctx, tests, failed, notes, explanations)
    best = standing[0]
    how = confound(best, inp.trials, inp.runs)
    rival = next((e for e in standing[1:] if rivals(best, e, how is not None)), None)
    if rival is not None and how is None and _refine_close(explanations, standing, inp):
        # the close ones were refitted to convergence: rank them again
        standing = arena.standing(explanations, bool(failed))
        best = standing[0]
        how = confound(best, inp.trials, inp.runs)
        rival = next((e for e in standing[1:] if rivals(best, e, how is not None)), None)
    out = Judgement(best.verdict, best.explainer.sentence(best, fit), notes, None, best)
    if how is not None and rival is None:
        rival = next((e for e in standing[1:] if e.kind == LibraryEffect.kind), None)
    if rival is not None:
        _ambiguous(out, best, rival, how, inp)
    if best.explainer.measurement:
        notes.append(Note("diagnose.sensor", out.summary, None, "warning"))
    if best.kind == Discovered.kind:
        out.summary = f"{out.summary} {unknown_hint(tests)}"
        notes.append(Note("diagnose.discovered", out.summary, None, "warning"))
    return out


#: The explanations that refit the consistency test's own claim (a parameter that
#: differs between runs) on the whole data.
RUN_KINDS = ("split", "drift")


def _uncorroborated(failed: list[dict[str, object]], explanations: list[Explanation]) -> bool:
    """Whether the only failed test is consistency and its claim, refitted on the whole
    data, does not stand.

    The consistency test compares per-trial fits against their standard errors; those
    leave out what a whole trial shares (its thrust level read from a noisy force, its
    place between samples, a per-trial optimum in a long valley), which the fit itself
    finds and widens for (``fit.correlated_residual``). Its claim, a parameter that
    differs between runs, is refitted by the arena on every sample at once (a split or
    a drift of each parameter): where none of those earns its place, the per-trial
    scatter is the per-trial fits', not the balancer's.
    """
    if not failed or any(t["name"] != "consistency" for t in failed):
        return False
    return any(e.kind in RUN_KINDS for e in explanations)


def _nothing_stands(
    ctx: DiagnosisContext,
    tests: ResidualTests,
    failed: list[dict[str, object]],
    notes: list[Note],
    explanations: list[Explanation] | None = None,
) -> Judgement:
    """``adequate`` when every test passed (or only consistency, uncorroborated by the
    arena's refits per run), else ``effect missing`` with what failed."""
    if _uncorroborated(failed, explanations or []):
        best = max(
            (e for e in explanations or [] if e.kind in RUN_KINDS), key=lambda e: e.delta_bic
        )
        return Judgement(
            Verdict.ADEQUATE,
            f"the per-trial estimates scatter beyond their errors ({failed[0]['text']}), but a "
            f"parameter refitted per run does not earn its place on the whole data (best: "
            f"{best.label}, BIC {-best.delta_bic:+.0f}): the scatter is the per-trial fits' "
            "(what a whole trial shares), not the balancer's; the residual is consistent "
            "with noise",
            notes,
        )
    if not failed:
        excess = ctx.excess_rmse()
        ratio = excess / ctx.noise_floor if ctx.noise_floor > 0 else float("inf")
        return Judgement(
            Verdict.ADEQUATE,
            "the residual is consistent with noise: error above the noise floor "
            f"{excess:.4f} m/s^2 ({ratio:.2f}x the noise of {ctx.noise_floor:.4f} "
            "m/s^2), as white as the resting noise, the parameters agree across "
            "runs; no explanation tried improves BIC enough",
            notes,
        )
    why = "; ".join(str(t["text"]) for t in failed)
    tried = ", ".join(k.tried for k in KINDS if k.tried)
    return Judgement(
        Verdict.EFFECT_MISSING,
        f"no explanation tried ({tried}) accounts for it: {why}. "
        + unknown_hint(tests)
        + " Write a user effect for it (README: 'Writing your own effect').",
        notes,
    )


def _ambiguous(
    out: Judgement, best: Explanation, rival: Explanation, how: str | None, inp: ArenaInput
) -> None:
    """``out`` made ``ambiguous`` between ``best`` and ``rival``, with the trial to record."""
    hint = record_hint(best, how, inp.trials) if how is not None else tell_apart(best, rival)
    out.ambiguity = {
        "best": best.label,
        "runner_up": rival.label,
        "delta_bic": [best.delta_bic, rival.delta_bic],
        "confounded_by": how,
        "record": hint,
    }
    text = (
        f"{best.label} (BIC -{best.delta_bic:.0f}) and {rival.label} "
        f"(BIC -{rival.delta_bic:.0f}) both explain the residual"
        + (f"; the split coincides with the {how} of the runs" if how else "")
        + f": {hint}"
    )
    out.notes.append(
        Note("diagnose.confounded" if how else "diagnose.ambiguous", text, None, "warning")
    )
    out.verdict = Verdict.AMBIGUOUS
    out.summary = text + ". Best: " + out.summary


def offered(suggestions: list[Suggestion], j: Judgement) -> list[Suggestion]:
    """The suggestions a verdict offers: none when adequate or when the best stands
    alone (a change, a sensor's effect: an effect would only mimic it); the missing
    ones beside a discovered force; else those with a benefit (a pair's effect only).

    Parameters
    ----------
    suggestions : list of Suggestion
    j : Judgement

    Returns
    -------
    list of Suggestion
    """
    best = j.best
    if j.verdict == Verdict.ADEQUATE:
        return []  # nothing offered without benefit
    if best is not None and best.explainer.stands_alone and j.ambiguity is None:
        return []  # no effect that would only mimic it
    if best is not None and best.kind == Discovered.kind:
        return [s for s in suggestions if is_missing(s) and not s.null]
    keep = set(best.effects) if best is not None and best.kind == Pair.kind else None
    return [
        s
        for s in suggestions
        if s.delta_bic > 0 and not s.null and (keep is None or s.effect in keep)
    ]


def _refine_close(
    explanations: list[Explanation], standing: list[Explanation], inp: ArenaInput
) -> bool:
    """Refit to convergence the best and the explanations close to it, in place.

    The arena's first fits stop early (enough to rank them); two explanations within the
    close window may differ by that alone, most when the current fit is far from every
    explanation's optimum. Each refined explanation replaces its first fit in
    ``explanations`` (kept sorted). Returns whether any was refined.
    """
    best = standing[0]
    window = max(CLOSE_BIC, CLOSE_SHARE * best.delta_bic if best.excess_drop < FLOOR_DROP else 0)
    close = [e for e in standing if e.refine is not None and best.delta_bic - e.delta_bic <= window]
    done = False
    for e in close[:MAX_REFINED]:
        try:
            new = e.refine()  # type: ignore[misc]
        except Exception:  # a refinement that fails keeps the first fit
            continue
        if new.delta_bic <= e.delta_bic:
            continue
        explanations[explanations.index(e)] = inp.polish(new)
        done = True
    explanations.sort(key=lambda x: -x.delta_bic)
    return done


def rivals(best: Explanation, e: Explanation, confounded: bool) -> bool:
    """Whether ``e`` is a runner-up the verdict must name with ``best``.

    Another verdict is a rival when the recording confounds the best with it, when it
    comes within :data:`CLOSE_BIC`, or, while the best leaves part of the error above the
    noise floor (it removes less than :data:`FLOOR_DROP` of it: a misspecified best,
    whose BIC lead is not to be trusted), within :data:`CLOSE_SHARE` of the best's BIC
    fall. A best that brings the residual to the noise floor is outranked by likelihood
    alone: a rival 100 BIC units behind is e^50 times less likely. An explanation of the same
    verdict naming other effects or parameters (D0 drifting against A drifting) is one
    when within :data:`CLOSE_BIC`: the verdict stands, but not what it names. Another
    boundary of the same parameter's split is not a rival (what changed is known). A
    twin (the same delay read as the sensor's or the balancer's:
    :meth:`~balancer_id.diagnostics.explanations.base.ExplanationKind.twin`) always is.

    Parameters
    ----------
    best, e : Explanation
    confounded : bool
        Whether the recording confounds the best with another explanation.

    Returns
    -------
    bool
    """
    gap = best.delta_bic - e.delta_bic
    if best.explainer.twin(best, e) or e.explainer.twin(e, best):
        return True
    if e.verdict != best.verdict:
        relative = CLOSE_SHARE * best.delta_bic if best.excess_drop < FLOOR_DROP else 0.0
        return confounded or gap <= max(CLOSE_BIC, relative)
    names = (set(best.effects), set(best.parameters))
    return (set(e.effects), set(e.parameters)) != names and gap <= CLOSE_BIC


def tell_apart(best: Explanation, rival: Explanation) -> str:
    """The trial to record that tells ``best`` from ``rival``.

    Two changes of the same verdict naming different parameters: each thrust level at
    the start and the end; else the separating trial of the kind that is the sensor's,
    or of the one that changes a parameter, or of the best.

    Parameters
    ----------
    best, rival : Explanation

    Returns
    -------
    str
    """
    kinds = (best.explainer, rival.explainer)
    both = [*best.parameters, *(p for p in rival.parameters if p not in best.parameters)]
    changes = all(k.changes_parameter for k in kinds)
    if changes and best.verdict == rival.verdict and len(both) > 1:
        return (
            "record each thrust level, up and down, at the start and again at the end of "
            f"the session: {' and '.join(both)} change the response differently across "
            "thrust levels and directions, so the change seen at every level tells which "
            "one moved"
        )
    first = min(kinds, key=lambda k: (not k.measurement, not k.changes_parameter))
    return first.separating_trial


def unknown_hint(tests: ResidualTests) -> str:
    """Where the residual is worst, what it follows and its spectrum's peak.

    Parameters
    ----------
    tests : ResidualTests

    Returns
    -------
    str
    """
    where = tests.worst_windows[0] if tests.worst_windows else None
    corr = tests.state_correlation
    name, r = max(corr.items(), key=lambda kv: abs(kv[1])) if corr else ("-", 0.0)
    peaks = tests.spectrum["peaks"]
    return (
        (
            f"Worst in trial {where['trial']} at {where['t_start']:.2f}-{where['t_end']:.2f} s; "
            if where
            else ""
        )
        + f"it follows the {name} (r = {r:+.2f})"
        + (f"; spectrum peak at {peaks[0]['frequency_hz']:.2f} Hz" if peaks else "")  # type: ignore[index]
        + "."
    )


def groups_record(best: Explanation, per: list, runs_of_per: list[str]) -> dict[str, object]:
    """CONTRACT.md ``parameter_groups`` of a split, with the per-run estimates.

    Parameters
    ----------
    best : Explanation
        The split (or a pair with one).
    per : list
        The per-trial fits.
    runs_of_per : list of str
        Each per-trial fit's run.

    Returns
    -------
    dict
    """
    from scipy.special import chdtrc

    from balancer_id.diagnostics.groups import run_estimates

    d = best.detail
    name = best.parameters[0]
    n = int(best.detail.get("n_samples", 0) or 0)  # type: ignore[call-overload]
    # the split's likelihood-ratio statistic from its BIC fall (one more parameter)
    delta_chi2 = best.delta_bic + (float(np.log(n)) if n > 1 else 0.0)
    est = run_estimates(
        runs_of_per,
        [p.values.get(name, np.nan) for p in per],
        [p.stderr.get(name) for p in per],
        [p.thrust_N for p in per],
    )
    return {
        "parameter": name,
        "split_after_run": d.get("split_after_run"),
        "before": {"value": d.get("before")},
        "after": {"value": d.get("after")},
        "group_by": d.get("group_by"),
        "with_effects": list(best.effects),
        "delta_bic": best.delta_bic,
        "delta_chi2": delta_chi2,
        "p_value": float(min(chdtrc(1, max(delta_chi2, 0.0)) * max(len(est) - 3, 1), 1.0)),
        "runs": [
            {"run": e.run, "value": e.value, "stderr": e.stderr, "thrust_N": e.thrust_N}
            for e in est
        ],
    }
