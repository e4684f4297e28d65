"""The document model of a report (numbers are formatted by :mod:`balancer_id.numbers`).

A report is a title and a list of :class:`Section`; a section holds blocks that every
renderer draws (:class:`Paragraph`, :class:`Subheading`, :class:`Preformatted`,
:class:`Table`, :class:`Plot`), an optional HTML fragment (HTML only) and figures.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


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
