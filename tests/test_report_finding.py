"""Issue 11: the full report leads with the finding, says poorly determined parameters are
a symptom of a missing effect, holds the improve ladder and the residual analysis, and
its PDF tables stay on the page."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from conftest import EXAMPLES

from balancer_id.diagnostics.diagnosis import diagnose
from balancer_id.diagnostics.improve import improve
from balancer_id.identify import fit, resolve_model
from balancer_id.simulation.synth import write_synthetic_log

#: A balancer with the example hose pulling it back (a user effect), fitted without it: an
#: effect is missing. The hose's models are those test_diagnose's improve walk simulates
#: too, so their kernels are compiled once for the suite.
HOSE = EXAMPLES / "effects" / "hose_spring.py"
TRUE = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4, "k_h": 4.0}


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    path = tmp_path_factory.mktemp("finding") / "hose.csv"
    model = resolve_model("variable_viscosity+hose_spring", [HOSE])
    values = {k: v for k, v in TRUE.items() if k in model.param_names}
    write_synthetic_log(path, model, values, [2.45, -4.9, 7.35], seed=2, duration_s=4)
    result = fit([path], model="variable_viscosity", effects_files=[HOSE])
    diagnosis = diagnose(result)
    return result, diagnosis, improve(result, diagnosis=diagnosis, max_steps=1)


def test_the_report_leads_with_the_verdict_and_the_top_suggestion(diagnosed, tmp_path):
    from balancer_id.report.sections import write_full_report

    result, diagnosis, improved = diagnosed
    assert diagnosis.verdict == "effect missing"
    out = write_full_report(result, diagnosis, tmp_path / "r.html", improved)
    html = Path(out).read_text(encoding="utf-8")
    first = html.index('id="s-finding"')
    assert first < html.index('id="s-summary"')  # the finding comes first
    top = diagnosis.suggestions[0]
    assert top.label in html[first : html.index('id="s-summary"')]
    assert 'id="s-improving-the-model"' in html  # the ladder
    assert "The error falling as effects are added" in html  # the hose added: a figure
    assert "Residual analysis" in html


def test_a_ladder_that_adds_nothing_says_so_instead_of_drawing_one_bar(diagnosed):
    from balancer_id.report.blocks import Paragraph, Plot
    from balancer_id.report.sections import improve_section

    result, diagnosis, _ = diagnosed
    section = improve_section(improve(result, diagnosis=diagnosis, max_steps=0))
    assert not [b for b in section.blocks if isinstance(b, Plot)]
    said = " ".join(b.text for b in section.blocks if isinstance(b, Paragraph))
    assert "No effect was added" in said


def test_poorly_determined_parameters_are_a_symptom_not_a_reason_to_fix(diagnosed):
    """A ``fit.not_identifiable`` note (a typed note, as the fit writes it: the report once
    crashed splitting it as a string) becomes ``fit.symptom`` and leads the Finding."""
    from balancer_id.notes import Note
    from balancer_id.report.blocks import Paragraph
    from balancer_id.report.sections import finding_section

    _, diagnosis, _ = diagnosed
    note = Note(
        "fit.not_identifiable",
        "the data cannot determine m_a (standard error ...); fix them with --fix NAME=VALUE",
        "m_a",
    )
    # a fit is complete when made: the note comes with a fit made with it
    fit = dataclasses.replace(diagnosis.fit, warnings=(*diagnosis.fit.warnings, note))
    diagnosis = dataclasses.replace(diagnosis, fit=fit)
    (reworded,) = [
        w
        for w in diagnosis.fit_warnings()
        if w.code == "fit.symptom" and "m_a (standard error ...)" in w.text
    ]
    said = [b.text for b in finding_section(diagnosis).blocks if isinstance(b, Paragraph)]
    assert reworded.subject == "m_a"
    assert "symptom of the missing effect" in reworded.text
    assert "not a reason to hold it with --fix" in reworded.text
    assert "⚠ the data cannot determine m_a (standard error ...): a symptom" in " ".join(said)


def test_residual_analysis_draws_the_bands_and_the_states(diagnosed):
    from balancer_id.report.residual_plots import plot_residual_analysis

    _, diagnosis, _ = diagnosed
    fig = plot_residual_analysis(diagnosis)
    acf, xcorr, *states = fig.axes
    assert len(states) == 3
    assert acf.patches and xcorr.patches  # the 95 % bands (axhspan)
    assert xcorr.lines and xcorr.lines[0].get_xdata().size > 10  # the curve itself
    labels = [ax.get_xlabel() for ax in states]
    assert any("position" in s for s in labels) and any("velocity" in s for s in labels)


def test_every_pdf_table_fits_its_page_width(diagnosed, tmp_path, monkeypatch):
    from balancer_id.report import pdf
    from balancer_id.report.sections import write_full_report

    result, diagnosis, improved = diagnosed
    laid_out: list[tuple[float, float]] = []
    original = pdf._table

    def measured(block, styles, width):
        flowables = original(block, styles, width)
        table = flowables[0]
        used, _ = table.wrap(width, 1e6)  # reportlab lays the table out in the text width
        laid_out.append((used, width))
        return flowables

    monkeypatch.setattr(pdf, "_table", measured)
    write_full_report(result, diagnosis, tmp_path / "r.pdf", improved)
    assert laid_out
    assert all(used <= width + 0.5 for used, width in laid_out), laid_out
    assert (tmp_path / "r.pdf").read_bytes()[:5] == b"%PDF-"


def test_every_pdf_code_line_stays_on_the_page(diagnosed, tmp_path, monkeypatch):
    # the suggested commands are long code lines: wrapped shell-style, never cut off
    from reportlab.pdfbase.pdfmetrics import stringWidth

    from balancer_id.report import pdf
    from balancer_id.report.sections import write_full_report

    result, diagnosis, improved = diagnosed
    seen: list[tuple[list[str], float, float]] = []
    original = pdf.code_lines

    def recorded(text, width_pt, font_size):
        lines = original(text, width_pt, font_size)
        seen.append((lines, width_pt, font_size))
        return lines

    monkeypatch.setattr(pdf, "code_lines", recorded)
    write_full_report(result, diagnosis, tmp_path / "r.pdf", improved)
    assert seen
    for lines, width, size in seen:
        for line in lines:
            assert stringWidth(line, "Courier", size) <= width or " " not in line.strip()
    joined = " ".join(" ".join(lines) for lines, _, _ in seen).replace(" \\     ", " ")
    assert diagnosis.suggestions[0].command in joined  # whole again when unwrapped


def test_code_wraps_like_a_shell_continuation():
    from balancer_id.report.pdf import wrap_code

    line = "balancer-id fit a.csv --model variable_viscosity+karnopp --effects-file e/f.py"
    pieces = wrap_code(line, 30)
    # each piece fits, or is one word too long to break
    assert all(len(p) <= 30 or " " not in p.removesuffix(" \\").strip() for p in pieces)
    assert len(pieces) > 2
    assert all(p.endswith(" \\") for p in pieces[:-1])
    assert " ".join(p.removesuffix(" \\").strip() for p in pieces) == line
    assert wrap_code("short", 30) == ["short"]
