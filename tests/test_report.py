"""Reports and figures: HTML, PDF and PNG from a fit of a small simulated log."""

from __future__ import annotations

import base64
import re
from html.parser import HTMLParser
from pathlib import Path

import pytest
from typer.testing import CliRunner

from balancer_id.cli import app
from balancer_id.errors import UsageError
from balancer_id.identify import fit
from balancer_id.identify.result import FitResult
from balancer_id.model.spec import parse_model
from balancer_id.report import plots
from balancer_id.report.document import (
    Paragraph,
    Section,
    Table,
    format_estimate,
    format_number,
    write_fit_report,
    write_report,
)
from balancer_id.simulation.synth import write_synthetic_log

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
TRUE = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
THRUSTS = [2.45, -4.9, 7.35]
VOID = {"meta", "img", "br", "hr", "link", "input", "col", "area", "base", "source", "wbr"}


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("logs") / "sim.csv"
    write_synthetic_log(
        path, parse_model("variable_viscosity"), TRUE, THRUSTS, seed=1, duration_s=4
    )
    return path


@pytest.fixture(scope="module")
def result(log: Path) -> FitResult:
    return fit([log], per_trial=True)


@pytest.fixture(scope="module")
def html_report(result: FitResult, tmp_path_factory: pytest.TempPathFactory) -> str:
    ladder = plots.plot_error_ladder(
        [
            {"model": "base", "added": None, "rmse": 0.08, "aic": -900.0, "bic": -890.0},
            {"model": "viscous", "added": "viscous", "rmse": 0.04, "aic": -1500.0, "bic": -1480.0},
        ]
    )
    extra = Section(
        "Improve <script>alert(1)</script> & co",
        html='<p class="trusted">kept as given</p>',
        figures=[ladder],
        blocks=[
            Paragraph("a < b & c > d"),
            Table(["name", "value"], [["<i>x</i>", "1.5"]], "caption with <tags>"),
        ],
    )
    path = tmp_path_factory.mktemp("out") / "fit.html"
    assert write_fit_report(result, path, extra_sections=[extra]) == path
    return path.read_text(encoding="utf-8")


class _Checker(HTMLParser):
    """Checks that tags nest and close; collects the tables as rows of cell texts."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.tables: list[list[list[str]]] = []
        self.cell: list[str] | None = None
        self.images: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "img":
            self.images.append(dict(attrs).get("src") or "")
        if tag in VOID:
            return
        self.stack.append(tag)
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self.cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag in VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:]}")
            return
        self.stack.pop()
        if tag in ("td", "th") and self.cell is not None:
            self.tables[-1][-1].append("".join(self.cell).strip())
            self.cell = None

    def handle_data(self, data: str) -> None:
        if self.cell is not None:
            self.cell.append(data)


def _parse(text: str) -> _Checker:
    checker = _Checker()
    checker.feed(text)
    checker.close()
    return checker


def _table(checker: _Checker, *headings: str) -> list[list[str]]:
    for table in checker.tables:
        if table and table[0][: len(headings)] == list(headings):
            return table
    raise AssertionError(f"no table with the columns {headings}")


def test_html_is_well_formed_and_self_contained(html_report: str) -> None:
    assert html_report.startswith("<!DOCTYPE html>")
    checker = _parse(html_report)
    assert checker.errors == []
    assert checker.stack == []
    assert "<style>" in html_report
    assert not re.search(r"""(src|href)=["'](?!data:|#)""", html_report), "external resource"


def test_html_parameter_table_shows_the_fit(html_report: str, result: FitResult) -> None:
    table = _table(_parse(html_report), "parameter")
    assert table[0][:6] == ["parameter", "meaning", "value", "std. error", "95 % interval", "unit"]
    rows = {row[0]: row for row in table[1:]}
    assert list(rows) == list(result.match.parameters)
    for name, p in result.match.parameters.items():
        value, se = format_estimate(p.value, p.stderr)
        assert rows[name][2] == value
        assert rows[name][3] == (se if p.vary else "-")
        assert rows[name][5] == p.unit
        assert " .. " in rows[name][4] or not p.vary
    assert "±" in html_report and "kg" in html_report


def test_html_per_trial_tables(html_report: str, result: FitResult) -> None:
    checker = _parse(html_report)
    trials = result.match.data.trials
    table = _table(checker, "trial", "source")
    assert len(table) == 1 + len(trials)
    for row, td, rmse in zip(table[1:], trials, result.match.trial_rmse, strict=True):
        assert row[0] == str(td.index)
        assert row[3] == f"{td.thrust_N:+.3f}"
        assert row[4] == td.direction
        assert row[7] == format_number(rmse)
    refits = [t for t in checker.tables if t[0][:3] == ["trial", "thrust (N)", "direction"]]
    assert any(len(t) == 1 + len(result.per_trial) for t in refits)
    for section in ("The paper&#x27;s method", "Correlations", "Files and software", "Model:"):
        assert section in html_report
    assert "SHA-256" in html_report


def test_html_embeds_every_figure_as_png(html_report: str) -> None:
    checker = _parse(html_report)
    # paper's method, trials (3 in one figure), per-trial refits, and the extra ladder
    assert html_report.count("data:image/png;base64,") == 4
    assert len(checker.images) == 4
    for src in checker.images:
        data = base64.b64decode(src.split(",", 1)[1])
        assert data.startswith(PNG_MAGIC) and len(data) > 5_000


def test_html_escapes_text_but_keeps_trusted_fragments(html_report: str) -> None:
    assert "<script>" not in html_report
    assert "Improve &lt;script&gt;alert(1)&lt;/script&gt; &amp; co" in html_report
    assert "a &lt; b &amp; c &gt; d" in html_report
    assert "&lt;i&gt;x&lt;/i&gt;" in html_report
    assert '<p class="trusted">kept as given</p>' in html_report


def test_pdf_report(result: FitResult, tmp_path: Path) -> None:
    path = write_fit_report(result, tmp_path / "fit.PDF")
    data = path.read_bytes()
    assert data.startswith(b"%PDF")
    pages = len(re.findall(rb"/Type\s*/Page(?![a-z])", data))
    assert pages > 1
    assert [p.name for p in tmp_path.iterdir()] == ["fit.PDF"]  # no temporary file left


@pytest.mark.parametrize("which", ["trials", "ladder"])
def test_png_files(result: FitResult, tmp_path: Path, which: str) -> None:
    out = tmp_path / f"{which}.png"
    if which == "trials":
        label, curves = plots.model_curves(result.match)
        two = [(label, curves[:2]), ("half", [0.5 * y for y in curves[:2]])]
        written = plots.plot_trials(result.match.data.trials[:2], two, out, title="compare")
    else:
        steps = [
            {"model": "base", "added": None, "rmse": 0.05, "aic": -10.0, "bic": -8.0},
            {"model": "viscous", "added": "viscous", "rmse": 0.03, "aic": -20.0, "bic": -17.0},
        ]
        written = plots.plot_error_ladder(steps, out)
    assert written == out
    data = out.read_bytes()
    assert data.startswith(PNG_MAGIC) and len(data) > 10_000
    assert [p.name for p in tmp_path.iterdir()] == [out.name]  # no temporary file left


def test_plots_return_figures_without_path(result: FitResult) -> None:
    from matplotlib.figure import Figure

    paper = plots.plot_paper_method(result.classic, reference=result.values)
    assert isinstance(paper, Figure) and len(paper.axes) == 2
    per = plots.plot_per_trial(result.per_trial, joint=result.values)
    varied = {n for p in result.per_trial for n, se in p.stderr.items() if se is not None}
    assert isinstance(per, Figure)
    assert len([ax for ax in per.axes if ax.axison]) == len(varied)
    trials = result.match.data.trials
    fig = plots.plot_trials(trials, [plots.model_curves(result.match)])
    assert isinstance(fig, Figure) and len(fig.axes) == 2 * len(trials)


def test_plot_trials_refuses_curves_that_do_not_match(result: FitResult) -> None:
    trials = result.match.data.trials
    with pytest.raises(ValueError, match="curves"):
        plots.plot_trials(trials, [("short", [trials[0].accel])])


def test_plot_refuses_a_file_that_is_not_png(result: FitResult, tmp_path: Path) -> None:
    with pytest.raises(UsageError, match=r"\.png"):
        plots.plot_paper_method(result.classic, tmp_path / "figure.csv")


def test_bad_suffix_is_a_usage_error(result: FitResult, tmp_path: Path) -> None:
    with pytest.raises(UsageError) as info:
        write_fit_report(result, tmp_path / "report.txt")
    message = str(info.value)
    assert "\n" not in message and ".html or .pdf" in message
    assert not (tmp_path / "report.txt").exists()


def test_never_overwrites_an_input_log(result: FitResult, log: Path, tmp_path: Path) -> None:
    before = log.read_bytes()
    with pytest.raises(UsageError):
        write_fit_report(result, log)
    link = tmp_path / "looks_like_a_report.html"
    link.symlink_to(log)
    with pytest.raises(UsageError, match="input log"):
        write_fit_report(result, link)
    with pytest.raises(UsageError, match="input log"):
        write_report("t", [], tmp_path / ".." / tmp_path.name / link.name, inputs=[log])
    assert log.read_bytes() == before


def test_failed_write_leaves_the_old_file(tmp_path: Path) -> None:
    path = tmp_path / "report.pdf"
    path.write_bytes(b"old")
    with pytest.raises(Exception):  # noqa: B017 - any error of the PNG reader will do
        write_report("t", [Section("broken", figures=[b"not a png"])], path)
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["report.pdf"]


def test_cli_fit_writes_the_report(log: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.html"
    runner = CliRunner()
    res = runner.invoke(app, ["fit", str(log), "--report", str(out), "--json"])
    assert res.exit_code == 0, res.output
    assert out.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    bad = runner.invoke(app, ["fit", str(log), "--report", str(tmp_path / "out.docx")])
    assert bad.exit_code == 2
