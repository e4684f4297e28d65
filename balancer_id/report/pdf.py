"""The PDF renderer: a layout engine that flows text, tables and figures onto A4 pages
(matplotlib only)."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from typing import IO, TYPE_CHECKING, Any

import numpy as np

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

if TYPE_CHECKING:
    from matplotlib.figure import Figure



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
            if mono:
                room = (_PAGE[0] - 2 * _MARGIN - 0.15) / (0.6 * size / 72)  # monospace cells
                out += wrap_code(raw, int(room))
            else:
                out += textwrap.wrap(raw, width) if raw else [raw]
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
        ncols = max(len(table.columns), 1)
        longest = max(
            [len(c) for c in table.columns]
            + [len(_cell_text(c)) for row in table.rows for c in row]
            + [1]
        )
        size = 7.5 if ncols <= 7 and longest <= 60 else 6.5
        rows = list(table.rows) or [["-"] * ncols]
        layout = _TableLayout(table.columns, rows, size)
        whole = sum(layout.heights) + 0.35
        if whole <= _PAGE[1] - 2 * _MARGIN - 0.5 and self.y - whole < _MARGIN:
            self.new_page()  # a table that fits on one page is not split
        start = 0
        while start < len(rows):
            self.need(layout.header + 2 * max(layout.heights[start:], default=0.22))
            room = self.y - _MARGIN - 0.35 - layout.header
            stop = start + 1
            used = layout.heights[start]
            while stop < len(rows) and used + layout.heights[stop] <= room:
                used += layout.heights[stop]
                stop += 1
            self._draw_table(layout, start, stop)
            start = stop
            if start < len(rows):
                self.new_page()
        if table.caption:
            self.lines(table.caption, size=7.5, color="0.35", width=120)
        self.y -= 0.1

    def _draw_table(self, layout: _TableLayout, start: int, stop: int) -> None:
        """Rows ``start:stop`` of a laid-out table (with the header), wrapped to the page."""
        assert self.fig is not None
        heights = [layout.header, *layout.heights[start:stop]]
        height = sum(heights)
        width = sum(layout.widths)
        ax = self.fig.add_axes(
            (_MARGIN / _PAGE[0], (self.y - height) / _PAGE[1], width / _PAGE[0], height / _PAGE[1])
        )
        ax.axis("off")
        from matplotlib.transforms import Bbox

        rows = layout.rows[start:stop]
        tab = ax.table(
            cellText=layout.text[start:stop],
            colLabels=layout.columns or None,
            loc="upper left",
            cellLoc="left",
            bbox=Bbox.from_bounds(0, 0, 1, 1),
        )
        tab.auto_set_font_size(False)
        tab.set_fontsize(layout.size)
        for (r, c), cell in tab.get_celld().items():
            # widths and heights as laid out (the bbox scales them by exactly 1)
            cell.set_width(layout.widths[c] / width)
            cell.set_height(heights[r] / height)
            cell.set_edgecolor("#c9d0db")
            cell.set_linewidth(0.5)
            cell.PAD = 0.06 / layout.widths[c]  # 0.06 in, whatever the column's width
            cell.get_text().set_parse_math(False)
            cell.get_text().set_linespacing(1.15)
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


class _TableLayout:
    """A table's cells wrapped to fit the page width, with each column's width and each
    row's height (inches).

    Columns keep their natural width (the longest cell) while the table fits the text
    width; otherwise the narrow columns keep theirs and the wide ones share what is left
    (water-filling), their cells wrapped onto more lines (long words, paths and commands,
    are broken).
    """

    #: Character width as a fraction of the font size (DejaVu Sans, mixed text; generous).
    CHAR = 0.62
    #: Horizontal padding of a cell (inches, both sides).
    PAD = 0.14

    def __init__(self, columns: Sequence[str], rows: Sequence[Sequence[str | Cell]], size: float):
        self.columns = list(columns)
        self.rows = [list(r) + [""] * (len(self.columns) - len(r)) for r in rows]
        self.size = size
        ncols = max(len(self.columns), 1)
        raw = [[_cell_text(c) for c in row] for row in self.rows]
        char_in = size * self.CHAR / 72
        natural = [
            max([len(self.columns[j])] + [len(line) for r in raw for line in r[j].splitlines()])
            for j in range(len(self.columns))
        ]
        budget = (_PAGE[0] - 2 * _MARGIN - 0.05) / char_in - ncols * self.PAD / char_in
        caps = list(natural)
        if sum(natural) > budget:  # water-filling: narrow columns whole, wide ones share
            left, order = budget, sorted(range(len(natural)), key=lambda j: natural[j])
            for k, j in enumerate(order):
                share = left / (len(order) - k)
                caps[j] = max(4, min(natural[j], int(share)))
                left -= caps[j]
        self.widths = [max(caps[j], 1) * char_in + self.PAD for j in range(len(self.columns))]
        self.text = [[_wrap(r[j], caps[j]) for j in range(len(self.columns))] for r in raw]
        self.columns = [_wrap(h, caps[j]) for j, h in enumerate(self.columns)]
        line = size / 72 * 1.2
        self.header = max([h.count("\n") + 1 for h in self.columns] + [1]) * line + 0.09
        self.heights = [
            max([t.count("\n") + 1 for t in r] + [1]) * line + 0.09 for r in self.text
        ]


def _wrap(text: str, width: int) -> str:
    """``text`` wrapped to ``width`` characters (long words broken), lines joined by \\n."""
    out: list[str] = []
    for raw in text.splitlines() or [""]:
        out += textwrap.wrap(raw, max(width, 1), break_on_hyphens=False) or [""]
    return "\n".join(out)


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

