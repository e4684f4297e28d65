"""The document model of a report and the number formatting its tables share.

A report is a title and a list of :class:`Section`; a section holds blocks that every
renderer draws (:class:`Paragraph`, :class:`Subheading`, :class:`Preformatted`,
:class:`Table`, :class:`Plot`), an optional HTML fragment (HTML only) and figures.
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:

    pass


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
    if dec is not None and np.isfinite(value) and stderr > abs(value):  # type: ignore[operator]
        # the error swamps the value: no digits the data do not hold ("6 ± 7253")
        return format_value(value, 2), format_value(stderr, 2)
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


def _e(text: object) -> str:
    """Escape text for HTML."""
    return html.escape(str(text), quote=True)


def _anchor(title: str) -> str:
    return "s-" + (re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-") or "section")
