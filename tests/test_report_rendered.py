"""The reports looked at as a person sees them (issue 29): the HTML report opened in a real
browser (headless Chromium) and the PDF turned into page images (pdftoppm) and text
(pdftotext). Every figure renders, no table runs off the page, no header breaks mid-word.

CI installs Chromium and poppler from Debian's packages (``.ci/run``); on a machine without
them the browser and page-image checks are skipped, the column widths are checked anyway.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import pytest
from conftest import SAMPLE_LOGS

from balancer_id.report.blocks import Table
from balancer_id.report.pdf import _column_widths

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
PDFTOPPM = shutil.which("pdftoppm")
PDFTOTEXT = shutil.which("pdftotext")

#: The headers of the fit's parameter table, which broke as "uni t" and "not e".
HEADERS = ["parameter", "value", "std. error", "95% interval", "unit", "note"]

#: Run in the page once it has loaded: the checks' results as JSON in the document title.
PROBE = """
<script>
window.addEventListener('load', () => {
  const page = document.documentElement.clientWidth;
  const images = [...document.images];
  const broken = images.filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.alt);
  const wide = [...document.querySelectorAll('table')]
      .filter(t => t.getBoundingClientRect().right > page + 1)
      .map(t => t.innerText.slice(0, 40));
  const split = [];
  for (const th of document.querySelectorAll('th')) {
    const walker = document.createTreeWalker(th, NodeFilter.SHOW_TEXT);
    for (let node = walker.nextNode(); node; node = walker.nextNode()) {
      const re = /\\S+/g; let m;
      while ((m = re.exec(node.textContent)) !== null) {
        const range = document.createRange();
        range.setStart(node, m.index); range.setEnd(node, m.index + m[0].length);
        if (range.getClientRects().length > 1) split.push(m[0]);
      }
    }
  }
  document.title = JSON.stringify({images: images.length, broken, wide, split});
});
</script>
"""


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """The fit report of the paper's balancer, as HTML and as PDF."""
    from typer.testing import CliRunner

    from balancer_id.cli import app

    folder = tmp_path_factory.mktemp("rendered")
    # A log in a deep folder, as on a CI machine: its path and SHA-256 fill the provenance table.
    deep = folder.joinpath(*["a_long_folder_name_on_a_build_machine"] * 4)
    deep.mkdir(parents=True)
    log = deep / "paper_balancer.csv"
    shutil.copyfile(SAMPLE_LOGS / "paper_balancer.csv", log)
    runner = CliRunner()
    for suffix in ("html", "pdf"):
        res = runner.invoke(
            app, ["fit", str(log), "--report",
                  str(folder / f"fit.{suffix}")],
        )
        assert res.exit_code == 0, res.stderr
    return folder / "fit.html", folder / "fit.pdf"


def test_pdf_columns_never_break_a_header_word():
    from reportlab.pdfbase.pdfmetrics import stringWidth

    long_text = "the residual follows the position, r = -0.92, in every trial " * 2
    row: list = ["m_a", "15.17", "0.035", "15.1 .. 15.2", "kg", "", long_text]
    block = Table([*HEADERS, "evidence"], [row])
    width = 450.0
    widths = _column_widths(block, width)
    assert sum(widths) == pytest.approx(width)
    for header, w in zip([*HEADERS, "evidence"], widths, strict=True):
        for word in header.split():
            assert w >= stringWidth(word, "Helvetica-Bold", 8) + 6, (header, w)


@pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed (CI installs it)")
def test_the_html_report_renders_in_a_browser(reports, tmp_path):
    html, _ = reports
    page = tmp_path / "page.html"
    page.write_text(html.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"))
    done = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1024,768",
         "--virtual-time-budget=10000", "--dump-dom", page.as_uri()],
        capture_output=True, text=True, timeout=120,
    )
    title = re.search(r"<title>(\{.*?\})</title>", done.stdout, re.S)
    assert title is not None, done.stderr[-2000:]
    seen = json.loads(title.group(1).replace("&quot;", '"'))
    assert seen["images"] >= 2 and seen["broken"] == [], seen
    assert seen["wide"] == [], seen
    assert seen["split"] == [], seen


@pytest.mark.skipif(PDFTOPPM is None or PDFTOTEXT is None, reason="poppler is not installed")
def test_the_pdf_report_renders_to_pages_with_whole_headers(reports, tmp_path):
    _, pdf = reports
    subprocess.run([PDFTOPPM, "-r", "30", "-png", str(pdf), str(tmp_path / "page")],
                   check=True, timeout=120)
    pages = sorted(tmp_path.glob("page*.png"))
    assert len(pages) >= 2
    from matplotlib.image import imread

    for png in pages:
        pixels = imread(png)
        assert pixels.std() > 0.01, f"{png.name} is blank"
    text = subprocess.run([PDFTOTEXT, "-layout", str(pdf), "-"], capture_output=True,
                          text=True, check=True, timeout=120).stdout
    lines = text.splitlines()
    header_line = next(line for line in lines if "parameter" in line and "value" in line)
    for word in ("parameter", "value", "error", "interval", "unit", "note"):
        assert re.search(rf"\b{word}\b", header_line), (word, header_line)
