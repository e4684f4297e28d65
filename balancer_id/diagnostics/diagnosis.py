"""``diagnose``: residual tests and ranked suggestions of missing effects."""

from __future__ import annotations

import contextlib
import os
import shlex
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from balancer_id.diagnostics import adequacy, arena
from balancer_id.diagnostics import discover as discovery_search
from balancer_id.diagnostics.arena import ArenaInput, Explanation
from balancer_id.diagnostics.candidates import Candidate, Refit, candidates, quick_refit
from balancer_id.diagnostics.context import DiagnosisContext, build_context
from balancer_id.diagnostics.residual_tests import (
    input_correlation,
    regime_table,
    spectrum_peaks,
    state_correlations,
    whiteness,
    worst_windows,
)
from balancer_id.diagnostics.signatures import Signature, signature_of
from balancer_id.identify.classic import ClassicResult
from balancer_id.identify.data import TrialData
from balancer_id.identify.display import CallableText, Displayable
from balancer_id.identify.matching import MatchResult
from balancer_id.identify.result import FitResult
from balancer_id.notes import Note, as_note, texts
from balancer_id.simulation.kernel import compile_models, get_kernel
from balancer_id.status import step, tell

#: BIC improvement a candidate needs before an effect is called missing. Calibrated on
#: simulated logs with nothing hidden (benchmarks/bench_diagnose.py, false alarms <= 5 %).
BIC_THRESHOLD = 30.0
#: ... and the share of the error above the noise floor it must remove.
MIN_EXCESS_DROP = 0.1


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


@dataclass
class ResidualTests:
    """The residual tests of a fit (CONTRACT.md ``diagnose`` ``residual_tests``).

    Attributes
    ----------
    noise_floor : float
        Acceleration noise (m/s^2).
    whiteness : dict
        Autocorrelation, its band and the Ljung-Box test
        (:func:`~balancer_id.diagnostics.residual_tests.whiteness`).
    input_cross_correlation : dict
        The residual against the thrust step, its peak and significance.
    spectrum : dict
        ``peaks`` of the residual's spectrum.
    regimes : list of dict
        The residual by regime, direction and thrust level.
    state_correlation : dict of str to float
        Correlation of the residual with each simulated state.
    worst_windows : list of dict
        Where the residual is largest.
    paper_line : dict
        ``m_a``, ``intercept_N`` and ``free_slope`` of the paper's method.
    parameter_drift : list of dict
        Per-trial refits: each parameter's slope against thrust and up/down difference.
    parameter_groups : dict or None
        A parameter that changed between runs (payload, setting), with its per-run
        estimates and the split test; None when none did.
    input_cross_correlation_curve : dict
        :attr:`input_cross_correlation` with its curve (``lag_s``, ``mean_residual``).
    """

    noise_floor: float
    whiteness: dict[str, object]
    input_cross_correlation: dict[str, object]
    spectrum: dict[str, object]
    regimes: list[dict[str, object]]
    state_correlation: dict[str, float]
    worst_windows: list[dict[str, object]]
    paper_line: dict[str, float]
    parameter_drift: list[dict[str, object]]
    parameter_groups: dict[str, object] | None = None
    #: The cross-correlation with its ``lag_s`` and ``mean_residual`` curve (for the
    #: report's plot; the JSON keeps the peak and the band only).
    input_cross_correlation_curve: dict[str, object] = field(default_factory=dict, repr=False)

    def __getitem__(self, key: str) -> object:
        """The test named ``key``, as in :meth:`to_dict`.

        Parameters
        ----------
        key : str
            A key of the CONTRACT.md ``residual_tests`` object.

        Returns
        -------
        object
        """
        if key not in self.__dataclass_fields__:
            raise KeyError(key)
        return getattr(self, key)

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``residual_tests`` object."""
        return {
            "noise_floor": self.noise_floor,
            "whiteness": self.whiteness,
            "input_cross_correlation": self.input_cross_correlation,
            "spectrum": self.spectrum,
            "regimes": self.regimes,
            "state_correlation": self.state_correlation,
            "worst_windows": self.worst_windows,
            "paper_line": self.paper_line,
            "parameter_drift": self.parameter_drift,
            **({"parameter_groups": self.parameter_groups} if self.parameter_groups else {}),
        }


@dataclass(repr=False)
class Diagnosis(Displayable):
    """Everything ``balancer-id diagnose`` reports.

    Attributes
    ----------
    fit : FitResult
        The fit diagnosed (its trials, paper's method and per-trial fits are reused).
    context : DiagnosisContext
        The fit's residuals, trial by trial, and the noise floor.
    tests : ResidualTests
        The residual tests.
    suggestions : list of Suggestion
        Candidate effects, best first.
    verdict : str
        ``adequate`` or ``effect missing``.
    summary : str
        One paragraph saying why.
    failures : list of str
        Candidates whose check or refit failed (named).
    """

    fit: FitResult
    context: DiagnosisContext
    tests: ResidualTests
    suggestions: list[Suggestion]
    verdict: str
    summary: str  # type: ignore[assignment]  # also callable: CallableText
    failures: list[str] = field(default_factory=list)
    #: Every fitted explanation, best first (:mod:`~balancer_id.diagnostics.arena`).
    explanations: list[Explanation] = field(default_factory=list)
    #: The tests "adequate" must pass (:mod:`~balancer_id.diagnostics.adequacy`).
    checks: list[dict[str, object]] = field(default_factory=list)
    #: Typed notes: failed tests, ambiguity, confounding, sensor effects.
    notes: list[Note] = field(default_factory=list)
    #: The runner-up when it is close or confounded with the best, and how to tell them.
    ambiguity: dict[str, object] | None = None
    #: The discovered missing force (:mod:`~balancer_id.diagnostics.discover`), or None.
    discovery: discovery_search.Discovery | None = None

    def __post_init__(self) -> None:
        # ``diagnosis.summary`` is the verdict's paragraph; ``diagnosis.summary()`` the
        # full lmfit-style text (as every result of the API has)
        self.summary = CallableText(str(self.summary), self._summary_text)

    @property
    def match(self) -> MatchResult:
        """The simulation-matching fit diagnosed."""
        return self.fit.match

    def fit_warnings(self) -> list[Note]:
        """The fit's warnings, read in the light of the verdict.

        When an effect is missing, a parameter the data cannot determine (note
        ``fit.not_identifiable``) is a symptom of the missing effect (the model bends its
        parameters to follow what it lacks): the note becomes ``fit.symptom``, its advice
        to hold the parameter with ``--fix`` replaced by the top suggestion.

        Returns
        -------
        list of Note
        """
        warnings = [as_note(w) for w in (*self.fit.warnings, *self.fit.match.warnings)]
        if self.verdict == "adequate":
            return warnings
        missing = [s for s in self.suggestions if is_missing(s)]
        first = (
            f"add the effect first ({missing[0].label}: {missing[0].command})"
            if missing
            else "find the effect first (no library effect explains it: see the diagnosis)"
        )
        out = []
        for w in warnings:
            if w.code == "fit.not_identifiable":
                head = w.text.split(";")[0]
                w = Note(
                    "fit.symptom",
                    f"{head}: a symptom of the missing effect, not a reason to hold it with "
                    f"--fix; {first}",
                    w.subject,
                    w.severity,
                )
            out.append(w)
        return out

    def _shown_match(self) -> MatchResult:
        return self.fit.match

    def _headline(self) -> str:
        top = f"; top suggestion: {self.suggestions[0].label}" if self.suggestions else ""
        return f"{self.fit.model}: {self.verdict}{top}"

    def _summary_warnings(self) -> list[str]:
        return texts(self.fit_warnings())

    def _summary_extra(self) -> list[str]:
        lines = ["[[Diagnosis]]", f"    verdict: {self.verdict}", f"    {self.summary!s}"]
        for t in self.checks:
            state = "passed" if t["passed"] else "FAILED"
            lines.append(f"    test {t['name']}: {state}; {t['text']}")
        if self.explanations:
            lines.append("[[Explanations]] (fitted, best first; BIC fall)")
            for e in self.explanations[:5]:
                lines.append(f"    {e.label}: {e.delta_bic:.0f}")
        if self.suggestions:
            lines.append("[[Suggestions]] (best first)")
            for k, s in enumerate(self.suggestions[:5], 1):
                lines.append(
                    f"    {k}. {s.label}: score {s.score:.1f}, RMSE {s.rmse:.4g} m/s^2;"
                    f" {s.signature.evidence}"
                )
                lines.append(f"       {s.command}")
        if self.discovery is not None:
            d = self.discovery
            lines.append("[[Discovered term]] (sparse regression of the force discrepancy)")
            lines.append(f"    {d.formula} (N); BIC falls by {d.delta_bic:.0f}")
            for t in d.terms:
                se = f" +/- {t.stderr:.2g}" if t.stderr is not None else ""
                lines.append(
                    f"    {t.expression}: {t.coefficient:.4g}{se} {t.term.unit},"
                    f" kept in {t.inclusion:.0%} of the bootstrap resamples"
                )
            lines.append(f"    {d.command}")
        return lines

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``diagnose`` object."""
        from balancer_id.jsonsafe import json_ready

        return json_ready(
            {
                "model": self.match.model.spec,
                "metrics": {
                    **self.match.metrics,
                    "noise_floor": self.context.noise_floor,
                    "excess_rmse": self.context.excess_rmse(),
                },
                "parameters": {k: p.to_dict() for k, p in self.match.parameters.items()},
                "residual_tests": self.tests.to_dict(),
                "verdict": self.verdict,
                "summary": self.summary,
                "suggestions": [s.to_dict() for s in self.suggestions],
                "failed_candidates": self.failures,
                "tests": self.checks,
                "explanations": [e.to_dict() for e in self.explanations],
                "ambiguity": self.ambiguity,
                "notes": [n.to_dict() for n in self.notes],
                "discovery": self.discovery.to_dict() if self.discovery is not None else None,
            }
        )


def diagnose(
    fit: FitResult,
    *,
    threads: int | None = None,
    discover: bool = True,
    extra_terms: Sequence[discovery_search.Term] = (),
) -> Diagnosis:
    """Test the residual of a fit and rank the effects that could explain it.

    The fit's paper's method and per-trial fits are reused (the per-trial fits are
    computed here when the fit has none yet, and kept on it); each candidate is refitted
    from the fit and from the start values a fit of it would use (the data's own scale).

    Parameters
    ----------
    fit : FitResult
        A fit over all trials, with what it was computed from (trials, fixed values,
        effect files, reference move: the suggested commands carry them all).
    threads : int, optional
        Fits run at once (the candidates' refits, the arena's splits and drifts); None
        uses :data:`REFIT_THREADS` (one per core). A batch's workers pass 1: their
        processes already share the cores.
    discover : bool
        When the tests fail and no explanation of the arena brings the residual to the
        noise floor, search the missing force as a sparse sum of candidate terms
        (:func:`~balancer_id.diagnostics.discover.discover`); False never searches.
    extra_terms : sequence of Term
        The user's own candidate terms, added to the discovery's library.

    Returns
    -------
    Diagnosis
    """
    match = fit.match
    ctx = build_context(match)
    trials: list[TrialData] = list(match.data.trials)
    classic = fit.classic
    fixed = fit.fixed or None
    xcorr = input_correlation(ctx)
    tests = ResidualTests(
        noise_floor=ctx.noise_floor,
        whiteness=whiteness(ctx),
        input_cross_correlation=_thin(xcorr),
        input_cross_correlation_curve=xcorr,
        spectrum={"peaks": spectrum_peaks(ctx)["peaks"]},
        regimes=regime_table(ctx),
        state_correlation=state_correlations(ctx),
        worst_windows=worst_windows(ctx),
        paper_line={
            "m_a": classic.m_a,
            "intercept_N": classic.intercept_N,
            "free_slope": classic.free_slope,
        },
        parameter_drift=parameter_drift(fit),
    )
    per = fit.per_trial_fits()
    source_of = {td.index: td.source for td in trials}
    runs_of_per = [source_of.get(p.index, "") for p in per]
    colour = adequacy.colour_test(ctx)
    checks = [
        adequacy.level_test(ctx, colour),
        colour,
        adequacy.consistency_test(
            match.model.param_names,
            runs_of_per,
            [p.values for p in per],
            [p.stderr for p in per],
            [p.thrust_N for p in per],
            (classic.m_a, classic.m_a_stderr) if classic is not None else None,
            (match.parameters["m_a"].value, match.parameters["m_a"].stderr)
            if "m_a" in match.parameters
            else None,
            adequacy.colour_inflation(colour),
        ),
    ]
    suggestions: list[Suggestion] = []
    failures: list[str] = []
    with_trajectory = fit.trial_set.trajectory is not None
    cands = candidates(match.model, with_trajectory=with_trajectory)
    for cand, sig, refit, sig_failure in _refit_candidates(
        cands, ctx, trials, match, fixed, classic, threads
    ):
        if sig_failure:
            failures.append(sig_failure)
        if refit.match is None:
            failures.append(refit.error or cand.effect.name)
            continue
        new = refit.match.metrics
        # BIC counts every sample as independent; with coloured noise they are not, so the
        # improvement is scaled by the effective share of independent samples.
        d_bic = float(match.metrics["bic"] - new["bic"]) * independence(refit.match)
        drop = excess_drop(match.metrics["rmse"], new["rmse"], ctx.noise_floor)
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
                null=arena.is_null(refit.match, cand.effect.name),
            )
        )
    suggestions.sort(key=lambda s: -s.score)
    inp = ArenaInput(
        match=match,
        trials=trials,
        runs=[source_of.get(td.index, "") for td in trials],
        noise_floor=ctx.noise_floor,
        independence=independence(match),
        effect_fits=[(s.effect, s.refit) for s in suggestions if s.refit is not None],
        rest_cutoff_hz=arena.rest_cutoff(trials, 1.0 / ctx.dt) if ctx.dt > 0 else None,
        ar=arena.ar_coefficients(colour["rest_acf"], int(colour["n_rest"])),  # type: ignore[arg-type]
        threads=threads or REFIT_THREADS,
    )
    rest_rss, rest_n = arena.whitened_rss(adequacy.rest_noise(ctx), inp.ar)
    inp.rest_innovation = rest_rss / rest_n if rest_n >= 50 else None
    explanations = _explain(inp, suggestions, failures)
    found = None
    if discover:
        found = _discover(inp, ctx, checks, explanations, failures, fit, extra_terms)
    verdict, summary, notes, ambiguity, best = _arena_verdict(
        ctx, tests, checks, explanations, suggestions, inp, fit
    )
    if best is not None and best.verdict == "parameter changed":
        tests.parameter_groups = _groups_record(best, per, runs_of_per)
    if verdict == "adequate":
        suggestions = []  # nothing offered without benefit
    elif best is not None and best.kind in ("split", "drift", "sensor") and ambiguity is None:
        suggestions = []  # no effect that would only mimic it
    elif best is not None and best.kind == "discovered":
        suggestions = [s for s in suggestions if is_missing(s) and not s.null]
    else:
        keep = set(best.effects) if best is not None and best.kind == "pair" else None
        suggestions = [
            s
            for s in suggestions
            if s.delta_bic > 0 and not s.null and (keep is None or s.effect in keep)
        ]
    return Diagnosis(
        fit,
        ctx,
        tests,
        suggestions,
        verdict,
        summary,
        failures,
        explanations,
        checks,
        notes,
        ambiguity,
        found,
    )


def _discover(
    inp: ArenaInput,
    ctx: DiagnosisContext,
    checks: list[dict[str, object]],
    explanations: list[Explanation],
    failures: list[str],
    fit: FitResult,
    extra_terms: Sequence[discovery_search.Term],
) -> discovery_search.Discovery | None:
    """The discovered force when the arena's best leaves the tests failed; joins the arena."""
    failed = [t for t in checks if not t["passed"]]
    standing = _standing(explanations, bool(failed))
    best = standing[0] if standing else None
    margin = 0.0
    if not discovery_search.should_try(best, ctx.noise_floor, bool(failed)):
        if not (failed and discovery_search.challenges(best, inp.match.model.registry)):
            return None
        margin = discovery_search.CHALLENGE_BIC  # the library's law reached the floor
    if fit.stuck:  # a fit stuck on a bound: a force found would only patch it
        return None
    command = fit.command(subcommand="improve") + " --discover --effects-out discovered.py"
    try:
        with step("discovering the missing term"):
            found = discovery_search.discover(
                inp, ctx, rival=best, command=command, extra_terms=extra_terms, margin=margin
            )
    except Exception as exc:  # the search must not stop the diagnosis
        failures.append(f"discovery failed: {exc!r}")
        return None
    if found is None:
        return None
    found.excess_drop = excess_drop(inp.match.metrics["rmse"], found.rmse, inp.noise_floor)
    e = found.explanation()
    available = inp.available()
    e.share = e.delta_bic / available if available else None
    explanations.append(e)
    explanations.sort(key=lambda x: -x.delta_bic)
    return found


def _explain(
    inp: ArenaInput, suggestions: list[Suggestion], failures: list[str]
) -> list[Explanation]:
    """Every generator's explanations, plus the best effect paired with a split or drift."""
    out: list[Explanation] = []
    available = inp.available()
    for gen in arena.GENERATORS:
        try:
            out.extend(gen(inp))
        except Exception as exc:  # one generator must not stop the others
            failures.append(f"explanations of {getattr(gen, '__name__', gen)} failed: {exc!r}")
    for e in out:
        e.excess_drop = excess_drop(inp.match.metrics["rmse"], e.rmse, inp.noise_floor)
        e.share = e.delta_bic / available if available else None
    effects = [e for e in out if e.kind == "effect" and _valid(e, True)]
    if effects:
        top = max(effects, key=lambda e: e.delta_bic)
        _add_pairs(inp, top, suggestions, out, failures, polish=True)
        # a best that leaves much of the error above the floor is misspecified: the
        # second effect (one that lowers BIC by the threshold, whatever its share) may
        # be the one a split or drift completes (friction and a payload change, where a
        # dead time mimics part of both)
        best = max((e for e in out if _valid(e, True)), key=lambda e: e.delta_bic)
        second = sorted(
            (
                e
                for e in out
                if e.kind == "effect"
                and e is not top
                and not e.null
                and e.delta_bic > BIC_THRESHOLD
            ),
            key=lambda e: -e.delta_bic,
        )
        if best.excess_drop < FLOOR_DROP and second:
            _add_pairs(inp, second[0], suggestions, out, failures, polish=False)
    out.sort(key=lambda e: -e.delta_bic)
    return out


def _add_pairs(
    inp: ArenaInput,
    effect: Explanation,
    suggestions: list[Suggestion],
    out: list[Explanation],
    failures: list[str],
    polish: bool,
) -> None:
    """``effect`` paired with each split and drift, appended to ``out`` (polished first)."""
    available = inp.available()
    refit = next((s.refit for s in suggestions if s.effect == effect.effects[0] and s.refit), None)
    if refit is None:
        return
    if polish:
        try:
            polished = arena.polish(inp, effect, refit)
            if polished.delta_bic > effect.delta_bic:  # the same model, fitted better
                effect.delta_bic, effect.rmse = polished.delta_bic, polished.rmse
                effect.detail = polished.detail
                effect.excess_drop = excess_drop(
                    inp.match.metrics["rmse"], effect.rmse, inp.noise_floor
                )
                effect.share = effect.delta_bic / available if available else None
        except Exception as exc:
            failures.append(f"polishing {effect.label} failed: {exc!r}")
    try:
        for e in arena.pairs(inp, effect, refit):
            e.excess_drop = excess_drop(inp.match.metrics["rmse"], e.rmse, inp.noise_floor)
            e.share = e.delta_bic / available if available else None
            out.append(e)
    except Exception as exc:
        failures.append(f"explanations of pairs failed: {exc!r}")


def _valid(e: Explanation, tests_failed: bool = False) -> bool:
    """An explanation with a benefit: BIC falls enough, not at its null value, and a real
    drop of the error above the noise floor (or of the prewhitened excess)."""
    if e.null:
        return False
    if e.kind == "sensor" and not tests_failed:
        # offered only when the resting noise shows a filter's roll-off (independent
        # evidence, measured with the balancer still): it stands unless the response
        # contradicts it. A response fitted as well without it has the sensor's lag in
        # T_a: that is worth saying, not "adequate"
        return e.delta_bic > -CLOSE_BIC
    if e.delta_bic <= BIC_THRESHOLD:
        return False
    if e.excess_drop > MIN_EXCESS_DROP:
        return True
    # a sensor's low-pass hides part of the noise from the floor's estimate (its resting
    # parts are short and smooth), so its drop is understated: the sensor explanation
    # (offered only when the resting noise rolls off, its own evidence) needs BIC only
    return e.kind == "sensor"


def _standing(explanations: list[Explanation], tests_failed: bool) -> list[Explanation]:
    """The valid explanations; a pair only when it beats both its parts by the threshold."""
    valid = [e for e in explanations if _valid(e, tests_failed)]
    by_label = {e.label: e for e in explanations}
    out = []
    for e in valid:
        if e.kind == "pair":
            part_effect = by_label.get(f"+{e.effects[0]}") if e.effects else None
            alone = e.label.split(" and ", 1)[-1]
            part_split = by_label.get(alone)
            gain = min(
                e.delta_bic - (part_effect.delta_bic if part_effect else 0.0),
                e.delta_bic - (part_split.delta_bic if part_split else 0.0),
            )
            if gain <= BIC_THRESHOLD:
                continue
        out.append(e)
    return sorted(out, key=lambda e: -e.delta_bic)


#: A runner-up of another kind within this share of the best's BIC fall is "close".
CLOSE_SHARE = 0.05
#: A runner-up naming other effects or parameters within this many BIC units is "close"
#: whatever its kind: a likelihood ratio under e^3 ~ 20 (Kass and Raftery's "positive"
#: evidence, short of "strong"), so the recording cannot tell the two apart.
CLOSE_BIC = 6.0


#: A best removing this share of the error above the noise floor reaches the floor.
FLOOR_DROP = 0.9
#: At most this many close explanations are refitted before an ambiguity is declared.
MAX_REFINED = 4


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
    available = inp.available()
    done = False
    for e in close[:MAX_REFINED]:
        try:
            new = e.refine()  # type: ignore[misc]
        except Exception:  # a refinement that fails keeps the first fit
            continue
        if new.delta_bic <= e.delta_bic:
            continue
        new.excess_drop = excess_drop(inp.match.metrics["rmse"], new.rmse, inp.noise_floor)
        new.share = new.delta_bic / available if available else None
        explanations[explanations.index(e)] = new
        done = True
    explanations.sort(key=lambda x: -x.delta_bic)
    return done


def _rivals(best: Explanation, e: Explanation, confounded: bool) -> bool:
    """Whether ``e`` is a runner-up the verdict must name with ``best``.

    Another verdict is a rival when the recording confounds the best with it, when it
    comes within :data:`CLOSE_BIC`, or, while the best leaves part of the error above the
    noise floor (it removes less than :data:`FLOOR_DROP` of it: a misspecified best,
    whose BIC lead is not to be trusted), within :data:`CLOSE_SHARE` of the best's BIC
    fall. A best that brings the residual to the noise floor is outranked by likelihood
    alone: a rival 100 BIC units behind is e^50 times less likely. An explanation of the same
    verdict naming other effects or parameters (D0 drifting against A drifting) is one
    when within :data:`CLOSE_BIC`: the verdict stands, but not what it names. Another
    boundary of the same parameter's split is not a rival (what changed is known).
    """
    gap = best.delta_bic - e.delta_bic
    if e.verdict != best.verdict:
        relative = CLOSE_SHARE * best.delta_bic if best.excess_drop < FLOOR_DROP else 0.0
        return confounded or gap <= max(CLOSE_BIC, relative)
    names = (set(best.effects), set(best.parameters))
    return (set(e.effects), set(e.parameters)) != names and gap <= CLOSE_BIC


def _arena_verdict(
    ctx: DiagnosisContext,
    tests: ResidualTests,
    checks: list[dict[str, object]],
    explanations: list[Explanation],
    suggestions: list[Suggestion],
    inp: ArenaInput,
    fit: FitResult,
) -> tuple[str, str, list[Note], dict[str, object] | None, Explanation | None]:
    """The verdict from the tests and the best explanation."""
    notes = adequacy.failed_notes(checks)
    failed = [t for t in checks if not t["passed"]]
    standing = _standing(explanations, bool(failed))
    if not standing:
        if not failed:
            excess = ctx.excess_rmse()
            ratio = excess / ctx.noise_floor if ctx.noise_floor > 0 else float("inf")
            return (
                "adequate",
                (
                    "the residual is consistent with noise: error above the noise floor "
                    f"{excess:.4f} m/s^2 ({ratio:.2f}x the noise of {ctx.noise_floor:.4f} "
                    "m/s^2), as white as the resting noise, the parameters agree across "
                    "runs; no explanation tried improves BIC enough"
                ),
                notes,
                None,
                None,
            )
        why = "; ".join(str(t["text"]) for t in failed)
        verdict = "effect missing"
        summary = (
            "no explanation tried (library effects, a parameter changed or drifting between "
            f"runs, the sensor's low-pass) accounts for it: {why}. "
            + _unknown_hint(tests)
            + " Write a user effect for it (README: 'Writing your own effect')."
        )
        return verdict, summary, notes, None, None
    best = standing[0]
    how = arena.confound(best, inp.trials, inp.runs)
    rival = next((e for e in standing[1:] if _rivals(best, e, how is not None)), None)
    if rival is not None and how is None and _refine_close(explanations, standing, inp):
        # the close ones were refitted to convergence: rank them again
        standing = _standing(explanations, bool(failed))
        best = standing[0]
        how = arena.confound(best, inp.trials, inp.runs)
        rival = next((e for e in standing[1:] if _rivals(best, e, how is not None)), None)
    verdict = best.verdict
    summary = _explanation_sentence(best, fit)
    ambiguity = None
    if how is not None and rival is None:
        rival = next((e for e in standing[1:] if e.kind == "effect"), None)
    if rival is not None:
        hint = (
            arena.record_hint(best, how, inp.trials)
            if how is not None
            else _tell_apart(best, rival)
        )
        ambiguity = {
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
        notes.append(
            Note("diagnose.confounded" if how else "diagnose.ambiguous", text, None, "warning")
        )
        verdict = "ambiguous"
        summary = text + ". Best: " + summary
    if best.kind == "sensor":
        notes.append(Note("diagnose.sensor", summary, None, "warning"))
    if best.kind == "discovered":
        summary = f"{summary} {_unknown_hint(tests)}"
        notes.append(Note("diagnose.discovered", summary, None, "warning"))
    return verdict, summary, notes, ambiguity, best


def _unknown_hint(tests: ResidualTests) -> str:
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
        + (f"; spectrum peak at {peaks[0]['frequency_hz']:.2f} Hz" if peaks else "")
        + "."
    )


def _tell_apart(best: Explanation, rival: Explanation) -> str:
    kinds = {best.kind, rival.kind}
    both = [*best.parameters, *(p for p in rival.parameters if p not in best.parameters)]
    if kinds <= {"split", "drift", "pair"} and best.verdict == rival.verdict and len(both) > 1:
        return (
            "record each thrust level, up and down, at the start and again at the end of "
            f"the session: {' and '.join(both)} change the response differently across "
            "thrust levels and directions, so the change seen at every level tells which "
            "one moved"
        )
    if "sensor" in kinds:
        return (
            "record a few seconds at rest with the sensor on the frame (its noise spectrum "
            "shows the sensor's filter) and one step with a second, unfiltered sensor"
        )
    if kinds & {"split", "drift", "pair"}:
        return (
            "repeat the first run at the end of the session: a change or drift of the "
            "balancer shows as a different result, a missing effect as the same"
        )
    return "record more thrust levels in both directions"


def _explanation_sentence(e: Explanation, fit: FitResult) -> str:
    d = e.detail
    head = (
        f"{e.label} lowers BIC by {e.delta_bic:.0f} and removes {e.excess_drop:.0%} of the "
        "error above the noise floor"
    )
    if e.kind == "effect":
        return f"adding {e.effects[0]}: {head}. Fit it: {fit.command(_model_for(fit, e))}"
    if e.kind == "discovered":
        alts = [a for a in d.get("alternatives", []) or []]  # type: ignore[union-attr]
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
    if "split_after_run" in d:
        k = int(d["split_after_run"])  # type: ignore[arg-type]
        n = int(str(d["group_by"]).rsplit("-", 1)[-1])
        p = e.parameters[0]
        u = " kg" if p == "m_a" else ""
        first = "run 1" if k == 1 else f"runs 1-{k}"
        second = f"run {n}" if k + 1 == n else f"runs {k + 1}-{n}"
        return (
            f"{p} is {float(d['before']):.3g}{u} in {first} and "  # type: ignore[arg-type]
            f"{float(d['after']):.3g}{u} in {second}: "  # type: ignore[arg-type]
            f"the payload or the balancer's setting changed between runs {k} and {k + 1}"
            + (f" (with {e.effects[0]} added)" if e.effects else "")
            + f"; {head}. Fit each group on its own: {fit.command()} --group-by "
            + shlex.quote(str(d["group_by"]))
        )
    if d.get("drift"):
        p = e.parameters[0]
        return (
            f"{p} drifts from {float(d['first_run']):.3g} in the first run to "  # type: ignore[arg-type]
            f"{float(d['last_run']):.3g} in the last (oil warming, wear)"  # type: ignore[arg-type]
            + (f", with {e.effects[0]} added" if e.effects else "")
            + f"; {head}"
        )
    if e.kind == "sensor":
        if e.delta_bic <= BIC_THRESHOLD:
            values = d.get("values") or {}
            now = fit.match.values()
            moved = [
                f"{k} {float(values[k]):.4g} with it, {now[k]:.4g} without"  # type: ignore[index]
                for k in ("T_a", "m_a")
                if k in values and k in now
            ]
            head = (
                f"the response fits as well with it (BIC {-e.delta_bic:+.0f}), and without it "
                "the balancer's parameters hold the sensor's lag"
                + (f" ({'; '.join(moved)})" if moved else "")
            )
        return (
            f"the accelerometer smooths its signal: a low-pass at {float(d['cutoff_hz']):.1f} Hz "  # type: ignore[arg-type]
            f"(the resting noise rolls off at {float(d['rest_noise_cutoff_hz']):.1f} Hz, "  # type: ignore[arg-type]
            f"as a filter's, not as coloured noise's); {head}. Not the balancer: record with "
            "the sensor's filter off or a higher bandwidth, or read its delay as part of the "
            "sensor"
        )
    return head


def _model_for(fit: FitResult, e: Explanation) -> str:
    v = e.detail.get("values")
    spec = fit.model
    return f"{spec}+{e.effects[0]}" if e.effects and v is not None else spec


def _groups_record(best: Explanation, per: list, runs_of_per: list[str]) -> dict[str, object]:
    """CONTRACT.md ``parameter_groups`` of a split, with the per-run estimates."""
    from scipy.special import chdtrc

    from balancer_id.diagnostics.groups import run_estimates

    d = best.detail
    name = best.parameters[0]
    n = int(best.detail.get("n_samples", 0) or 0)
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


#: A candidate, its signature, its refit and why its signature check failed (or None).
Refitted = tuple[Candidate, Signature, Refit, str | None]

#: Threads running the diagnosis's fits at once (candidate refits, the arena's splits and
#: drifts; the kernels release the GIL); None: one per core.
REFIT_THREADS: int | None = None


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
    from concurrent.futures import ThreadPoolExecutor, as_completed

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

    threads = min(len(cands), threads or REFIT_THREADS or os.cpu_count() or 1)
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


def independence(match: MatchResult) -> float:
    """Effective share of independent samples in a fit's residual, ``(1 - r1) / (1 + r1)``.

    Parameters
    ----------
    match : MatchResult
        A fit; ``r1`` is the lag-one autocorrelation of its residual, averaged over trials.

    Returns
    -------
    float
        1 for a white residual, smaller for a correlated one (at least 0.05).
    """
    r1s, weights = [], []
    for sl in match.data.slices():
        r = match.residual[sl]
        r = r - np.mean(r)
        denom = float(r @ r)
        if r.size > 10 and denom > 0:
            r1s.append(float(r[:-1] @ r[1:]) / denom)
            weights.append(r.size)
    if not r1s:
        return 1.0
    r1 = max(float(np.average(r1s, weights=weights)), 0.0)
    return float(min(max((1.0 - r1) / (1.0 + r1), 0.05), 1.0))


def excess_drop(rmse_before: float, rmse_after: float, noise_floor: float) -> float:
    """Share of the error above the noise floor that a change removes.

    ``(rmse_before^2 - rmse_after^2) / (rmse_before^2 - min(floor, rmse_after)^2)``: the
    floor is capped at the new RMSE, so a floor estimated a little too high (it is itself
    noisy) cannot hide a real improvement.

    Parameters
    ----------
    rmse_before : float
        RMSE of the acceleration before the change (m/s^2).
    rmse_after : float
        RMSE after the change (m/s^2).
    noise_floor : float
        White noise level of the acceleration (m/s^2).

    Returns
    -------
    float
        The share removed, at most 1 and at least -10 (a change for the worse); 0 when
        there is no error above the floor.
    """
    floor = min(noise_floor, rmse_after)
    denom = rmse_before**2 - floor**2
    if denom <= 0:
        return 0.0
    return float(max(min((rmse_before**2 - rmse_after**2) / denom, 1.0), -10.0))


def _thin(xc: dict[str, object]) -> dict[str, object]:
    keep = dict(xc)
    keep.pop("lag_s", None)
    keep.pop("mean_residual", None)
    return keep


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


def _verdict(
    ctx: DiagnosisContext, tests: ResidualTests, suggestions: list[Suggestion]
) -> tuple[str, str]:
    white = tests.whiteness
    excess = ctx.excess_rmse()
    ratio = excess / ctx.noise_floor if ctx.noise_floor > 0 else np.inf
    if suggestions and is_missing(suggestions[0]):
        s = suggestions[0]
        return "effect missing", (
            f"adding {s.effect} lowers BIC by {s.delta_bic:.0f} and removes "
            f"{s.excess_drop:.0%} of the error above the noise floor; "
            f"evidence: {s.signature.evidence}"
        )
    p = white.get("ljung_box_p")
    if p is not None and p < 1e-6 and ratio > 0.5:
        where = tests.worst_windows[0] if tests.worst_windows else None
        corr = tests.state_correlation
        name, r = max(corr.items(), key=lambda kv: abs(kv[1])) if corr else ("-", 0.0)
        peaks = tests.spectrum["peaks"]
        return "effect missing", (
            "no effect in the library explains the residual: it is not white (Ljung-Box "
            f"p = {p:.1e}) and the error above the noise floor is {ratio:.1f}x the noise; "
            + (
                f"worst in trial {where['trial']} at "
                f"{where['t_start']:.2f}-{where['t_end']:.2f} s; "
                if where
                else ""
            )
            + f"it follows the {name} (r = {r:+.2f})"
            + (f"; spectrum peak at {peaks[0]['frequency_hz']:.2f} Hz" if peaks else "")
            + ". Write a user effect for it (README: 'Writing your own effect')."
        )
    return "adequate", (
        f"the residual is consistent with noise: error above the noise floor "
        f"{excess:.4f} m/s^2 ({ratio:.2f}x the noise of {ctx.noise_floor:.4f} m/s^2); "
        "no effect in the library improves BIC enough"
    )


def parameter_drift(fit: FitResult) -> list[dict[str, object]]:
    """Per-trial refits of the current model: slope of each parameter against thrust
    and the up/down difference, with their significance.

    Parameters
    ----------
    fit : FitResult
        The joint fit; its per-trial fits (:meth:`FitResult.per_trial_fits`, computed once
        and kept) are used. Fewer than three trials give no rows.

    Returns
    -------
    list of dict
        One row per parameter with at least three finite standard errors:
        ``parameter``, the per-trial ``values``, the weighted ``slope_per_N`` against
        ``|thrust|`` and its ``slope_z`` (when the thrusts differ), and ``up_minus_down``
        (when both directions occur).
    """
    match = fit.match
    if len(match.data.trials) < 3:
        return []
    per = fit.per_trial_fits()
    rows = []
    for name in match.model.param_names:
        vals = [(abs(p.thrust_N), p.direction, p.values[name], p.stderr.get(name)) for p in per]
        vals = [v for v in vals if v[3] is not None and np.isfinite(v[3]) and v[3] > 0]
        if len(vals) < 3:
            continue
        h, d, x, s = zip(*vals, strict=True)
        h, x, s = np.array(h), np.array(x), np.array(s)
        w = 1 / s**2
        row: dict[str, object] = {"parameter": name, "values": [float(v) for v in x]}
        if np.ptp(h) > 0:
            A = np.column_stack([np.ones_like(h), h])
            cov = np.linalg.pinv(A.T @ (A * w[:, None]))
            coef = cov @ (A.T @ (w * x))
            row["slope_per_N"] = float(coef[1])
            row["slope_z"] = float(coef[1] / np.sqrt(cov[1, 1]))
        up = [xi for xi, di in zip(x, d, strict=True) if di == "up"]
        dn = [xi for xi, di in zip(x, d, strict=True) if di == "down"]
        if up and dn:
            row["up_minus_down"] = float(np.mean(up) - np.mean(dn))
        rows.append(row)
    return rows
