"""The content of a fit report, built from a :class:`~balancer_id.identify.result.FitResult`.

Summary, warnings, model, the paper's method, trials, per-trial refits, correlations and
the robot coupling; it renders what the result holds and computes nothing new.
"""

from __future__ import annotations

import inspect
import re
import textwrap
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from balancer_id.metric_fields import metric_cells
from balancer_id.numbers import format_estimate, format_number
from balancer_id.param_fields import PARAM_FIELDS, parameter_cells
from balancer_id.report.blocks import (
    Block,
    Cell,
    Paragraph,
    Plot,
    Preformatted,
    Section,
    Subheading,
    Table,
)
from balancer_id.report.html import anchor as _anchor
from balancer_id.report.html import escape as _e
from balancer_id.report.plots import (
    model_curves,
    plot_corner,
    plot_coupling,
    plot_paper_method,
    plot_per_trial,
    plot_trials,
)

if TYPE_CHECKING:
    from balancer_id.identify.result import FitResult
    from balancer_id.model.effect import Effect

#: Trials per figure in the report (3 rows of 2).
TRIALS_PER_FIGURE = 6
#: Correlations at least this large (in magnitude) are flagged.
STRONG_CORRELATION = 0.9


def fit_sections(
    result: FitResult, warnings: Sequence[object] | None = None
) -> list[Section]:
    """The sections of a fit report, for composing a bigger report.

    Parameters
    ----------
    result : FitResult
        A fit.
    warnings : sequence of str or Note, optional
        The warnings to show (a diagnosis reads them in the light of its verdict:
        :meth:`~balancer_id.diagnostics.diagnosis.Diagnosis.fit_warnings`); None shows
        the fit's own.

    Returns
    -------
    list of Section
        Summary, warnings (when any), model, paper's method, trials, per-trial refits
        (when present), correlations, robot coupling (when present).
    """
    sections = [_summary_section(result)]
    if warnings is None:
        warnings = [*result.warnings, *result.match.warnings]
    if warnings:
        sections.append(Section("Warnings", blocks=[Paragraph(f"⚠ {w}") for w in warnings]))
    sections += [
        _model_section(result),
        _paper_section(result),
        _trials_section(result),
    ]
    if result.per_trial:
        sections.append(_per_trial_section(result))
    if result.tracking is not None:
        from balancer_id.report.tracking_plot import tracking_section

        sections.append(tracking_section(result.tracking))
    sections.append(_correlation_section(result))
    if result.posterior is not None:
        sections.append(_posterior_section(result))
    if result.coupling is not None:
        sections.append(_coupling_section(result))
    return sections


def _parameter_table(result: FitResult) -> Table:
    descriptions = {p.name: p.description for p in result.match.model.params}
    rows: list[list[str | Cell]] = []
    style = {"value": "strong", "note": "warn"}
    for name, p in result.match.parameters.items():
        cells = parameter_cells(p)
        rows.append(
            [
                Cell(name, "strong"),
                descriptions.get(name, ""),
                *(Cell(t, style[k]) if k in style and t else t for k, t in cells.items()),
            ]
        )
    return Table(
        ["parameter", "meaning", *(f.heading for f in PARAM_FIELDS)],
        rows,
        "Identified by simulation matching over all trials at once (bounded least squares: "
        "Gauss-Newton steps with the simulated sensitivities as Jacobian, scipy's "
        "trust-region reflective method where a step misbehaves). "
        "The interval is value ± 1.96 standard errors (Wald) or, where that would cross "
        "a parameter's bounds, the profile-likelihood interval (marked 'profile': the "
        "other parameters refitted at each trial value).",
    )


def _summary_section(result: FitResult) -> Section:
    m = result.metrics
    match = result.match
    n_free = sum(1 for p in match.parameters.values() if p.vary)
    status = "converged" if match.success else "did NOT converge"
    cards = []
    for name, p in match.parameters.items():
        value, se = format_estimate(p.value, p.stderr)
        err = f" ± {se}" if p.vary and se != "-" else (" (held)" if not p.vary else "")
        if p.vary and p.ci95_method == "profile" and p.ci95 is not None:
            value = format_number(p.value, 3)  # the profile interval, not a Wald ± beside it
            err = f" ({format_number(p.ci95[0], 3)} .. {format_number(p.ci95[1], 3)})"
        cards.append(
            f'<div class="card"><div class="k">{_e(name)}</div>'
            f'<div class="v">{_e(value)}<span class="pm">{_e(err)}</span></div>'
            f'<div class="u">{_e(p.unit)}</div></div>'
        )
    cards.append(
        f'<div class="card alt"><div class="k">RMSE</div>'
        f'<div class="v">{_e(format_number(m["rmse"], 3))}</div><div class="u">m/s²</div></div>'
    )
    cards.append(
        f'<div class="card alt"><div class="k">fit</div>'
        f'<div class="v">{_e(format_number(m["nrmse_fit_percent"], 3))}</div>'
        f'<div class="u">% (NRMSE)</div></div>'
    )
    n_warn = len(result.warnings) + len(match.warnings)
    warn_html = (
        f'<p class="alert">⚠ {n_warn} warning{"s" * (n_warn != 1)}: '
        f'see <a href="#{_anchor("Warnings")}">Warnings</a>.</p>'
        if n_warn
        else ""
    )
    cells = metric_cells(m)
    errors = Table(
        [*(f.heading for f, _ in cells), "free parameters", "optimizer"],
        [
            [
                *(text for _, text in cells),
                str(n_free),
                Cell(f"{status} ({match.nfev} evaluations)", "" if match.success else "bad"),
            ]
        ],
        "Errors of the simulated against the measured acceleration over every sample of "
        "every trial; fit = 100 (1 - |y - y_model| / |y - mean(y)|).",
    )
    c = result.classic
    intro = Paragraph(
        f"Model '{result.model}' fitted to {len(match.data.trials)} step trials "
        f"({int(m['n_samples'])} samples); the optimizer {status}. RMSE "
        f"{format_number(m['rmse'], 3)} m/s², fit {format_number(m['nrmse_fit_percent'], 3)} %. "
        f"The paper's method gives m_a = {format_number(c.m_a)} kg and "
        f"T_a = {format_number(c.T_a, 3)} s." + ("" if n_warn else " No warnings.")
    )
    untrusted = "".join(
        f'<p class="alert"><b>NOT TRUSTED:</b> {_e(why)}</p>'
        for why in result.untrusted_because
    )
    return Section(
        "Summary",
        html=f'{untrusted}<div class="cards">{"".join(cards)}</div>{warn_html}',
        blocks=[intro, _parameter_table(result), errors],
    )


def _docstring_blocks(effect: type[Effect]) -> list[Block]:
    """An effect's docstring as paragraphs and its ``::`` literal blocks as equations."""
    doc = inspect.getdoc(effect) or ""
    blocks: list[Block] = []
    literal = False
    for chunk in re.split(r"\n\s*\n", doc):
        if not chunk.strip():
            continue
        if literal and chunk.startswith((" ", "\t")):
            blocks.append(Preformatted(textwrap.dedent(chunk).rstrip()))
            continue
        literal = chunk.rstrip().endswith("::")
        text = " ".join(chunk.split()).replace("``", "")
        if literal:
            text = text[:-2].rstrip() + ":"
        blocks.append(Paragraph(text))
    return blocks


def _model_section(result: FitResult) -> Section:
    model = result.match.model
    blocks: list[Block] = [
        Paragraph(
            "In words: the drive force f follows the operating thrust u through a "
            "first-order lag with time constant T_a; the virtual equivalent mass m_a is "
            "accelerated by f plus the force of every effect below; the accelerometer sees "
            "a = dv/dt (after gravity removal). State: drive force f (N), velocity v (m/s), "
            "position z (m). A step trial is a step of u by the trial's thrust f_in at its "
            "onset, from the state the log shows then: at rest, or, for a change of thrust "
            "while moving (a session), from the motion and drive force the trial before "
            "left; a guided move is driven by the measured force throughout."
        )
    ]
    for eff in model.all_effects:
        blocks.append(Subheading(eff.name + (f"  ({eff.source})" if eff.source else "")))
        blocks += _docstring_blocks(eff) or [Paragraph(eff.summary)]
    rows: list[list[str | Cell]] = []
    replaced = {n for e in model.effects for n in e.replaces}
    for eff in model.all_effects:
        for p in eff.parameters:
            if p.name in replaced:
                continue
            rows.append(
                [p.name, p.description, p.unit, f"{p.min:g} .. {p.max:g}", f"{p.value:g}", eff.name]
            )
    blocks.append(
        Table(
            ["parameter", "meaning", "unit", "bounds", "start", "effect"],
            rows,
            "Parameters of the model, in SI units.",
        )
    )
    return Section(f"Model: {model.spec}", blocks=blocks)


def _friction_hint(c: Any) -> str:
    """What the free line's intercept says of friction (against the scatter about it)."""
    hint = ""
    if np.isfinite(c.intercept_N) and np.isfinite(c.scatter_N) and c.scatter_N > 0:
        if abs(c.intercept_N) > 2 * c.scatter_N:
            hint = (
                f" The free line's intercept ({c.intercept_N:+.3g} N) is large against the "
                f"scatter ({c.scatter_N:.3g} N): a thrust that produces no motion, i.e. "
                "friction; try the model with '+karnopp'."
            )
        else:
            hint = (
                f" The free line's intercept ({c.intercept_N:+.3g} N) is within the scatter "
                f"({c.scatter_N:.3g} N): no sign of a friction threshold."
            )
    return hint


def _paper_section(result: FitResult) -> Section:
    c = result.classic
    v = result.values
    m_se = format_number(c.m_a_stderr, 2)
    summary = Table(
        ["figure", "paper's method", "simulation matching", "unit"],
        [
            [
                "m_a, line through the origin",
                f"{format_number(c.m_a)} ± {m_se}",
                format_number(v.get("m_a")),
                "kg",
            ],
            ["free line: slope", format_number(c.free_slope), "", "kg"],
            ["free line: intercept", format_number(c.intercept_N, 3), "", "N"],
            ["scatter about the line (RMS)", format_number(c.scatter_N, 3), "", "N"],
            [
                "T_a, median over trials",
                format_number(c.T_a, 3),
                format_number(
                    result.spec_model.drive_lag(v) if result.spec_model.drive_lag_names else None
                ),
                "s",
            ],
        ],
        "The paper's identification (Figs. 7 and 8) next to the simulation matching.",
    )
    per = Table(
        ["trial", "thrust f_in (N)", "direction", "a_zc (m/s²)", "T_a (s)", "3 T_a (s)"],
        [
            [
                str(t.index),
                f"{t.thrust_N:+.3f}",
                t.direction,
                format_number(t.a_zc),
                format_number(t.T_a, 3),
                format_number(t.settling_time, 3),
            ]
            for t in c.trials
        ],
        "Per trial: steady acceleration a_zc and time constant T_a of a first-order step "
        "fitted to the first seconds after the onset (95 % of a_zc at 3 T_a, eq. 1).",
    )
    by_level = Table(
        ["|f_in| (N)", "direction", "mean T_a (s)", "trials"],
        [
            [f"{r['thrust_N']:g}", str(r["direction"]), format_number(r["T_a"], 3), str(r["n"])]
            for r in c.T_a_table()
        ],
        "T_a per thrust level and direction (the paper's Fig. 8 as a table).",
    )
    hint = _friction_hint(c)
    blocks: list[Block] = [
        Paragraph(
            "Per trial, a first-order step a(t) = a_zc (1 - exp(-(t - t0)/T_a)) is fitted to "
            "the window after the onset; m_a is the slope of f_in = m_a a_zc through the "
            "origin over all trials (Fig. 7) and T_a is shown against thrust and direction "
            "(Fig. 8). The method neglects viscosity in the window, so it reads m_a a little "
            "high where viscosity is strong." + hint
        ),
        summary,
        Plot(
            plot_paper_method(c, reference=v),
            "Left: thrust against steady acceleration, up ▲ and down ▼, with the line through "
            "the origin (slope m_a) and the free line. Right: time constant against thrust. "
            "Dotted: the simulation-matching values.",
        ),
        per,
        by_level,
    ]
    return Section("The paper's method", blocks=blocks)


def _trial_fit_percent(y: np.ndarray, ym: np.ndarray) -> float:
    spread = float(np.linalg.norm(y - np.mean(y)))
    if spread <= 0:
        return float("nan")
    return 100.0 * (1.0 - float(np.linalg.norm(y - ym)) / spread)


def _trials_section(result: FitResult) -> Section:
    match = result.match
    trials = match.data.trials
    label, curves = model_curves(match)
    rmse = np.asarray(match.trial_rmse, float)
    worst = int(np.nanargmax(rmse)) if rmse.size and np.any(np.isfinite(rmse)) else -1
    rows: list[list[str | Cell]] = []
    for k, (td, ym) in enumerate(zip(trials, curves, strict=True)):
        fit_pc = _trial_fit_percent(np.asarray(td.accel, float), np.asarray(ym, float))
        r = format_number(rmse[k])
        rows.append(
            [
                str(td.index),
                td.source,
                f"{td.t_step:.3f}",
                f"{td.thrust_N:+.3f}",
                td.direction,
                str(len(td.time)),
                f"{td.time[-1] - td.t_step:.2f}",
                Cell(r, "warn") if k == worst and len(trials) > 1 else r,
                format_number(fit_pc, 3),
            ]
        )
    table = Table(
        [
            "trial",
            "source",
            "onset (s)",
            "thrust (N)",
            "direction",
            "samples",
            "after onset (s)",
            "RMSE (m/s²)",
            "fit (%)",
        ],
        rows,
        "Errors per trial" + (" (the worst one marked)." if len(trials) > 1 else "."),
    )
    blocks: list[Block] = [table]
    band = result.band()
    stretches = band.stretches(match.y)
    for start in range(0, len(trials), TRIALS_PER_FIGURE):
        stop = min(start + TRIALS_PER_FIGURE, len(trials))
        chunk = [(label, list(curves[start:stop]))]
        blocks.append(
            Plot(
                plot_trials(trials[start:stop], chunk, bands=[band], stretches=stretches),
                f"Trials {trials[start].index} to {trials[stop - 1].index}: measured (grey) "
                f"and simulated ({label}) acceleration, shaded: its 95 % band from the "
                f"parameters' uncertainty ({_band_method(band.method)}), dotted: that band "
                f"widened by the noise (σ = {format_number(band.sigma, 3)} m/s²), red: "
                "where the measurement leaves it; beneath, the residual (thin) and its "
                "0.25 s moving mean (thick). Time is counted from the onset of the thrust.",
            )
        )
    blocks.append(_where_it_fails(band, stretches, match.y))
    return Section("Trials: measured vs simulated", blocks=blocks)


def _posterior_section(result: FitResult) -> Section:
    """Credible intervals beside the Wald and profile ones, the chain's health, the corner."""
    post = result.posterior
    assert post is not None
    cred, med = post.credible(), post.median()
    units = {n: p.unit for n, p in result.match.parameters.items()}

    def span(iv) -> str:
        return f"{format_number(iv[0], 4)} .. {format_number(iv[1], 4)}" if iv else "-"

    rows: list[list[str | Cell]] = []
    disagree = {n.subject for n in post.notes if n.code == "fit.posterior_disagrees"}
    for n in post.names:
        rows.append(
            [
                Cell(n, "strong"),
                format_number(post.fitted[n], 4),
                format_number(med[n], 4),
                span(post.wald.get(n)),
                span(post.profile.get(n)),
                Cell(span(cred[n]), "warn") if n in disagree else span(cred[n]),
                units.get(n, ""),
            ]
        )
    table = Table(
        [
            "parameter",
            "fitted",
            "posterior median",
            "Wald 95 %",
            "profile 95 %",
            "credible 95 %",
            "unit",
        ],
        rows,
        "The posterior sampled with emcee (likelihood of the fit's own noise variance and "
        "residual correlation; a reference prior inside the bounds: flat where the data tell "
        "the parameters apart, Jeffreys' where they do not"
        + (", normal priors as given" if post.priors else "")
        + ")"
        + (
            f", each of {len(post.modes)} valleys the fit's starts ended in sampled on its "
            "own and weighed by bridge sampling"
            if len(post.modes) > 1
            else ""
        )
        + ". A credible interval marked differs from the Wald one by more than a quarter "
        "of its width: the uncertainty is not Gaussian there.",
    )
    blocks: list[Block] = [table, Paragraph(post.diagnostics_text())]
    blocks += [Paragraph(f"⚠ {n.text}") for n in post.notes]
    blocks.append(
        Plot(
            plot_corner(post),
            "Corner plot of the posterior samples: each parameter's histogram (2.5, 50 and "
            "97.5 % quantiles dashed in blue, the Wald interval dashed in grey) and each "
            "pair's joint samples; orange lines: the least-squares optimum.",
        )
    )
    return Section("Posterior", blocks=blocks)


def _band_method(method: str) -> str:
    return {
        "covariance": "the covariance through the simulated sensitivities",
        "posterior": "quantiles of the posterior samples' responses",
    }.get(method, "no covariance: the band is the noise alone")


def _where_it_fails(band, stretches, measured: np.ndarray) -> Block:
    """Where the measurement leaves the 95 % band widened by the noise."""
    inside = band.coverage(measured)
    head = (
        f"Where it fails: {100 * inside:.1f} % of the measured samples lie inside the 95 % "
        "band widened by the noise (95 % expected when the model holds). "
    )
    if not stretches:
        return Paragraph(
            head + "No stretch of 0.1 s or more leaves it (at least half of a 0.25 s window "
            "outside): the residual is noise and parameter uncertainty."
        )
    rows: list[list[str | Cell]] = [
        [
            str(s.trial),
            f"{s.t_start:.2f}",
            f"{s.t_end:.2f}",
            f"{s.t_end - s.t_start:.2f}",
            f"{100 * s.share_outside:.0f} %",
            f"measured {s.side}",
        ]
        for s in stretches
    ]
    return Table(
        ["trial", "from (s)", "to (s)", "length (s)", "samples outside", "side"],
        rows,
        head + "Stretches where the measurement leaves it (at least half of a 0.25 s window "
        "outside, shaded red in the figures): the model fails there.",
    )


def _per_trial_section(result: FitResult) -> Section:
    names = list(result.match.parameters)
    rows: list[list[str | Cell]] = []
    for p in result.per_trial:
        cells: list[str | Cell] = [str(p.index), f"{p.thrust_N:+.3f}", p.direction]
        for n in names:
            value, se = format_estimate(p.values.get(n, float("nan")), p.stderr.get(n))
            cells.append(f"{value} ± {se}" if se != "-" else f"{value} (held)")
        cells.append(format_number(p.rmse))
        rows.append(cells)
    units = {n: p.unit for n, p in result.match.parameters.items()}
    table = Table(
        ["trial", "thrust (N)", "direction", *[f"{n} ({units[n]})" for n in names], "RMSE (m/s²)"],
        rows,
        "The model fitted to each trial alone, starting from the joint fit. Drift with "
        "thrust or direction is what the joint fit averages away.",
    )
    return Section(
        "Each trial alone",
        blocks=[
            table,
            Plot(
                plot_per_trial(result.per_trial, joint=result.values),
                "Per-trial estimates (± one standard error) against the thrust; dashed: the "
                "joint fit over all trials.",
            ),
        ],
    )


def _correlation_section(result: FitResult) -> Section:
    corr = result.match.correlations
    names = [n for n in result.match.parameters if n in corr]
    if len(names) < 2:
        return Section(
            "Correlations",
            blocks=[Paragraph("Fewer than two parameters were fitted: no correlation.")],
        )
    rows: list[list[str | Cell]] = []
    for a in names:
        cells: list[str | Cell] = [Cell(a, "strong")]
        for b in names:
            if a == b:
                cells.append(Cell("1", "dim"))
                continue
            c = corr.get(a, {}).get(b)
            if c is None:
                cells.append("-")
                continue
            style = "bad" if abs(c) >= STRONG_CORRELATION else ("warn" if abs(c) >= 0.7 else "")
            cells.append(Cell(f"{c:+.3f}", style))
        rows.append(cells)
    strong = sorted(
        {
            tuple(sorted((a, b)))
            for a in names
            for b in names
            if a != b and abs(corr.get(a, {}).get(b, 0.0)) >= STRONG_CORRELATION
        }
    )
    text = (
        "Correlation of the parameter estimates (from the fit's covariance). Near ±1 the "
        "data cannot tell the two apart: one can trade for the other with little change "
        "in the error; fix one with --fix or add trials that separate them."
    )
    if strong:
        text += (
            " Strongly correlated (|r| ≥ 0.9): "
            + ", ".join(f"{a} and {b}" for a, b in strong)
            + "."
        )
    return Section("Correlations", blocks=[Paragraph(text), Table(["", *names], rows)])


def _coupling_section(result: FitResult) -> Section:
    cp = result.coupling
    assert cp is not None
    stable = cp.stability_margin > 0
    table = Table(
        ["oscillation (Hz)", "damping ratio", "stability margin", "verdict", "poles (1/s)"],
        [
            [
                format_number(cp.oscillation_hz, 3),
                format_number(cp.damping_ratio, 3),
                f"{cp.stability_margin:+.3g}",
                Cell(
                    "UNSTABLE: oscillates"
                    if not stable
                    else f"lightly damped: vibrates (damping {cp.damping_ratio:.2g} < 0.3)"
                    if cp.lightly_damped
                    else "stable, well damped",
                    "bad" if not stable else "warn" if cp.lightly_damped else "good",
                ),
                ", ".join(f"{p.real:.3g}{p.imag:+.3g}j" for p in cp.poles),
            ]
        ],
    )
    return Section(
        "Robot coupling",
        blocks=[
            Paragraph(
                "With a position-controlled robot holding the load through its servo (k_r, "
                "c_r), the drive lag closes a third-order loop T_a m_a s³ + (T_a D + m_a) s² "
                "+ (D + c_r) s + k_r, stable only when (T_a D + m_a)(D + c_r) > T_a m_a k_r "
                "(margin = left / right - 1). A stiff, lightly damped servo oscillates where "
                "a person does not (paper section IV)."
            ),
            table,
            Plot(
                plot_coupling(cp, params=result.values),
                "Closed-loop poles, and the stability boundary in the servo's (c_r, k_r) "
                "plane with the identified robot.",
            ),
            *_advice_blocks(result),
        ],
    )


def _advice_blocks(result: FitResult) -> list[Paragraph]:
    """The stability condition's dominant terms and the advice the fit carries (issue 9)."""
    dominant = result.coupling.dominant if result.coupling is not None else ""
    lines = result.advice.lines() if result.advice is not None else []
    return [Paragraph(f"Dominant terms: {dominant}.")] + [Paragraph(line.strip()) for line in lines]


def reproduce_section(result: FitResult) -> Section:
    """The command line that reproduces the fit (the report's footer).

    Parameters
    ----------
    result : FitResult
        The fit; the command carries its logs, model, fixed values, effect files,
        reading options and reference move.

    Returns
    -------
    Section
        "Reproduce" with the ``balancer-id fit`` command.
    """
    return Section(
        "Reproduce",
        blocks=[
            Paragraph("This fit is reproduced by:"),
            Preformatted(result.command()),
        ],
    )
