"""Fits that share across logs: some parameters each log's own, the rest shared
(``fit LOG... --per-log m_a``, issue 33).

One fit over all logs (:func:`~balancer_id.identify.grouped.fit_grouped`, a group per
log) gives each log's own values and the shared ones; the shared ones are pinned by every
log at once. The same logs are also fitted with everything shared (one joint fit) and
with nothing shared (each log alone), and the three are compared:

* by BIC, with the likelihood of a residual correlated over ``tau`` samples counted on
  ``n / tau`` effective samples (the same ``tau`` for all three, the richest model's), so
  that a correlated residual does not make every extra parameter look significant;
* on held-out data: for up to :data:`MAX_HELD_OUT` logs, each model is fitted without
  that log, the log's own parameters are then fitted on its first half of trials (the
  shared ones held), and the second half is predicted; the RMSE of those predictions.

The model the data support is the one of lowest BIC; the held-out errors are shown
beside it (they rank the same way when the logs are long enough to tell).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from balancer_id.errors import IdentificationError, UsageError
from balancer_id.identify.data import TrialData, group_trials
from balancer_id.identify.grouped import fit_grouped
from balancer_id.identify.matching import ParameterEstimate, evaluate_trials, match_trials
from balancer_id.identify.metrics import correlation_time
from balancer_id.model.spec import Model

#: Held-out logs at most (each costs three fits of the other logs).
MAX_HELD_OUT = 4
#: A BIC difference this large is "strong" evidence (Kass and Raftery: 6 to 10).
STRONG_BIC = 6.0
MODELS = ("all shared", "partly shared", "all separate")


@dataclass
class ModelScore:
    """One sharing model's fit and held-out error."""

    name: str
    rss: float
    n_samples: int
    n_free: int
    bic: float = float("nan")
    held_out_rmse: float | None = None

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "rss": self.rss,
            "n_samples": self.n_samples,
            "n_free": self.n_free,
            "bic": self.bic,
            "held_out_rmse": self.held_out_rmse,
        }


@dataclass(repr=False)
class PerLogFit:
    """The outcome of a fit with per-log parameters (``bid.fit(logs, per_log=[...])``).

    Attributes
    ----------
    model : Model
        The model.
    per_log : list of str
        The parameters each log has its own value of.
    logs : list of str
        The logs, in order.
    shared : dict of str to ParameterEstimate
        The shared parameters (fitted over all logs; held ones marked).
    own : list of dict of str to ParameterEstimate
        Each log's own parameters.
    separate : list of dict of str to ParameterEstimate
        Each log fitted alone (every parameter its own), for comparison.
    scores : dict of str to ModelScore
        ``all shared``, ``partly shared``, ``all separate``.
    supported : str
        The model of lowest BIC.
    tau : float
        The residual's correlation time (samples) the criteria count with.
    notes : list of str
        What else the user should know.
    """

    model: Model
    per_log: list[str]
    logs: list[str]
    shared: dict[str, ParameterEstimate]
    own: list[dict[str, ParameterEstimate]]
    separate: list[dict[str, ParameterEstimate]]
    scores: dict[str, ModelScore]
    supported: str
    tau: float
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, object]:
        """The JSON object of ``fit --per-log`` (docs/CONTRACT.md)."""
        from balancer_id.jsonsafe import json_ready

        return json_ready(
            {
                "model": self.model.spec,
                "per_log": self.per_log,
                "files": self.logs,
                "shared": {k: p.to_dict() for k, p in self.shared.items()},
                "logs": [
                    {
                        "file": log,
                        "own": {k: p.to_dict() for k, p in own.items()},
                        "alone": {k: p.to_dict() for k, p in alone.items()},
                    }
                    for log, own, alone in zip(self.logs, self.own, self.separate, strict=True)
                ],
                "comparison": {k: s.to_dict() for k, s in self.scores.items()},
                "supported": self.supported,
                "verdict": self.verdict(),
                "residual_correlation_samples": self.tau,
                "notes": self.notes,
            }
        )

    def verdict(self) -> str:
        """One sentence: which sharing the data support, and how strongly."""
        best = self.scores[self.supported].bic
        others = sorted(s.bic - best for k, s in self.scores.items() if k != self.supported)
        margin = others[0] if others else float("inf")
        strength = "strongly" if margin >= STRONG_BIC else "weakly"
        what = {
            "all shared": "one set of values for every log (the logs do not differ in "
            + ", ".join(self.per_log) + ")",
            "partly shared": f"{', '.join(self.per_log)} of each log's own, the rest shared",
            "all separate": "every parameter of each log's own (more differs between the "
            "logs than " + ", ".join(self.per_log) + ")",
        }[self.supported]
        return f"the data {strength} support {what} (BIC lower by {margin:.1f})"

    def lines(self) -> list[str]:
        """The terminal's and notebook's text (:func:`per_log_lines`)."""
        return per_log_lines(self.to_dict())

    def __repr__(self) -> str:
        return "\n".join(self.lines())

    def summary(self) -> str:
        """The result as text.

        Returns
        -------
        str
        """
        return "\n".join(self.lines())

    def _repr_html_(self) -> str:
        import html

        return "<pre>" + html.escape("\n".join(self.lines())) + "</pre>"


def _est(p: ParameterEstimate) -> str:
    if p.stderr is None:
        return f"{p.value:.4g} (held)" if not p.vary else f"{p.value:.4g}"
    return f"{p.value:.4g} ± {p.stderr:.2g}"


def per_log_lines(doc: Mapping[str, object]) -> list[str]:
    """The text of a per-log fit's JSON (terminal and notebook).

    Parameters
    ----------
    doc : mapping
        :meth:`PerLogFit.to_dict`.

    Returns
    -------
    list of str
    """

    def fmt(p: Mapping[str, object]) -> str:
        v, se = p.get("value"), p.get("stderr")
        if se is None:
            return f"{v:.4g} (held)" if not p.get("vary", True) else f"{v:.4g}"
        return f"{v:.4g} ± {se:.2g}"

    shared = doc["shared"]
    logs = doc["logs"]
    assert isinstance(shared, Mapping) and isinstance(logs, list)
    per_log = list(doc["per_log"])  # type: ignore[call-overload]
    out = [f"model {doc['model']}: {', '.join(per_log)} per log, the rest shared"]
    out.append(
        "shared over all logs: "
        + ", ".join(f"{k} = {fmt(p)} {p.get('unit', '')}".rstrip() for k, p in shared.items())
    )
    out.append("each log's own (and the same parameters fitted to the log alone):")
    for row in logs:
        own = ", ".join(
            f"{k} = {fmt(p)} (alone {fmt(row['alone'][k]) if k in row['alone'] else '-'})"
            for k, p in row["own"].items()
        )
        out.append(f"  {row['file']}: {own}")
    out.append("sharing compared (BIC on effective samples; held-out logs' second halves):")
    comparison = doc["comparison"]
    assert isinstance(comparison, Mapping)
    for name, s in comparison.items():
        held = s.get("held_out_rmse")
        held_text = f"{held:.4g} m/s^2" if held is not None else "-"
        mark = "  <- supported" if name == doc["supported"] else ""
        out.append(
            f"  {name:<14} BIC {s['bic']:.1f}, {s['n_free']} parameters, "
            f"held-out RMSE {held_text}{mark}"
        )
    out.append(f"verdict: {doc['verdict']}")
    notes = doc.get("notes") or []
    assert isinstance(notes, list)
    out += [f"note: {n}" for n in notes]
    return out


def _bic(rss: float, n: int, k: int, tau: float) -> float:
    ne = n / max(tau, 1.0)
    return float(ne * np.log(rss / n) + k * np.log(ne))


def _rss(match) -> float:
    r = match.residual
    return float(r @ r)


def _halves(trials: Sequence[TrialData]) -> tuple[list[TrialData], list[TrialData]] | None:
    """A log's trials in two halves (calibrate on the first, predict the second)."""
    if len(trials) < 2:
        return None
    k = len(trials) // 2
    return list(trials[:k]), list(trials[k:])


def fit_per_log(
    model: Model,
    data: Sequence[TrialData],
    per_log: Sequence[str],
    *,
    start: Mapping[str, float] | None = None,
    fixed: Mapping[str, float] | None = None,
    held_out: bool = True,
) -> PerLogFit:
    """Fit ``per_log`` parameters per log and the rest over all logs; compare sharings.

    Parameters
    ----------
    model : Model
        The model.
    data : sequence of TrialData
        All logs' trials, in order (their ``source`` names the log).
    per_log : sequence of str
        The parameters each log has its own value of.
    start : mapping of str to float, optional
        Start values (the paper's method's, or the user's).
    fixed : mapping of str to float, optional
        Held parameters (shared).
    held_out : bool
        Also score each sharing on held-out logs.

    Returns
    -------
    PerLogFit

    Raises
    ------
    UsageError
        Fewer than two logs, or a parameter that is not free in the model.
    IdentificationError
        A fit that cannot be made.
    """
    fixed = dict(fixed or {})
    per_log = list(dict.fromkeys(per_log))
    for name in per_log:
        if name not in model.param_names:
            raise UsageError(
                f"--per-log {name}: not a parameter of '{model.spec}' "
                f"(its parameters: {', '.join(model.param_names)})"
            )
        if name in fixed:
            raise UsageError(f"--per-log {name}: it is held with --fix; give a fitted parameter")
    groups = group_trials(data, "log")
    if len(groups) < 2:
        raise UsageError(
            "--per-log needs two or more logs (one log has no other to share with); "
            "give several logs of one balancer type"
        )
    labels = [g[0] for g in groups]
    trials = [g[1] for g in groups]
    joint = match_trials(model, data, start=start, fixed=fixed)
    values = joint.values()
    partly = fit_grouped(model, trials, per_log, start=values, fixed=fixed)
    alone = []
    for group in trials:
        try:
            alone.append(match_trials(model, group, start=values, fixed=fixed))
        except IdentificationError as exc:
            raise IdentificationError(f"{group[0].source}: fitted alone: {exc}") from exc
    segs = [
        m.residual[sl] for m in alone for sl in m.data.slices()
    ]
    tau = max(correlation_time([x - x.mean() for x in segs if x.size]), 1.0)
    n = partly.n_samples
    free_joint = sum(1 for p in joint.parameters.values() if p.vary)
    free_alone = sum(sum(1 for p in m.parameters.values() if p.vary) for m in alone)
    scores = {
        "all shared": ModelScore("all shared", _rss(joint), n, free_joint),
        "partly shared": ModelScore("partly shared", partly.rss, n, partly.n_free),
        "all separate": ModelScore(
            "all separate", float(sum(_rss(m) for m in alone)), n, free_alone
        ),
    }
    for s in scores.values():
        s.bic = _bic(s.rss, s.n_samples, s.n_free, tau)
    notes: list[str] = []
    if held_out:
        _score_held_out(model, trials, per_log, values, fixed, scores, notes)
    supported = min(scores, key=lambda k: scores[k].bic)
    if not partly.converged:
        notes.append("the shared fit stopped before its steps became small; its values may move")
    return PerLogFit(
        model=model,
        per_log=per_log,
        logs=labels,
        shared=partly.shared,
        own=partly.own,
        separate=[{k: m.parameters[k] for k in model.param_names} for m in alone],
        scores=scores,
        supported=supported,
        tau=tau,
        notes=notes,
    )


def _score_held_out(
    model: Model,
    trials: list[list[TrialData]],
    per_log: list[str],
    values: Mapping[str, float],
    fixed: Mapping[str, float],
    scores: dict[str, ModelScore],
    notes: list[str],
) -> None:
    """Held-out RMSE of each sharing (see the module's docstring)."""
    picks = np.unique(np.linspace(0, len(trials) - 1, min(MAX_HELD_OUT, len(trials))).round())
    sq = dict.fromkeys(scores, 0.0)
    count = 0
    for i in (int(x) for x in picks):
        halves = _halves(trials[i])
        if halves is None:
            continue
        calib, test = halves
        others = [g for j, g in enumerate(trials) if j != i]
        rest = [t for g in others for t in g]
        try:
            shared_all = match_trials(model, rest, start=values, fixed=fixed).values()
            partly = fit_grouped(model, others, per_log, start=values, fixed=fixed)
            shared_part = {k: p.value for k, p in partly.shared.items()}
            own = match_trials(
                model, calib, start=values,
                fixed={**fixed, **{k: v for k, v in shared_part.items() if k not in per_log}},
            ).values()
            alone = match_trials(model, calib, start=values, fixed=fixed).values()
            preds = {
                "all shared": evaluate_trials(model, test, shared_all),
                "partly shared": evaluate_trials(model, test, own),
                "all separate": evaluate_trials(model, test, alone),
            }
        except IdentificationError:
            continue
        for name, m in preds.items():
            sq[name] += _rss(m)
        count += sum(int(t.time.size) for t in test)
    if count == 0:
        notes.append("no log had two halves to hold out; held-out errors not computed")
        return
    for name in scores:
        scores[name].held_out_rmse = float(np.sqrt(sq[name] / count))
