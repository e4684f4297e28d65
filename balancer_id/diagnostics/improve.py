"""``improve``: add the best-supported effect, refit, and repeat while the model gets better.

A step is taken when the diagnosis calls an effect missing (BIC improvement and a real
drop of the error above the noise floor, :func:`~balancer_id.diagnostics.diagnosis.is_missing`)
*and* the error on held-out trials falls (K-fold cross-validation across trials).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from balancer_id.diagnostics.diagnosis import Diagnosis, diagnose, is_missing
from balancer_id.diagnostics.discover import Discovery
from balancer_id.errors import BalancerIdError
from balancer_id.identify.data import FitData, TrialData
from balancer_id.identify.display import Displayable
from balancer_id.identify.matching import MatchResult, match_trials
from balancer_id.identify.result import FitResult, fit_match
from balancer_id.model.spec import Model
from balancer_id.notes import Note, texts
from balancer_id.records import ImproveRecord, ReadsBack
from balancer_id.status import step
from balancer_id.verdicts import Verdict

#: Folds of the cross-validation across trials.
CV_FOLDS = 3


@dataclass(frozen=True)
class ImproveStep:
    """One rung of the ladder.

    Attributes
    ----------
    model : str
        The spec of the rung's model.
    added : str or None
        The effect added on this rung (None on the first).
    fit : FitResult
        The rung's fit (sharing the trials, paper's method and fixed values of the start).
    cv_rmse : float or None
        Held-out RMSE (m/s^2).
    evidence : str
        The signature evidence that chose the effect.
    """

    model: str
    added: str | None
    fit: FitResult
    cv_rmse: float | None
    evidence: str = ""
    #: The effect added is a discovered force (``improve --discover``).
    discovered: bool = False

    @property
    def match(self) -> MatchResult:
        """The rung's simulation-matching fit."""
        return self.fit.match

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md ``improve`` step."""
        m = self.match.metrics
        return {
            "model": self.model,
            "added": self.added,
            "rmse": m["rmse"],
            "aic": m["aic"],
            "bic": m["bic"],
            "nrmse_fit_percent": m["nrmse_fit_percent"],
            "cv_rmse": self.cv_rmse,
            "parameters": {k: p.to_dict() for k, p in self.match.parameters.items()},
            "evidence": self.evidence,
            "discovered": self.discovered,
            "command": self.fit.command(),
        }


@dataclass(repr=False, frozen=True)
class ImproveResult(Displayable, ReadsBack):
    """The ladder of models and the final diagnosis."""

    steps: list[ImproveStep]
    final: Diagnosis
    rejected: list[str] = field(default_factory=list)
    #: ``--discover``: the effect file written (``file``, ``effect``, ``formula``), or None.
    discovered: dict[str, object] | None = None
    #: ``--discover``: what happened (a file written, or why none was).
    discovery_note: Note | None = None
    #: ``--discover``: the discovery that was written and added as a step.
    discovery: Discovery | None = field(default=None, repr=False)
    #: What the JSON reads back as (:meth:`from_dict`).
    record: ClassVar[type[ImproveRecord]] = ImproveRecord

    def _shown_match(self) -> MatchResult:
        return self.steps[-1].match

    def _headline(self) -> str:
        ladder = " -> ".join(s.added or s.model for s in self.steps)
        return f"{ladder}: final {self.final_model} ({self.final.verdict})"

    def _summary_warnings(self) -> list[str]:
        return texts(self.final.fit_warnings())

    def _summary_extra(self) -> list[str]:
        lines = ["[[Ladder]] (error and BIC as effects are added)"]
        for s in self.steps:
            m = s.match.metrics
            lines.append(
                f"    {s.model}: RMSE {m['rmse']:.4g} m/s^2, BIC {m['bic']:.1f},"
                f" fit {m['nrmse_fit_percent']:.1f} %"
            )
        if self.rejected:
            lines.append(f"    rejected: {', '.join(self.rejected)}")
        if self.discovery_note is not None:
            lines.append(f"    discovery: {self.discovery_note}")
        lines.append(f"    final verdict: {self.final.verdict}")
        return lines

    @property
    def final_model(self) -> str:
        """Spec of the last accepted model."""
        return self.steps[-1].model

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``improve`` object."""
        from balancer_id.jsonsafe import json_ready

        return json_ready(
            {
                "steps": [s.to_dict() for s in self.steps],
                "final_model": self.final_model,
                "final_verdict": self.final.verdict,
                "final_summary": self.final.summary,
                "rejected": self.rejected,
                "discovered": self.discovered,
                "discovery_note": (
                    self.discovery_note.to_dict() if self.discovery_note is not None else None
                ),
            }
        )


def cross_validated_rmse(
    model: Model,
    trials: Sequence[TrialData],
    start: Mapping[str, float],
    fixed: Mapping[str, float] | None = None,
    folds: int = CV_FOLDS,
) -> float | None:
    """RMSE on held-out trials: fit on the others, predict the fold, over K folds.

    Parameters
    ----------
    model : Model
        The model to cross-validate.
    trials : sequence of TrialData
        All trials; trial ``i`` is held out in fold ``i % folds``.
    start : mapping of str to float
        Start values of every fold's fit (usually the joint fit).
    fixed : mapping of str to float, optional
        Parameters held at these values.
    folds : int
        Number of folds K (at most the number of trials).

    Returns
    -------
    float or None
        RMSE of the predicted acceleration over all held-out samples (m/s^2), or None
        with fewer than three trials or when a fold's fit fails.
    """
    n = len(trials)
    if n < 3:
        return None
    k = min(folds, n)
    sq, count = 0.0, 0
    for j in range(k):
        test = [t for i, t in enumerate(trials) if i % k == j]
        train = [t for i, t in enumerate(trials) if i % k != j]
        try:
            m = match_trials(model, train, start=start, fixed=fixed, max_nfev=300)
        except BalancerIdError:
            return None
        values = m.values()
        data = FitData.build(test)
        out = data.packed.run(model, np.array([values[p] for p in model.param_names]))
        r = data.y - out[:, 0]
        sq += float(r @ r)
        count += r.size
    return float(np.sqrt(sq / count))


def improve(
    fit: FitResult,
    *,
    max_steps: int = 4,
    diagnosis: Diagnosis | None = None,
    discover_to: str | Path | None = None,
    overwrite: bool = False,
) -> ImproveResult:
    """Climb the ladder from a fit: add the best-supported effect while it helps.

    Parameters
    ----------
    fit : FitResult
        The fit of the starting model (its trials, fixed values, effect files and
        reference move carry over to every rung and every printed command).
    max_steps : int
        Effects to add at most.
    diagnosis : Diagnosis, optional
        The diagnosis of ``fit`` when it is already made (it is not made again).
    discover_to : str or Path, optional
        ``--discover --effects-out FILE.py``: when, after the library's effects, the
        diagnosis discovers a missing force, write it to this file as a user effect, add
        it as a step and refit; when nothing is missing, no file is written (the result's
        ``discovery_note`` says so).
    overwrite : bool
        Replace ``discover_to`` when a previous ``--discover`` wrote it (a file of the
        user's is never replaced).

    Returns
    -------
    ImproveResult
    """
    trials = list(fit.match.data.trials)
    fixed = fit.fixed or None
    current = fit
    cv = cross_validated_rmse(current.spec_model, trials, current.values, fixed)
    steps = [ImproveStep(current.model, None, current, cv)]
    rejected: list[str] = []
    if diagnosis is None or diagnosis.fit is not fit:
        with step(f"step 1: {current.model}"):
            diagnosis = diagnose(current)
    for k in range(max_steps):
        chosen = None
        for s in diagnosis.suggestions:
            if s.null:  # the effect's parameter sits where it does nothing: no step
                rejected.append(f"{s.label}: its parameters sit at the value that does nothing")
                continue
            if not is_missing(s) or s.refit is None:
                break
            cv_new = cross_validated_rmse(s.refit.model, trials, s.refit.values(), fixed)
            if cv is not None and cv_new is not None and cv_new >= cv:
                rejected.append(
                    f"{s.label}: BIC falls by {s.delta_bic:.0f} but the held-out error does not "
                    f"({cv_new:.4f} vs {cv:.4f} m/s^2)"
                )
                continue
            chosen = (s, cv_new)
            break
        if chosen is None:
            break
        s, cv = chosen
        assert s.refit is not None  # a chosen suggestion was refitted
        current = fit_match(
            s.refit,
            fit.trial_set,
            classic=fit.classic,
            fixed=fit.held(s.refit.model),
            effects_files=fit.effects_files,
        )
        steps.append(ImproveStep(current.model, s.effect, current, cv, s.signature.evidence))
        with step(f"step {k + 2}: {current.model}"):
            diagnosis = diagnose(current)
    result = ImproveResult(steps, diagnosis, rejected)
    if discover_to is not None:
        result = _discover_step(result, trials, discover_to, overwrite)
    return result


def _discover_step(
    result: ImproveResult, trials: list[TrialData], path: str | Path, overwrite: bool
) -> ImproveResult:
    """Write the last diagnosis's discovered force as an effect file, add it and refit
    (``result`` with the step added, or with why none was)."""
    from balancer_id.diagnostics.discover import write_effect
    from balancer_id.model.registry import Registry

    found = result.final.discovery
    current = result.steps[-1].fit
    if found is None:
        why = (
            "nothing is missing"
            if result.final.verdict == Verdict.ADEQUATE
            else "no force in the candidate terms explains what is missing better than the "
            "explanations tried"
        )
        return replace(result, discovery_note=Note(
            "improve.no_discovery", f"{why}: no effect file written ({path})", None, "info"
        ))
    fixed = current.fixed or None
    cv_old = result.steps[-1].cv_rmse
    cv_new = cross_validated_rmse(found.refit.model, trials, found.refit.values(), found.fixed)
    if cv_old is not None and cv_new is not None and cv_new >= cv_old:
        result.rejected.append(
            f"discovered {found.formula}: BIC falls by {found.delta_bic:.0f} but the held-out "
            f"error does not ({cv_new:.4f} vs {cv_old:.4f} m/s^2)"
        )
        return replace(result, discovery_note=Note(
            "improve.no_discovery",
            f"the discovered force does not lower the held-out error: no effect file written "
            f"({path})",
            None,
            "info",
        ))
    evidence = (
        f"Held-out RMSE {cv_new:.4g} m/s^2 (before {cv_old:.4g})."
        if cv_new is not None and cv_old is not None
        else ""
    )
    path, name = write_effect(found, path, evidence=evidence, overwrite=overwrite)
    registry = Registry(list(current.spec_model.registry))
    if name in registry:  # a file of the same name loaded before: the new one replaces it
        registry = Registry([c for c in registry if c.name != name])
    (cls,) = registry.load_file(path)
    model = Model((*current.spec_model.effects, cls), registry)
    values = {**found.refit.values(), **{t.term.name: t.coefficient for t in found.terms}}
    start = {n: values[n] for n in model.param_names if n in values}
    with step(f"step {len(result.steps) + 1}: {model.spec} (discovered)"):
        match = match_trials(model, trials, start=start, fixed=fixed)
        new = fit_match(
            match,
            current.trial_set,
            classic=current.classic,
            fixed=current.held(model),
            effects_files=[*current.effects_files, str(path)],
        )
        added = ImproveStep(new.model, name, new, cv_new, found.formula, True)
        final = diagnose(new)
    return replace(
        result,
        steps=[*result.steps, added],
        final=final,
        discovered={"file": str(path), "effect": name, "formula": found.formula},
        discovery=found,
        discovery_note=Note(
            "improve.discovered",
            f"wrote {path}: effect '{name}', {found.formula} (N); load it with "
            f"--effects-file {path}",
            None,
            "info",
        ),
    )
