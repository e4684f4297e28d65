"""``diagnose``: the residual tests, the arena of explanations and the verdict.

``diagnose`` is a pipeline of named stages: the residual tests, the adequacy checks,
the library candidates' refits (the suggestions), the arena (every kind of
:data:`~balancer_id.diagnostics.explanations.KINDS`, stage by stage), the verdict and
the suggestions it offers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from balancer_id.diagnosis_fields import DIAGNOSIS_FIELDS, fact_lines
from balancer_id.diagnostics import adequacy, arena
from balancer_id.diagnostics import discover as discovery_search
from balancer_id.diagnostics.arena import (
    BIC_THRESHOLD,
    CLOSE_BIC,
    FLOOR_DROP,
    MIN_EXCESS_DROP,
    ArenaInput,
    Explanation,
    excess_drop,
    independence,
)
from balancer_id.diagnostics.context import DiagnosisContext, build_context
from balancer_id.diagnostics.explanations import Verdict, run_arena
from balancer_id.diagnostics.explanations.discovered import Discovered
from balancer_id.diagnostics.explanations.sensor_lowpass import rest_cutoff
from balancer_id.diagnostics.residual_tests import (
    ResidualTests,
    input_correlation,
    regime_table,
    spectrum_peaks,
    state_correlations,
    whiteness,
    worst_windows,
)
from balancer_id.diagnostics.rival_ambiguity import ambiguous_by_rival
from balancer_id.diagnostics.suggest import Suggestion, is_missing, suggest
from balancer_id.diagnostics.verdict import (
    CLOSE_SHARE,
    groups_record,
    judge,
    offered,
    rivals,
    tell_apart,
)
from balancer_id.identify.display import CallableText, Displayable
from balancer_id.identify.matching import MatchResult
from balancer_id.identify.result import FitResult
from balancer_id.notes import Note, as_note, texts
from balancer_id.records import DiagnosisRecord, ReadsBack

__all__ = [
    "BIC_THRESHOLD",
    "CLOSE_BIC",
    "CLOSE_SHARE",
    "FLOOR_DROP",
    "MIN_EXCESS_DROP",
    "Diagnosis",
    "ResidualTests",
    "Suggestion",
    "diagnose",
    "excess_drop",
    "independence",
    "is_missing",
    "parameter_drift",
]

#: Old names of the verdict's helpers (tests and scripts import them from here).
_rivals, _tell_apart = rivals, tell_apart

#: Threads running the diagnosis's fits at once (candidate refits, the arena's splits and
#: drifts; the kernels release the GIL); None: one per core.
REFIT_THREADS: int | None = None


@dataclass(repr=False, frozen=True)
class Diagnosis(Displayable, ReadsBack):
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
    #: What the JSON reads back as (:meth:`from_dict`).
    record: ClassVar[type[DiagnosisRecord]] = DiagnosisRecord

    def __post_init__(self) -> None:
        # ``diagnosis.summary`` is the verdict's paragraph; ``diagnosis.summary()`` the
        # full lmfit-style text (as every result of the API has)
        object.__setattr__(self, "summary", CallableText(str(self.summary), self._summary_text))

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
        if self.verdict == Verdict.ADEQUATE:
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

    def _fact_values(self) -> dict[str, object]:
        """The JSON values of the fields shown as one line (not the whole object)."""
        from balancer_id.jsonsafe import json_ready

        return {f.key: json_ready(f.of(self)) for f in DIAGNOSIS_FIELDS if f.line is not None}

    def _summary_extra(self) -> list[str]:
        lines = ["[[Diagnosis]]", f"    verdict: {self.verdict}", f"    {self.summary!s}"]
        lines += [f"    {t}" for t in fact_lines(self._fact_values())]
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
            for found in d.terms:
                se = f" +/- {found.stderr:.2g}" if found.stderr is not None else ""
                lines.append(
                    f"    {found.expression}: {found.coefficient:.4g}{se} {found.term.unit},"
                    f" kept in {found.inclusion:.0%} of the bootstrap resamples"
                )
            lines.append(f"    {d.command}")
        return lines

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``diagnose`` object: each of
        :data:`~balancer_id.diagnosis_fields.DIAGNOSIS_FIELDS`, in order."""
        from balancer_id.jsonsafe import json_ready

        out: dict[str, object] = json_ready({f.key: f.of(self) for f in DIAGNOSIS_FIELDS})
        return out


def diagnose(
    fit: FitResult,
    *,
    threads: int | None = None,
    discover: bool = True,
    extra_terms: Sequence[discovery_search.Term] = (),
) -> Diagnosis:
    """Test the residual of a fit and rank the explanations of what it misses.

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
    threads = threads or REFIT_THREADS
    ctx = build_context(fit.match)
    tests = residual_tests(fit, ctx)
    checks = adequacy_checks(fit, ctx)
    suggestions, failures = suggest(fit, ctx, threads)
    inp = arena_input(fit, ctx, checks, suggestions, threads, discover, extra_terms)
    explanations = run_arena(inp)
    judgement = judge(ctx, tests, checks, inp, fit)
    ambiguous_by_rival(judgement, fit)  # a rival model that fits as well (issue 31)
    if judgement.best is not None and judgement.verdict == Verdict.PARAMETER_CHANGED:
        tests.parameter_groups = groups_record(judgement.best, *_per_trial(fit))
    return Diagnosis(
        fit=fit,
        context=ctx,
        tests=tests,
        suggestions=offered(suggestions, judgement),
        verdict=judgement.verdict,
        summary=judgement.summary,
        failures=failures + inp.failures,
        explanations=explanations,
        checks=checks,
        notes=judgement.notes,
        ambiguity=judgement.ambiguity,
        discovery=next((e.source for e in explanations if e.kind == Discovered.kind), None),  # type: ignore[arg-type]
    )


def residual_tests(fit: FitResult, ctx: DiagnosisContext) -> ResidualTests:
    """The residual tests of a fit (CONTRACT.md ``residual_tests``).

    Parameters
    ----------
    fit : FitResult
    ctx : DiagnosisContext

    Returns
    -------
    ResidualTests
    """
    classic = fit.classic
    xcorr = input_correlation(ctx)
    return ResidualTests(
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


def adequacy_checks(fit: FitResult, ctx: DiagnosisContext) -> list[dict[str, object]]:
    """The tests an ``adequate`` verdict must pass: level, colour, consistency.

    Parameters
    ----------
    fit : FitResult
    ctx : DiagnosisContext

    Returns
    -------
    list of dict
    """
    match, classic = fit.match, fit.classic
    per, runs_of_per = _per_trial(fit)
    colour = adequacy.colour_test(ctx)
    return [
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


def arena_input(
    fit: FitResult,
    ctx: DiagnosisContext,
    checks: list[dict[str, object]],
    suggestions: list[Suggestion],
    threads: int | None,
    discover: bool,
    extra_terms: Sequence[object],
) -> ArenaInput:
    """What every kind of explanation sees: the fit, its trials, the noise and its colour.

    Parameters
    ----------
    fit : FitResult
    ctx : DiagnosisContext
    checks : list of dict
        The adequacy checks (the colour test's resting autocorrelation is the noise's).
    suggestions : list of Suggestion
        The candidates' refits (the library effects' explanations).
    threads : int or None
    discover : bool
    extra_terms : sequence of Term

    Returns
    -------
    ArenaInput
    """
    match = fit.match
    trials = list(match.data.trials)
    colour = next(t for t in checks if t["name"] == "whiteness")
    source_of = {td.index: td.source for td in trials}
    inp = ArenaInput(
        match=match,
        trials=trials,
        runs=[source_of.get(td.index, "") for td in trials],
        noise_floor=ctx.noise_floor,
        independence=independence(match),
        effect_fits=[(s.effect, s.refit) for s in suggestions if s.refit is not None],
        rest_cutoff_hz=rest_cutoff(trials, 1.0 / ctx.dt) if ctx.dt > 0 else None,
        ar=arena.ar_coefficients(
            colour["rest_acf"], int(colour["n_rest"])  # type: ignore[arg-type, call-overload]
        ),
        threads=threads,
        tests_failed=any(not t["passed"] for t in checks),
        fit=fit,
        context=ctx,
        discover=discover,
        extra_terms=tuple(extra_terms),
    )
    rest_rss, rest_n = arena.whitened_rss(adequacy.rest_noise(ctx), inp.ar)
    inp.rest_innovation = rest_rss / rest_n if rest_n >= 50 else None
    return inp


def _per_trial(fit: FitResult) -> tuple[list, list[str]]:
    """The per-trial fits and each one's run."""
    per = fit.per_trial_fits()
    source_of = {td.index: td.source for td in fit.match.data.trials}
    return list(per), [source_of.get(p.index, "") for p in per]


def _thin(xc: dict[str, object]) -> dict[str, object]:
    keep = dict(xc)
    keep.pop("lag_s", None)
    keep.pop("mean_residual", None)
    return keep


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
        h_, d, x_, s_ = zip(*vals, strict=True)
        h, x, s = np.array(h_, float), np.array(x_, float), np.array(s_, float)
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
