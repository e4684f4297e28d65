"""The PDF renderer: the report's blocks as reportlab flowables on A4 pages.

reportlab's platypus lays out the text, tables (repeated header rows when a table
spans pages) and figures; this module only maps each block to a flowable: a
:class:`~balancer_id.report.blocks.Paragraph` to a paragraph, a
:class:`~balancer_id.report.blocks.Table` to a styled table, a
:class:`~balancer_id.report.blocks.Plot` to the figure as a PNG image across the text
width with its numbered caption.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import IO, Any
from xml.sax.saxutils import escape

from balancer_id.report.blocks import (
    Cell,
    Paragraph,
    Plot,
    Preformatted,
    Section,
    Subheading,
    Table,
)
from balancer_id.report.html import _html_text
from balancer_id.text import make_figure_text_safe

__all__ = ["code_lines", "render_pdf", "wrap_code"]

#: Resolution of figures on the printed page (dots per inch).
PDF_DPI = 170
#: Background of a table cell by its style.
STYLE_COLORS = {"good": "#e3f4e8", "warn": "#fff3d6", "bad": "#fbe0dd"}
_INK = "#14213d"


def _styles() -> dict[str, Any]:
    from reportlab.lib import colors
    from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet

    base = getSampleStyleSheet()
    ink = colors.HexColor(_INK)
    return {
        "title": ParagraphStyle("title", parent=base["Title"], fontSize=18, textColor=ink,
                                alignment=0, spaceAfter=4),
        "subtitle": ParagraphStyle("subtitle", parent=base["Normal"], fontSize=11,
                                   textColor=colors.HexColor("#404040")),
        "meta": ParagraphStyle("meta", parent=base["Normal"], fontSize=8.5,
                               textColor=colors.HexColor("#737373"), spaceAfter=6),
        "h1": ParagraphStyle("h1", parent=base["Heading2"], fontSize=13, textColor=ink,
                             spaceBefore=10, spaceAfter=4),
        "h2": ParagraphStyle("h2", parent=base["Heading3"], fontSize=10.5, textColor=ink,
                             spaceBefore=6, spaceAfter=2),
        "body": ParagraphStyle("body", parent=base["Normal"], fontSize=9, leading=12,
                               spaceAfter=4),
        "code": ParagraphStyle("code", parent=base["Code"], fontSize=7.5, leading=9.5,
                               leftIndent=0, firstLineIndent=0),
        "cell": ParagraphStyle("cell", parent=base["Normal"], fontSize=8, leading=10),
        "caption": ParagraphStyle("caption", parent=base["Italic"], fontSize=8, leading=10,
                                  textColor=colors.HexColor("#404040"), spaceAfter=8),
    }  # fmt: skip


def wrap_code(line: str, width: int) -> list[str]:
    """Break a code line at spaces to ``width`` characters, shell-style.

    Every line but the last ends in `` \\`` and the next is indented, so a wrapped
    command copied from the PDF still runs as one command; a word longer than the line
    stays whole.

    Parameters
    ----------
    line : str
        One line of code.
    width : int
        Characters that fit on the page.

    Returns
    -------
    list of str
        The line, or its pieces.
    """
    if len(line) <= width:
        return [line]
    out: list[str] = []
    current = ""
    for word in line.split(" "):
        trial = f"{current} {word}" if current else word
        if current and len(trial) + 2 > width:
            out.append(current + " \\")
            current = "    " + word
        else:
            current = trial
    out.append(current)
    return out


#: Courier's advance per character, as a share of the font size.
MONO_ADVANCE = 0.6


def code_lines(text: str, width_pt: float, font_size: float) -> list[str]:
    """Preformatted text as lines that fit ``width_pt`` (shell-style continuations).

    Parameters
    ----------
    text : str
        The text (several lines).
    width_pt : float
        The text width (points).
    font_size : float
        The monospaced font's size (points).

    Returns
    -------
    list of str
    """
    chars = max(int(width_pt / (MONO_ADVANCE * font_size)), 20)
    return [piece for line in text.splitlines() for piece in wrap_code(line, chars)]


def _text(text: str) -> str:
    """Plain text as reportlab paragraph markup (escaped, line breaks kept)."""
    return escape(text).replace("\n", "<br/>")


def _table(block: Table, styles: dict[str, Any], width: float) -> list[Any]:
    from reportlab.lib import colors
    from reportlab.platypus import Paragraph as P
    from reportlab.platypus import Table as T
    from reportlab.platypus import TableStyle

    cell = styles["cell"]
    head = [P(f"<b>{_text(c)}</b>", cell) for c in block.columns]
    body = [[P(_text(c.text if isinstance(c, Cell) else str(c)), cell) for c in row]
            for row in block.rows]  # fmt: skip
    table = T([head, *body], repeatRows=1, hAlign="LEFT", colWidths=_column_widths(block, width))
    style = [
        ("BACKGROUND", (0, 0), (-1, 0), colors.HexColor("#e8edf5")),
        ("LINEBELOW", (0, 0), (-1, 0), 0.6, colors.HexColor(_INK)),
        ("LINEBELOW", (0, 1), (-1, -1), 0.25, colors.HexColor("#d0d0d0")),
        ("VALIGN", (0, 0), (-1, -1), "TOP"),
        ("LEFTPADDING", (0, 0), (-1, -1), 3),
        ("RIGHTPADDING", (0, 0), (-1, -1), 3),
    ]
    for r, row in enumerate(block.rows, start=1):
        for c, value in enumerate(row):
            shade = STYLE_COLORS.get(value.style) if isinstance(value, Cell) else None
            if shade:
                style.append(("BACKGROUND", (c, r), (c, r), colors.HexColor(shade)))
    table.setStyle(TableStyle(style))
    out: list[Any] = [table]
    if block.caption:
        out.append(P(_text(block.caption), styles["caption"]))
    return out


def _column_widths(block: Table, width: float, size: float = 8.0) -> list[float]:
    """Widths of the columns: each at least as wide as its longest word (a header such as
    "unit" never breaks mid-word; a cell's word counts up to 30 % of the page), the rest of
    the page shared in proportion to the columns' longest texts (capped)."""
    from reportlab.pdfbase.pdfmetrics import stringWidth

    pad = 7.0  # the cell's left and right padding, and a point to spare

    def widest_word(text: str, font: str) -> float:
        return max((stringWidth(w, font, size) for w in text.split()), default=0.0) + pad

    floor = [widest_word(c, "Helvetica-Bold") for c in block.columns]
    longest = [len(c) for c in block.columns]
    for row in block.rows:
        for k, value in enumerate(row[: len(longest)]):
            text = value.text if isinstance(value, Cell) else str(value)
            longest[k] = max(longest[k], min(len(text), 60))
            floor[k] = max(floor[k], min(widest_word(text, "Helvetica"), 0.3 * width))
    if sum(floor) >= width:  # too many columns for the page: shrink all alike
        return [width * f / sum(floor) for f in floor]
    share = [max(n, 3) for n in longest]
    spare = width - sum(floor)
    return [f + spare * n / sum(share) for f, n in zip(floor, share, strict=True)]


def _figure(block: Plot, number: int, styles: dict[str, Any], width: float) -> list[Any]:
    from reportlab.platypus import Image
    from reportlab.platypus import Paragraph as P

    figure = block.figure
    if isinstance(figure, bytes | bytearray):
        png = bytes(figure)
    else:
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        if not isinstance(getattr(figure, "canvas", None), FigureCanvasAgg):
            FigureCanvasAgg(figure)
        buffer = io.BytesIO()
        make_figure_text_safe(figure).savefig(buffer, format="png", dpi=PDF_DPI)
        png = buffer.getvalue()
    from reportlab.lib.utils import ImageReader

    w_px, h_px = ImageReader(io.BytesIO(png)).getSize()
    height = width * h_px / max(w_px, 1)
    image = Image(io.BytesIO(png), width=width, height=height)
    caption = f"Figure {number}. {block.caption}".strip()
    return [image, P(_text(caption), styles["caption"])]


def render_pdf(
    fh: IO[bytes], title: str, subtitle: str, sections: Sequence[Section], meta: dict[str, str]
) -> None:
    """Write the report as a PDF.

    Parameters
    ----------
    fh : binary file
        Where the PDF goes.
    title, subtitle : str
        The report's title and subtitle.
    sections : sequence of Section
        The content.
    meta : dict of str to str
        ``balancer-id`` (the version) and ``date``.
    """
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import cm
    from reportlab.platypus import Paragraph as P
    from reportlab.platypus import SimpleDocTemplate, Spacer

    styles = _styles()
    margin = 1.5 * cm
    doc = SimpleDocTemplate(
        fh, pagesize=A4, leftMargin=margin, rightMargin=margin, topMargin=margin,
        bottomMargin=margin, title=title, subject=subtitle,
        creator=f"balancer-id {meta['balancer-id']}",
    )  # fmt: skip
    width = doc.width
    story: list[Any] = [P(_text(title), styles["title"])]
    if subtitle:
        story.append(P(_text(subtitle), styles["subtitle"]))
    story.append(P(_text(f"balancer-id {meta['balancer-id']} · {meta['date']}"), styles["meta"]))
    figures = 0
    for k, section in enumerate(sections, 1):
        story.append(P(_text(f"{k}. {section.title}"), styles["h1"]))
        blocks = section.all_blocks()
        if section.html and not section.blocks:
            story.append(P(_text(_html_text(section.html)), styles["body"]))
        for block in blocks:
            if isinstance(block, Paragraph):
                story.append(P(_text(block.text), styles["body"]))
            elif isinstance(block, Subheading):
                story.append(P(_text(block.text), styles["h2"]))
            elif isinstance(block, Preformatted):
                code = styles["code"]
                lines = code_lines(block.text, width, code.fontSize)
                story.append(P(_text("\n".join(lines)).replace(" ", "&nbsp;"), code))
                story.append(Spacer(1, 4))
            elif isinstance(block, Table):
                story.extend(_table(block, styles, width))
                story.append(Spacer(1, 6))
            else:
                figures += 1
                story.extend(_figure(block, figures, styles, width))

    def footer(canvas: Any, document: Any) -> None:
        canvas.saveState()
        canvas.setFont("Helvetica", 7.5)
        canvas.setFillColorRGB(0.45, 0.45, 0.45)
        canvas.drawRightString(A4[0] - margin, 0.8 * cm, f"page {document.page}")
        if document.page > 1:
            canvas.drawString(margin, A4[1] - 0.9 * cm, title)
        canvas.restoreState()

    doc.build(story, onFirstPage=footer, onLaterPages=footer)
