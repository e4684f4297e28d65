"""``balancer-id plan``: the trials to record next, as one library call (issue 34.3).

Identify the logs (or take a fit), propose the step trials that shrink the widest
interval most (:func:`~balancer_id.identify.design.design_trials`), the trial that
reaches a limit the data do not reach, and, where the diagnosis finds two explanations
that fit alike, the trial that tells them apart (the arena's)::

    import balancer_id as bid
    plan = bid.plan("sample_logs/paper_balancer.csv")
    plan            # a table in a notebook
    print(plan.summary())
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from balancer_id.identify.api import fit as run_fit
from balancer_id.identify.design import Design, Proposal, design_trials
from balancer_id.identify.result import FitResult
from balancer_id.trials import ReadOptions, TrialSet

#: The plan says no trial does much better where this share of the target's predicted
#: half-width is the steps' places between samples (a 0.2 kg cart's m_a at 200 Hz: 0.79
#: of 0.90 mg).
FLOOR_SAYS = 0.7

__all__ = ["Plan", "plan", "plan_logs"]


@dataclass(frozen=True)
class Plan:
    """The trials to record next, with the intervals predicted after each.

    Attributes
    ----------
    fit : FitResult
        The identification the plan is made for.
    design : Design
        The proposals from the Fisher information.
    separate : str or None
        Where two explanations fit alike (the diagnosis's verdict ``ambiguous``): the
        trial that tells them apart, in words.
    rivals : tuple of str
        The two explanations (best, runner-up) when ``separate`` is set.
    fastest : float
        The largest speed the recorded trials reach in the model (m/s).
    notes : list of str
        What else the user should know.
    """

    fit: FitResult
    design: Design
    separate: str | None = None
    rivals: tuple[str, ...] = ()
    fastest: float = float("nan")
    notes: list[str] = field(default_factory=list)

    def _unit(self, name: str) -> str:
        return self.fit.match.parameters[name].unit

    def _interval(self, name: str, half: float) -> str:
        v = self.design.values[name]
        return f"{v - half:.4g} .. {v + half:.4g} {self._unit(name)}"

    def proposal_text(self, k: int, p: Proposal) -> str:
        """One proposal in words: the trial, why, and the predicted interval after.

        Parameters
        ----------
        k : int
            Its number (from 1).
        p : Proposal
            The proposal.

        Returns
        -------
        str
        """
        c = p.candidate
        head = f"{k}. record {c.sentence()}"
        if p.reaches is not None:
            est = self.fit.match.parameters[p.reaches]
            claim = est.claim or ""
            return (
                f"{head}: {p.reaches} {claim} {est.unit} is not reached by the trials so far "
                f"(the fastest went {self.fastest:.3g} m/s in the model); this one would go "
                f"{p.peak_speed:.3g} m/s without the limit, so it reaches the bound: if "
                f"{p.reaches} lies there it is predicted within ±{p.after[p.reaches]:.3g} "
                f"{est.unit}"
            )
        goal = p.target
        if goal == "all":
            shrink = [f"{n} ±{p.before[n]:.3g} -> ±{p.after[n]:.3g}" for n in self.design.names]
            return f"{head}: the joint uncertainty shrinks most (D-optimal): " + ", ".join(shrink)
        others = [
            f"{n} ±{p.before[n]:.3g} -> ±{p.after[n]:.3g}"
            for n in self.design.names
            if n != goal and n not in self.design.unreached
        ]
        v = abs(self.design.values[goal])
        now = (
            "is not determined now and is"
            if p.before[goal] > 10 * max(v, 1e-12)
            else f"{self._interval(goal, p.before[goal])} is"
        )
        floor = p.floor.get(goal, 0.0)
        limit = (
            f"; ±{floor:.3g} of it is where the steps fell between samples, which no trial "
            "at this sampling rate shrinks (a faster rate would): no trial does much better"
            if floor >= FLOOR_SAYS * p.after[goal]
            else ""
        )
        return (
            f"{head}: {goal}'s 95 % interval {now} "
            f"predicted to become {self._interval(goal, p.after[goal])}"
            + (f" (also {', '.join(others)})" if others else "")
            + limit
        )

    def lines(self) -> list[str]:
        """The plan as text, one line per proposal."""
        d = self.design
        what = {
            "widest": "the widest interval (relative to its value)",
            "all": "the joint uncertainty (D-optimal)",
        }.get(d.target, f"the interval of {d.target}")
        out = [f"trials to record next, to shrink {what}:"]
        out += [f"  {self.proposal_text(k, p)}" for k, p in enumerate(d.proposals, 1)]
        if not d.proposals:
            out.append("  none of the trials tried adds information")
        if self.separate:
            out.append(
                f"  to tell {self.rivals[0]} from {self.rivals[1]} (they fit alike): "
                f"{self.separate}"
            )
        out += [f"  note: {n}" for n in self.notes]
        return out

    def summary(self) -> str:
        """The plan as text."""
        return "\n".join(self.lines())

    def __repr__(self) -> str:
        n = len(self.design.proposals)
        return (
            f"<Plan {n} trial{'s' if n != 1 else ''} for {self.design.target} of {self.fit.model}>"
        )

    def _repr_html_(self) -> str:
        rows = []
        for k, p in enumerate(self.design.proposals, 1):
            c = p.candidate
            goal = p.reaches or p.target
            if goal == "all":
                now_after = "; ".join(
                    f"{n} ±{p.before[n]:.3g} → ±{p.after[n]:.3g}" for n in self.design.names
                )
            else:
                now_after = f"{goal} ±{p.before[goal]:.3g} → ±{p.after[goal]:.3g}"
            cells = (
                k,
                f"{c.thrust_N:+.3g} N {c.direction}",
                f"{c.rest_s:g} s",
                f"{c.duration_s:.3g} s",
                now_after,
            )
            rows.append(
                "<tr>" + "".join(f"<td>{html.escape(str(x))}</td>" for x in cells) + "</tr>"
            )
        extra = ""
        if self.separate:
            told = f"to tell {self.rivals[0]} from {self.rivals[1]}: {self.separate}"
            extra = f"<p>{html.escape(told)}</p>"
        return (
            f"<div><p><b>{html.escape(repr(self))}</b></p><table><thead><tr><th>#</th>"
            "<th>thrust</th><th>rest before</th><th>record after</th>"
            "<th>95 % half-width now → after</th></tr></thead><tbody>"
            + "".join(rows)
            + "</tbody></table>"
            + extra
            + "</div>"
        )

    def report_section(self) -> Any:
        """The "Next trials" section of a report: the proposals and their predictions.

        Returns
        -------
        balancer_id.report.blocks.Section
        """
        from balancer_id.report.blocks import Paragraph, Section, Table

        rows: list[list[Any]] = []
        for k, p in enumerate(self.design.proposals, 1):
            c = p.candidate
            goal = p.reaches or p.target
            names = self.design.names if goal == "all" else [goal]
            rows.append(
                [
                    str(k),
                    f"{c.thrust_N:+.3g} N {c.direction}",
                    f"{c.rest_s:g}",
                    f"{c.duration_s:.3g}",
                    "; ".join(f"{n} ±{p.before[n]:.3g} → ±{p.after[n]:.3g}" for n in names),
                ]
            )
        table = Table(
            ["#", "thrust", "rest before (s)", "record after (s)", "95 % half-width now → after"],
            rows,
            "The step trials to record next, in order, each chosen from the fit's Fisher "
            "information given the ones before it (levels up to 3x the largest recorded, "
            "moves up to 1.5x as far); the half-widths are predicted at the fitted values "
            "(for a parameter held at a guess, over the values it could have).",
        )
        blocks: list[Any] = [table, *(Paragraph(line.strip()) for line in self.lines()[1:])]
        return Section("Next trials", blocks=blocks)

    def write_report(self, path: str | Path) -> Path:
        """The fit's report (bands, posterior when sampled) with the plan after it.

        Parameters
        ----------
        path : str or Path
            ``FILE.html`` or ``FILE.pdf``.

        Returns
        -------
        Path
        """
        from balancer_id.report.document import write_fit_report

        return write_fit_report(self.fit, path, extra_sections=[self.report_section()])

    def to_dict(self) -> dict[str, object]:
        """The ``plan --json`` object (CONTRACT.md)."""
        from balancer_id.jsonsafe import json_ready

        return json_ready(
            {
                "model": self.fit.model,
                "files": self.fit.sources,
                **self.design.to_dict(),
                "fastest_speed": self.fastest,
                "separate": (
                    {"best": self.rivals[0], "runner_up": self.rivals[1], "record": self.separate}
                    if self.separate
                    else None
                ),
                "text": self.lines(),
            }
        )


def plan(
    source: FitResult | TrialSet | str | Path | Sequence[Any],
    *,
    model: str | None = None,
    param: str | None = None,
    count: int = 3,
    separate: bool = True,
    options: ReadOptions | None = None,
    fixed: dict[str, float] | None = None,
    effects_files: Sequence[str | Path] = (),
    posterior: bool = False,
) -> Plan:
    """The trials to record next: what shrinks the widest interval most.

    Parameters
    ----------
    source : FitResult, TrialSet, path(s) or trials
        A fit, or what :func:`~balancer_id.identify.api.fit` takes (fitted first).
    model : str, optional
        The model to fit (default ``variable_viscosity``); not with a FitResult.
    param : str, optional
        The parameter whose interval to shrink, ``"all"`` for the joint uncertainty
        (D-optimal), or None (default): the widest relative interval, after the trials
        that reach what the data do not reach.
    count : int
        Trials to propose.
    separate : bool
        Also diagnose the fit and, where two explanations fit alike, give the trial that
        separates them (costs a diagnosis: a few seconds).
    options : ReadOptions, optional
        Reading options for paths.
    fixed : dict of str to float, optional
        Values held in the fit.
    effects_files : sequence of path
        User effect files.
    posterior : bool
        Sample the fit's posterior too (when the fit is made here): its report then has
        the corner plot and the bands from the samples.

    Returns
    -------
    Plan
    """
    if isinstance(source, FitResult):
        result = source
    else:
        fitted = run_fit(
            source,
            model=model,
            options=options,
            fixed=fixed,
            effects_files=effects_files,
            posterior=posterior,
        )
        assert isinstance(fitted, FitResult), "a fit without per_log is one fit"
        result = fitted
    fitted_model = result.match.model
    held = [  # held by the fit because one thrust level cannot determine them (A)
        n
        for n, p in result.match.parameters.items()
        if not p.vary and n not in result.fixed and fitted_model.param(n).needs_thrust_levels
    ]
    design = design_trials(result.match, param, count, also=held)
    fastest = design.fastest
    notes = [
        f"{n} was held at {result.values[n]:.4g} (one thrust level cannot determine it); "
        "the trials above are planned to determine it"
        for n in held
    ]
    if not result.trusted:
        notes.append("the fit is not trusted (see its warnings): the predictions assume its values")
    hint: str | None = None
    rivals: tuple[str, ...] = ()
    if separate:
        from balancer_id.diagnostics.api import diagnose

        diagnosis = diagnose(result)
        amb = diagnosis.ambiguity
        if amb and amb.get("record"):
            hint = str(amb["record"])
            rivals = (str(amb.get("best")), str(amb.get("runner_up")))
    return Plan(result, design, hint, rivals, fastest, notes)


def plan_logs(
    logs: Sequence[str | Path],
    options: ReadOptions | None = None,
    *,
    count: int = 3,
    report: str | Path | None = None,
    overwrite: bool = False,
    **plan_options: Any,
) -> Plan:
    """``balancer-id plan``: check the outputs, read the logs, plan, write the report.

    Parameters
    ----------
    logs : sequence of str or Path
        The logs.
    options : ReadOptions, optional
        How they are read.
    count : int
        Trials to propose (>= 1).
    report : str or Path, optional
        The fit's report with the plan (HTML/PDF).
    overwrite : bool
        Replace ``report`` when it exists.
    **plan_options
        :func:`plan`'s options (``model``, ``param``, ``fixed``...).

    Returns
    -------
    Plan
    """
    from balancer_id.arguments import at_least
    from balancer_id.files import check_outputs, inputs_of
    from balancer_id.trials import load_trials

    at_least(count, 1, "--count")
    ins = inputs_of(logs, plan_options.get("effects_files"), None)
    check_outputs({"--report": report}, ins, overwrite)
    if report is not None:
        from balancer_id.report.document import check_report_path

        check_report_path(report, logs)
    result = plan(load_trials(list(logs), options), count=count, **plan_options)
    if report is not None:
        result.write_report(report)
    return result
