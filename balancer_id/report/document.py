"""Reports as one file: self-contained HTML or a PDF (matplotlib only, no other dependency).

A report is a title and a list of :class:`Section`. A section holds blocks that both
formats render (:class:`Paragraph`, :class:`Subheading`, :class:`Preformatted`,
:class:`Table`, :class:`Plot`), an optional HTML fragment (HTML only) and figures.
``fit`` builds its sections with :func:`fit_sections`; ``compare``, ``diagnose`` and
``improve`` add their own through ``extra_sections``. :func:`write_report` is the one
entry point that writes a file; it appends the provenance (files analysed with their
SHA-256, software versions, date), writes the file whole or not at all and never
overwrites an input log.

The format follows the suffix: ``.html`` (or ``.htm``) or ``.pdf``.
"""

from __future__ import annotations

import base64
import hashlib
import html
import inspect
import os
import re
import sys
import textwrap
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from html.parser import HTMLParser
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from balancer_id.errors import UsageError
from balancer_id.report.plots import (
    atomic_write,
    figure_png,
    model_curves,
    plot_coupling,
    plot_paper_method,
    plot_per_trial,
    plot_trials,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from balancer_id.fit.result import FitResult
    from balancer_id.model.effect import Effect

#: Trials per figure in the report (3 rows of 2).
TRIALS_PER_FIGURE = 6
#: Correlations at least this large (in magnitude) are flagged.
STRONG_CORRELATION = 0.9
#: Report formats by suffix.
FORMATS = {".html": "html", ".htm": "html", ".pdf": "pdf"}


# --------------------------------------------------------------------------------------
# content blocks
# --------------------------------------------------------------------------------------
@dataclass
class Paragraph:
    """Plain text (escaped in HTML, wrapped in PDF)."""

    text: str


@dataclass
class Subheading:
    """A heading inside a section."""

    text: str


@dataclass
class Preformatted:
    """Text kept as laid out (equations, listings), in a monospace font."""

    text: str


@dataclass
class Cell:
    """A table cell with a style: ``""``, ``"good"``, ``"warn"``, ``"bad"`` or ``"strong"``."""

    text: str
    style: str = ""


@dataclass
class Table:
    """A table: column headings and rows of text (or :class:`Cell`).

    Numbers are formatted by the caller (the report shows exactly what it is given).
    """

    columns: list[str]
    rows: list[list[str | Cell]]
    caption: str = ""


@dataclass
class Plot:
    """A figure (matplotlib Figure or PNG bytes) with an optional caption."""

    figure: Any
    caption: str = ""


Block = Paragraph | Subheading | Preformatted | Table | Plot


@dataclass
class Section:
    """One section of a report.

    Parameters
    ----------
    title : str
        Heading (plain text).
    html : str
        An HTML fragment placed first, *trusted as given* (escape what you insert:
        :func:`html.escape`). The PDF shows its text only when ``blocks`` is empty.
    figures : list
        Figures shown last: matplotlib Figures, PNG bytes or :class:`Plot`.
    blocks : list
        Paragraphs, subheadings, preformatted text, tables and plots, in order, rendered
        by both formats.
    """

    title: str
    html: str = ""
    figures: list[Any] = field(default_factory=list)
    blocks: list[Block] = field(default_factory=list)

    def all_blocks(self) -> list[Block]:
        """The blocks followed by the figures (as :class:`Plot`)."""
        plots = [f if isinstance(f, Plot) else Plot(f) for f in self.figures]
        return [*self.blocks, *plots]


# --------------------------------------------------------------------------------------
# number formatting shared by the tables
# --------------------------------------------------------------------------------------
def format_value(x: object, digits: int = 4) -> str:
    """A number as the report's tables show it.

    Parameters
    ----------
    x : float or None
        The number (anything ``float`` accepts; other objects are shown as text).
    digits : int
        Significant digits; trailing zeros are kept (``0.03000``).

    Returns
    -------
    str
        The text, ``-`` for missing or non-finite values.
    """
    if x is None:
        return "-"
    try:
        xf = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return str(x)
    if not np.isfinite(xf):
        return "-"
    text = f"{xf:#.{digits}g}"  # keeps trailing zeros: 0.03000, not 0.03
    mantissa, e, exponent = text.partition("e")
    return mantissa.rstrip(".") + e + exponent


def _decimals(stderr: float | None) -> int | None:
    """Decimals that show two significant digits of ``stderr``."""
    if stderr is None or not np.isfinite(stderr) or stderr <= 0:
        return None
    return int(np.clip(1 - np.floor(np.log10(stderr)), 0, 8))


def format_estimate(value: float, stderr: float | None) -> tuple[str, str]:
    """An estimate and its standard error, both to two significant digits of the error.

    ``15.0806, 0.1234`` gives ``("15.08", "0.12")``. Without a usable error the value
    has four significant digits and the error is ``-``.

    Parameters
    ----------
    value : float
        The estimate.
    stderr : float or None
        Its standard error.

    Returns
    -------
    tuple of str
        ``(value, stderr)`` as shown in the report's tables.
    """
    dec = _decimals(stderr)
    if dec is None or not np.isfinite(value) or not 1e-3 <= abs(value) < 1e6:
        return format_value(value), format_value(stderr, 2)
    return f"{value:.{dec}f}", f"{stderr:.{dec}f}"


def format_interval(value: float, stderr: float | None) -> str:
    """The approximate 95 % interval ``value ± 1.96 stderr``.

    Parameters
    ----------
    value : float
        The estimate.
    stderr : float or None
        Its standard error.

    Returns
    -------
    str
        ``lo .. hi`` with the decimals of :func:`format_estimate`, ``-`` without an error.
    """
    dec = _decimals(stderr)
    if stderr is None or not np.isfinite(stderr):
        return "-"
    lo, hi = value - 1.96 * stderr, value + 1.96 * stderr
    if dec is None or not 1e-3 <= max(abs(lo), abs(hi)) < 1e6:
        return f"{lo:.4g} .. {hi:.4g}"
    return f"{lo:.{dec}f} .. {hi:.{dec}f}"


# --------------------------------------------------------------------------------------
# the fit report
# --------------------------------------------------------------------------------------
def write_fit_report(
    result: FitResult, path: str | Path, *, extra_sections: list[Section] | None = None
) -> Path:
    """Write the report of a fit as FILE.html or FILE.pdf (chosen by the suffix).

    Parameters
    ----------
    result : FitResult
        What :func:`balancer_id.fit.fit` returned.
    path : str or Path
        The report file; ``.html``/``.htm`` or ``.pdf``.
    extra_sections : list of Section, optional
        Sections of other commands (compare, diagnose, improve), placed after the fit's.

    Returns
    -------
    Path
        ``path``, written whole.

    Raises
    ------
    UsageError
        Another suffix, a missing directory, or ``path`` is one of the input logs.
    """
    check_report_path(path, result.sources)
    n_trials = len(result.match.data.trials)
    n_logs = len(result.sources)
    sections = fit_sections(result) + list(extra_sections or [])
    return write_report(
        f"Balancer identification: {result.model}",
        sections,
        path,
        inputs=result.sources,
        subtitle=f"{n_trials} step trial{'s' * (n_trials != 1)} from "
        f"{n_logs} log{'s' * (n_logs != 1)}",
    )


def fit_sections(result: FitResult) -> list[Section]:
    """The sections of a fit report, for composing a bigger report.

    Parameters
    ----------
    result : FitResult
        A fit.

    Returns
    -------
    list of Section
        Summary, warnings (when any), model, paper's method, trials, per-trial refits
        (when present), correlations, robot coupling (when present).
    """
    sections = [_summary_section(result)]
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
    sections.append(_correlation_section(result))
    if result.coupling is not None:
        sections.append(_coupling_section(result))
    return sections


def _parameter_table(result: FitResult) -> Table:
    descriptions = {p.name: p.description for p in result.match.model.params}
    rows: list[list[str | Cell]] = []
    for name, p in result.match.parameters.items():
        value, se = format_estimate(p.value, p.stderr)
        note = ""
        if not p.vary:
            note = "held (not fitted)"
        elif p.at_bound:
            note = f"at {p.at_bound} bound"
        elif p.stderr is None or not np.isfinite(p.stderr) or p.stderr > abs(p.value):
            note = "poorly determined"
        rows.append(
            [
                Cell(name, "strong"),
                descriptions.get(name, ""),
                Cell(value, "strong"),
                se if p.vary else "-",
                format_interval(p.value, p.stderr) if p.vary else "-",
                p.unit,
                Cell(note, "warn") if note else "",
            ]
        )
    return Table(
        ["parameter", "meaning", "value", "std. error", "95 % interval", "unit", "note"],
        rows,
        "Identified by simulation matching over all trials at once (lmfit, bounded least "
        "squares). The interval is value ± 1.96 standard errors.",
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
        cards.append(
            f'<div class="card"><div class="k">{_e(name)}</div>'
            f'<div class="v">{_e(value)}<span class="pm">{_e(err)}</span></div>'
            f'<div class="u">{_e(p.unit)}</div></div>'
        )
    cards.append(
        f'<div class="card alt"><div class="k">RMSE</div>'
        f'<div class="v">{_e(format_value(m["rmse"], 3))}</div><div class="u">m/s²</div></div>'
    )
    cards.append(
        f'<div class="card alt"><div class="k">fit</div>'
        f'<div class="v">{_e(format_value(m["nrmse_fit_percent"], 3))}</div>'
        f'<div class="u">% (NRMSE)</div></div>'
    )
    n_warn = len(result.warnings) + len(match.warnings)
    warn_html = (
        f'<p class="alert">⚠ {n_warn} warning{"s" * (n_warn != 1)}: '
        f'see <a href="#{_anchor("Warnings")}">Warnings</a>.</p>'
        if n_warn
        else ""
    )
    errors = Table(
        ["RMSE (m/s²)", "fit (%)", "AIC", "BIC", "samples", "free parameters", "optimizer"],
        [
            [
                format_value(m["rmse"]),
                format_value(m["nrmse_fit_percent"], 4),
                f"{m['aic']:.1f}",
                f"{m['bic']:.1f}",
                str(int(m["n_samples"])),
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
        f"{format_value(m['rmse'], 3)} m/s², fit {format_value(m['nrmse_fit_percent'], 3)} %. "
        f"The paper's method gives m_a = {format_value(c.m_a)} kg and "
        f"T_a = {format_value(c.T_a, 3)} s." + ("" if n_warn else " No warnings.")
    )
    return Section(
        "Summary",
        html=f'<div class="cards">{"".join(cards)}</div>{warn_html}',
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
            "position z (m). Each trial is a step of u by the trial's thrust f_in at its "
            "onset, from rest."
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


def _paper_section(result: FitResult) -> Section:
    c = result.classic
    v = result.values
    m_se = format_value(c.m_a_stderr, 2)
    summary = Table(
        ["figure", "paper's method", "simulation matching", "unit"],
        [
            [
                "m_a, line through the origin",
                f"{format_value(c.m_a)} ± {m_se}",
                format_value(v.get("m_a")),
                "kg",
            ],
            ["free line: slope", format_value(c.free_slope), "", "kg"],
            ["free line: intercept", format_value(c.intercept_N, 3), "", "N"],
            ["scatter about the line (RMS)", format_value(c.scatter_N, 3), "", "N"],
            [
                "T_a, median over trials",
                format_value(c.T_a, 3),
                format_value(v.get("T_a", v.get("T_up"))),
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
                format_value(t.a_zc),
                format_value(t.T_a, 3),
                format_value(t.settling_time, 3),
            ]
            for t in c.trials
        ],
        "Per trial: steady acceleration a_zc and time constant T_a of a first-order step "
        "fitted to the first seconds after the onset (95 % of a_zc at 3 T_a, eq. 1).",
    )
    by_level = Table(
        ["|f_in| (N)", "direction", "mean T_a (s)", "trials"],
        [
            [f"{r['thrust_N']:g}", str(r["direction"]), format_value(r["T_a"], 3), str(r["n"])]
            for r in c.T_a_table()
        ],
        "T_a per thrust level and direction (the paper's Fig. 8 as a table).",
    )
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
        r = format_value(rmse[k])
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
                format_value(fit_pc, 3),
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
    for start in range(0, len(trials), TRIALS_PER_FIGURE):
        stop = min(start + TRIALS_PER_FIGURE, len(trials))
        chunk = [(label, list(curves[start:stop]))]
        blocks.append(
            Plot(
                plot_trials(trials[start:stop], chunk),
                f"Trials {trials[start].index} to {trials[stop - 1].index}: measured (grey) "
                f"and simulated ({label}) acceleration; beneath, the residual (thin) and its "
                "0.25 s moving mean (thick). Time is counted from the onset of the thrust.",
            )
        )
    return Section("Trials: measured vs simulated", blocks=blocks)


def _per_trial_section(result: FitResult) -> Section:
    names = list(result.match.parameters)
    rows: list[list[str | Cell]] = []
    for p in result.per_trial:
        cells: list[str | Cell] = [str(p.index), f"{p.thrust_N:+.3f}", p.direction]
        for n in names:
            value, se = format_estimate(p.values.get(n, float("nan")), p.stderr.get(n))
            cells.append(f"{value} ± {se}" if se != "-" else f"{value} (held)")
        cells.append(format_value(p.rmse))
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
                format_value(cp.oscillation_hz, 3),
                format_value(cp.damping_ratio, 3),
                f"{cp.stability_margin:+.3g}",
                Cell("stable" if stable else "UNSTABLE: oscillates", "good" if stable else "bad"),
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
    """The stability condition's dominant terms and the advice (issue 9)."""
    from balancer_id.diagnose.advice import advise_fit

    moves = [t.input for t in result.match.data.trials]
    advice = advise_fit(result.match.model, result.values, moves)
    dominant = result.coupling.dominant if result.coupling is not None else ""
    return [Paragraph(f"Dominant terms: {dominant}.")] + [
        Paragraph(line.strip()) for line in advice.lines()
    ]


# --------------------------------------------------------------------------------------
# the general writer
# --------------------------------------------------------------------------------------
def check_report_path(path: str | Path, inputs: Iterable[str | Path] = ()) -> str:
    """The report format of ``path``, refusing what must not be written.

    Parameters
    ----------
    path : str or Path
        The report file.
    inputs : iterable of path
        Input logs, which a report must never replace.

    Returns
    -------
    str
        ``"html"`` or ``"pdf"``.

    Raises
    ------
    UsageError
        Unknown suffix, missing directory, a directory, or one of the inputs.
    """
    path = Path(path)
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise UsageError(
            f"report file '{path}' must end in .html or .pdf (the suffix chooses the format)"
        )
    if path.is_dir():
        raise UsageError(f"report file '{path}' is a directory; give a file name")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise UsageError(f"cannot write report '{path}': directory '{parent}' does not exist")
    target = path.resolve()
    for src in inputs:
        s = Path(src)
        same = s.resolve() == target
        if not same and s.exists() and path.exists():
            try:
                same = os.path.samefile(s, path)
            except OSError:
                same = False
        if same:
            raise UsageError(
                f"report file '{path}' is the input log '{src}'; refusing to overwrite it, "
                "choose another name"
            )
    return fmt


def write_report(
    title: str,
    sections: Sequence[Section],
    path: str | Path,
    *,
    inputs: Sequence[str | Path] = (),
    subtitle: str = "",
) -> Path:
    """Write a report of ``sections`` as FILE.html or FILE.pdf (chosen by the suffix).

    A last section lists the files analysed (size, modification time, SHA-256) and the
    software (balancer-id and library versions, Python, date). The file is written
    whole or not at all (temporary file, then ``os.replace``).

    Parameters
    ----------
    title : str
        The report's title.
    sections : sequence of Section
        The content, in order.
    path : str or Path
        ``.html``/``.htm`` (one self-contained file: inline CSS, figures as base64 PNG)
        or ``.pdf`` (a title page with the first section, then the rest; figures as
        vector pages).
    inputs : sequence of path
        The logs analysed: listed, and never overwritten.
    subtitle : str
        A line under the title.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    UsageError
        Unknown suffix, missing directory, or ``path`` is one of ``inputs``.
    """
    fmt = check_report_path(path, inputs)
    meta = _software()
    all_sections = [*sections, _provenance_section(inputs, meta)]
    if fmt == "html":
        text = _render_html(title, subtitle, all_sections, meta)
        data = text.encode("utf-8")
        return atomic_write(path, lambda fh: fh.write(data))
    return atomic_write(path, lambda fh: _render_pdf(fh, title, subtitle, all_sections, meta))


def _software() -> dict[str, str]:
    from importlib import metadata

    import balancer_id

    out = {"balancer-id": balancer_id.__version__}
    for pkg in ("numpy", "scipy", "lmfit", "matplotlib", "numba", "pandas"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    out["python"] = sys.version.split()[0]
    out["date"] = datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z").strip()
    return out


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _provenance_section(inputs: Sequence[str | Path], meta: dict[str, str]) -> Section:
    rows: list[list[str | Cell]] = []
    for src in inputs:
        p = Path(src)
        if p.is_file():
            st = p.stat()
            when = datetime.fromtimestamp(st.st_mtime).astimezone().strftime("%Y-%m-%d %H:%M")
            rows.append([str(src), f"{st.st_size:,} B", when, _sha256(p)])
        else:
            rows.append([str(src), "-", "-", "not found when the report was written"])
    blocks: list[Block] = []
    if rows:
        blocks.append(Table(["file", "size", "modified", "SHA-256"], rows, "Files analysed."))
    else:
        blocks.append(Paragraph("No input file was named (data given in memory)."))
    blocks.append(
        Table(
            ["software", "version"],
            [[k, v] for k, v in meta.items() if k != "date"],
            f"Written {meta['date']} on {sys.platform}.",
        )
    )
    return Section("Files and software", blocks=blocks)


# --------------------------------------------------------------------------------------
# HTML
# --------------------------------------------------------------------------------------
CSS = """
:root { --ink:#1d2330; --mute:#5b6474; --line:#d9dee7; --head:#eef2f7; --accent:#0b5cad; }
* { box-sizing: border-box; }
body { font: 14px/1.45 -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif;
       color: var(--ink); margin: 0; background: #f6f7f9; }
header { background: #14213d; color: #fff; padding: 22px 36px 16px; }
header h1 { margin: 0 0 4px; font-size: 24px; font-weight: 600; }
header .sub { margin: 0; color: #c9d3e6; }
header .meta { margin: 6px 0 0; color: #93a1bb; font-size: 12px; }
nav { background: #fff; border-bottom: 1px solid var(--line); padding: 8px 36px; font-size: 13px; }
nav ol { margin: 0; padding: 0; list-style: none; display: flex; flex-wrap: wrap; gap: 4px 18px; }
nav a { color: var(--accent); text-decoration: none; }
main { max-width: 1180px; margin: 0 auto; padding: 8px 36px 36px; }
section { background: #fff; border: 1px solid var(--line); border-radius: 6px;
          padding: 6px 22px 16px; margin: 18px 0; }
h2 { font-size: 18px; border-bottom: 2px solid var(--accent); padding-bottom: 4px; }
h3 { font-size: 15px; margin: 16px 0 4px; color: #14213d; }
p { margin: 8px 0; }
pre { background: #f3f5f8; border-left: 3px solid var(--accent); padding: 8px 12px;
      font: 13px/1.4 "DejaVu Sans Mono", Menlo, Consolas, monospace; overflow-x: auto; }
table { border-collapse: collapse; margin: 10px 0 4px; font-size: 13px; }
caption { caption-side: bottom; text-align: left; color: var(--mute); font-size: 12px;
          padding-top: 4px; max-width: 900px; }
th, td { border: 1px solid var(--line); padding: 4px 9px; vertical-align: top; }
th { background: var(--head); text-align: left; font-weight: 600; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.strong { font-weight: 600; }
td.good { background: #e3f4e8; } td.warn { background: #fff3d6; } td.bad { background: #fbe0dd; }
td.dim { color: #9aa3b2; }
figure { margin: 14px 0; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--line); }
figcaption { color: var(--mute); font-size: 12px; max-width: 900px; }
.cards { display: flex; flex-wrap: wrap; gap: 10px; margin: 12px 0; }
.card { border: 1px solid var(--line); border-radius: 6px; padding: 8px 14px; min-width: 130px;
        background: #f9fbfd; }
.card.alt { background: #f5f7f2; }
.card .k { color: var(--mute); font-size: 12px; }
.card .v { font-size: 20px; font-weight: 600; font-variant-numeric: tabular-nums; }
.card .pm { font-size: 13px; font-weight: 400; color: var(--mute); }
.card .u { color: var(--mute); font-size: 12px; }
.alert { background: #fff3d6; border: 1px solid #f0d38a; padding: 6px 10px; border-radius: 4px; }
footer { color: var(--mute); font-size: 12px; text-align: center; padding: 0 0 24px; }
@media print {
  body { background: #fff; } header { background: #fff; color: #000; padding: 0; }
  header .sub, header .meta { color: #333; } nav { display: none; }
  section { border: none; padding: 0; break-inside: auto; } figure { break-inside: avoid; }
  main { padding: 0; max-width: none; }
}
"""

_NUMERIC = re.compile(r"^[+\-−]?(\d|\.\d)[\d.,eE+\-× ]*(±\s*[\d.eE+\-]+)?( \(held\))?$")


def _e(text: object) -> str:
    """Escape text for HTML."""
    return html.escape(str(text), quote=True)


def _anchor(title: str) -> str:
    return "s-" + (re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-") or "section")


def _html_cell(cell: str | Cell, tag: str = "td") -> str:
    text, style = (cell.text, cell.style) if isinstance(cell, Cell) else (cell, "")
    classes = [style] if style else []
    if tag == "td" and _NUMERIC.match(text.strip()):
        classes.append("num")
    cls = f' class="{" ".join(classes)}"' if classes else ""
    return f"<{tag}{cls}>{_e(text)}</{tag}>"


def _html_table(table: Table) -> str:
    head = "".join(f"<th>{_e(c)}</th>" for c in table.columns)
    body = "".join("<tr>" + "".join(_html_cell(c) for c in row) + "</tr>\n" for row in table.rows)
    cap = f"<caption>{_e(table.caption)}</caption>" if table.caption else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>\n{body}</tbody></table>\n"


def _png(figure: Any) -> bytes:
    if isinstance(figure, bytes | bytearray):
        return bytes(figure)
    return figure_png(figure)


def _html_block(block: Block, counter: list[int]) -> str:
    if isinstance(block, Paragraph):
        return f"<p>{_e(block.text)}</p>\n"
    if isinstance(block, Preformatted):
        return f"<pre>{_e(block.text)}</pre>\n"
    if isinstance(block, Subheading):
        return f"<h3>{_e(block.text)}</h3>\n"
    if isinstance(block, Table):
        return _html_table(block)
    counter[0] += 1
    data = base64.b64encode(_png(block.figure)).decode("ascii")
    label = f"Figure {counter[0]}"
    cap = f"<figcaption><b>{label}.</b> {_e(block.caption)}</figcaption>"
    return (
        f'<figure><img alt="{_e(label + ". " + block.caption)}" '
        f'src="data:image/png;base64,{data}">{cap}</figure>\n'
    )


def _render_html(
    title: str, subtitle: str, sections: Sequence[Section], meta: dict[str, str]
) -> str:
    counter = [0]
    nav = "".join(
        f'<li><a href="#{_anchor(s.title)}">{k}. {_e(s.title)}</a></li>'
        for k, s in enumerate(sections, 1)
    )
    body = []
    for k, s in enumerate(sections, 1):
        parts = [f'<section id="{_anchor(s.title)}">\n<h2>{k}. {_e(s.title)}</h2>\n']
        if s.html:
            parts.append(s.html + "\n")
        parts += [_html_block(b, counter) for b in s.all_blocks()]
        parts.append("</section>\n")
        body.append("".join(parts))
    stamp = f"balancer-id {meta['balancer-id']} · {meta['date']}"
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f'<meta name="generator" content="{_e(stamp)}">\n'
        f"<title>{_e(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n"
        f"<header><h1>{_e(title)}</h1>"
        + (f'<p class="sub">{_e(subtitle)}</p>' if subtitle else "")
        + f'<p class="meta">{_e(stamp)}</p></header>\n'
        f"<nav><ol>{nav}</ol></nav>\n<main>\n{''.join(body)}</main>\n"
        f"<footer>{_e(title)} · {_e(stamp)}</footer>\n</body>\n</html>\n"
    )


class _TextOnly(HTMLParser):
    """The text of an HTML fragment (for the PDF)."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.parts: list[str] = []

    def handle_data(self, data: str) -> None:
        self.parts.append(data)

    def handle_endtag(self, tag: str) -> None:
        if tag in {"p", "div", "li", "tr", "h3", "h4", "br", "table"}:
            self.parts.append("\n")


def _html_text(fragment: str) -> str:
    parser = _TextOnly()
    parser.feed(fragment)
    parser.close()
    lines = (" ".join(line.split()) for line in "".join(parser.parts).splitlines())
    return "\n".join(line for line in lines if line)


# --------------------------------------------------------------------------------------
# PDF
# --------------------------------------------------------------------------------------
_PAGE = (8.27, 11.69)  # A4 portrait, inches
_MARGIN = 0.6
_FIGURE_MARGIN = 0.45  # figures may use a little more of the width than text
_PDF_DPI = 170  # resolution of figures on the printed page (dots per inch)
_STYLE_COLORS = {
    "good": "#e3f4e8",
    "warn": "#fff3d6",
    "bad": "#fbe0dd",
    "strong": "white",
    "dim": "white",
}


class _PdfFlow:
    """Text, tables and figures flowed onto A4 pages of a ``PdfPages``."""

    def __init__(self, pdf: Any, title: str) -> None:
        self.pdf = pdf
        self.title = title
        self.fig: Figure | None = None
        self.y = 0.0
        self.page = 0
        self.figure_no = 0

    # page handling ---------------------------------------------------------------
    def new_page(self) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.flush()
        self.fig = Figure(figsize=_PAGE)
        FigureCanvasAgg(self.fig)
        self.page += 1
        self.y = _PAGE[1] - _MARGIN
        if self.page > 1:
            self._text(_MARGIN, _PAGE[1] - 0.35, self.title, size=7.5, color="0.45")
        self._text(
            _PAGE[0] - _MARGIN, 0.35, f"page {self.page}", size=7.5, color="0.45", ha="right"
        )

    def flush(self) -> None:
        if self.fig is not None:
            self.pdf.savefig(self.fig)
            self.fig = None

    def need(self, height: float) -> None:
        if self.fig is None or self.y - height < _MARGIN:
            self.new_page()

    def _text(self, x: float, y: float, s: str, **kw: Any) -> None:
        assert self.fig is not None
        size = kw.pop("size", 9)
        self.fig.text(
            x / _PAGE[0],
            y / _PAGE[1],
            s,
            fontsize=size,
            va=kw.pop("va", "top"),
            parse_math=False,
            **kw,
        )

    # content ------------------------------------------------------------------------
    def heading(self, text: str, size: float = 13) -> None:
        self.need(0.9)
        self.y -= 0.12
        self._text(_MARGIN, self.y, text, size=size, weight="bold", color="#14213d")
        self.y -= size / 72 * 1.5

    def subheading(self, text: str) -> None:
        self.need(0.6)
        self.y -= 0.04
        self._text(_MARGIN, self.y, text, size=10.5, weight="bold", color="#14213d")
        self.y -= 10.5 / 72 * 1.6

    def lines(
        self,
        text: str,
        *,
        size: float = 9,
        mono: bool = False,
        width: int = 108,
        color: str = "black",
    ) -> None:
        out: list[str] = []
        for raw in text.splitlines() or [""]:
            out += textwrap.wrap(raw, width) if not mono and raw else [raw]
        step = size / 72 * 1.35
        for line in out:
            self.need(step)
            self._text(
                _MARGIN + (0.15 if mono else 0.0),
                self.y,
                line,
                size=size,
                family="monospace" if mono else "sans-serif",
                color=color,
            )
            self.y -= step
        self.y -= 0.08

    def table(self, table: Table) -> None:
        row_h = 0.22
        ncols = max(len(table.columns), 1)
        longest = max(
            [len(c) for c in table.columns]
            + [len(_cell_text(c)) for row in table.rows for c in row]
            + [1]
        )
        size = 7.5 if ncols <= 7 and longest <= 60 else 6.5
        rows = list(table.rows) or [["-"] * ncols]
        whole = row_h * (len(rows) + 2) + 0.35  # as the chunking below counts
        if whole <= _PAGE[1] - 2 * _MARGIN - 0.5 and self.y - whole < _MARGIN:
            self.new_page()  # a table that fits on one page is not split
        start = 0
        while start < len(rows):
            self.need(3 * row_h)
            fit = max(1, int((self.y - _MARGIN - 0.35) / row_h) - 1)
            chunk = rows[start : start + fit]
            self._draw_table(table.columns, chunk, size, row_h)
            start += len(chunk)
            if start < len(rows):
                self.new_page()
        if table.caption:
            self.lines(table.caption, size=7.5, color="0.35", width=120)
        self.y -= 0.1

    def _draw_table(
        self, columns: list[str], rows: list[list[str | Cell]], size: float, row_h: float
    ) -> None:
        assert self.fig is not None
        height = row_h * (len(rows) + 1)
        text = [[_cell_text(c) for c in row] for row in rows]
        # as wide as the text needs (estimated from the character count), at most the page
        chars = [
            max([len(h) for h in columns[j : j + 1]] + [len(r[j]) for r in text if j < len(r)])
            for j in range(len(columns))
        ]
        natural = sum(n * size * 0.6 / 72 + 0.18 for n in chars)
        width = min(_PAGE[0] - 2 * _MARGIN, max(natural, 2.0))
        ax = self.fig.add_axes(
            (_MARGIN / _PAGE[0], (self.y - height) / _PAGE[1], width / _PAGE[0], height / _PAGE[1])
        )
        ax.axis("off")
        from matplotlib.transforms import Bbox

        tab = ax.table(
            cellText=text,
            colLabels=columns or None,
            loc="upper left",
            cellLoc="left",
            bbox=Bbox.from_bounds(0, 0, 1, 1),
        )
        tab.auto_set_font_size(False)
        tab.set_fontsize(size)
        tab.auto_set_column_width(list(range(len(columns))))
        for (r, c), cell in tab.get_celld().items():
            cell.set_edgecolor("#c9d0db")
            cell.set_linewidth(0.5)
            cell.PAD = 0.025  # fraction of the cell's width (default 0.1 indents wide cells)
            cell.get_text().set_parse_math(False)
            if r == 0:
                cell.set_facecolor("#eef2f7")
                cell.get_text().set_fontweight("bold")
                continue
            src = rows[r - 1][c] if c < len(rows[r - 1]) else ""
            style = src.style if isinstance(src, Cell) else ""
            if style in _STYLE_COLORS:
                cell.set_facecolor(_STYLE_COLORS[style])
            if style == "strong":
                cell.get_text().set_fontweight("bold")
            if style == "dim":
                cell.get_text().set_color("0.6")
        self.y -= height + 0.08

    def plot(self, block: Plot) -> None:
        """The figure as an image across the text width, its caption beneath."""
        self.figure_no += 1
        width_in = _PAGE[0] - 2 * _FIGURE_MARGIN
        img = _figure_pixels(block.figure, width_in)
        h, w = img.shape[:2]
        caption = f"Figure {self.figure_no}. {block.caption}".strip()
        cap_lines = len(textwrap.wrap(caption, 120)) or 1
        cap_h = cap_lines * 8 / 72 * 1.35 + 0.1
        width = min(width_in, w / _PDF_DPI * 1.0)
        height = width * h / w
        max_h = _PAGE[1] - 2 * _MARGIN - 0.4 - cap_h
        if height > max_h:
            height, width = max_h, max_h * w / h
        self.need(height + cap_h + 0.1)
        assert self.fig is not None
        x0 = (_PAGE[0] - width) / 2
        ax = self.fig.add_axes(
            (x0 / _PAGE[0], (self.y - height) / _PAGE[1], width / _PAGE[0], height / _PAGE[1])
        )
        ax.imshow(img, interpolation="none", aspect="auto")
        ax.axis("off")
        self.y -= height + 0.1
        self.lines(caption, size=8, color="0.3", width=120)


def _figure_pixels(figure: Any, width_in: float) -> np.ndarray:
    """RGB pixels of a figure (rendered for ``width_in`` inches at ``_PDF_DPI``) or a PNG."""
    if isinstance(figure, bytes | bytearray):
        from io import BytesIO

        import matplotlib.image as mpimg

        img = mpimg.imread(BytesIO(bytes(figure)), format="png")
        if img.dtype != np.uint8:
            img = (np.clip(img, 0, 1) * 255).astype(np.uint8)
        if img.ndim == 2:
            img = np.stack([img] * 3, axis=-1)
        return img[..., :3]
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig_w = float(figure.get_size_inches()[0])
    dpi = _PDF_DPI * min(1.0, width_in / fig_w)
    canvas = FigureCanvasAgg(figure)
    old_dpi, old_face = figure.get_dpi(), figure.get_facecolor()
    try:
        figure.set_dpi(dpi)
        figure.set_facecolor("white")
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()
    finally:
        figure.set_dpi(old_dpi)
        figure.set_facecolor(old_face)


def _cell_text(cell: str | Cell) -> str:
    return cell.text if isinstance(cell, Cell) else str(cell)


def _render_pdf(
    fh: IO[bytes], title: str, subtitle: str, sections: Sequence[Section], meta: dict[str, str]
) -> None:
    from matplotlib.backends.backend_pdf import PdfPages

    info = {
        "Title": title,
        "Subject": subtitle,
        "Creator": f"balancer-id {meta['balancer-id']}",
    }
    with PdfPages(fh, metadata=info) as pdf:
        flow = _PdfFlow(pdf, title)
        flow.new_page()
        flow._text(_MARGIN, flow.y, title, size=18, weight="bold", color="#14213d")
        flow.y -= 0.42
        if subtitle:
            flow._text(_MARGIN, flow.y, subtitle, size=11, color="0.25")
            flow.y -= 0.25
        flow._text(
            _MARGIN,
            flow.y,
            f"balancer-id {meta['balancer-id']} · {meta['date']}",
            size=8.5,
            color="0.45",
        )
        flow.y -= 0.3
        assert flow.fig is not None
        flow.fig.add_artist(_hline(flow.y / _PAGE[1], _MARGIN / _PAGE[0], 1 - _MARGIN / _PAGE[0]))
        flow.y -= 0.15
        for k, section in enumerate(sections, 1):
            if k > 1 and flow.fig is None:
                flow.new_page()
            flow.heading(f"{k}. {section.title}")
            blocks = section.all_blocks()
            if section.html and not section.blocks:
                flow.lines(_html_text(section.html))
            for block in blocks:
                if isinstance(block, Paragraph):
                    flow.lines(block.text)
                elif isinstance(block, Subheading):
                    flow.subheading(block.text)
                elif isinstance(block, Preformatted):
                    flow.lines(block.text, size=8, mono=True)
                elif isinstance(block, Table):
                    flow.table(block)
                else:
                    flow.plot(block)
        flow.flush()


def _hline(y: float, x0: float, x1: float) -> Any:
    from matplotlib.lines import Line2D

    return Line2D([x0, x1], [y, y], color="#0b5cad", linewidth=1.2)
