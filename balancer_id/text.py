"""Text shown to a person: file and run names made safe for terminals, HTML and plots.

A file name is whatever bytes the file system holds: terminal escape sequences, a
carriage return, bytes that are not UTF-8 (Python keeps them as lone surrogates), or a
``$`` that matplotlib would read as the start of a formula. Everything that shows a name
passes it through :func:`shown`; every figure passes through :func:`make_figure_text_safe`
before it is drawn.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["make_figure_text_safe", "one_line", "printable", "shown"]


def shown(text: object) -> str:
    """``text`` as it may be shown: undecodable bytes and control characters written
    visibly (``\\xff``, ``\\x1b``, ``\\r``), line breaks kept.

    Parameters
    ----------
    text : object
        A name or a message (``str()`` is taken).

    Returns
    -------
    str
        Printable text that encodes as UTF-8.
    """
    value = str(text)
    if value.isprintable():
        return value
    value = value.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    return "".join(ch if ch.isprintable() or ch == "\n" else repr(ch)[1:-1] for ch in value)


def _math_ok(text: str) -> bool:
    """Whether matplotlib can draw ``text`` (its ``$...$`` parts parse as mathtext)."""
    if "$" not in text:
        return True
    from matplotlib.mathtext import MathTextParser

    try:
        MathTextParser("path").parse(text)
    except Exception:  # mathtext raises ValueError or pyparsing's own errors
        return False
    return True


def make_figure_text_safe(fig: Any) -> Any:
    """Make every text of the matplotlib figure ``fig`` drawable, in place.

    Names with undecodable bytes or control characters are shown escaped (:func:`shown`);
    a text whose ``$`` signs do not form a formula matplotlib can parse (a ``$`` in a file
    name) is drawn literally, its ``$`` escaped.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure about to be saved.

    Returns
    -------
    matplotlib.figure.Figure
        ``fig``.
    """
    from matplotlib.text import Text

    for artist in fig.findobj(Text):
        text = artist.get_text()
        if not text:
            continue
        safe = shown(text)
        if not _math_ok(safe):
            safe = safe.replace("\\$", "$").replace("$", "\\$")
        if safe != text:
            artist.set_text(safe)
    return fig


def printable(obj: Any) -> Any:
    """``obj`` with control characters in every string made visible (``\\x1b``), so a run
    or file name holding terminal escape sequences cannot drive the user's terminal.

    Parameters
    ----------
    obj : object
        JSON-like data.

    Returns
    -------
    object
        The same structure, strings escaped.
    """
    if isinstance(obj, str):
        if obj.isprintable():
            return obj
        return "".join(ch if ch.isprintable() or ch == "\n" else repr(ch)[1:-1] for ch in obj)
    if isinstance(obj, Mapping):
        return {k: printable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [printable(v) for v in obj]
    return obj


def one_line(text: object) -> str:
    """``text`` on one line, with control characters (terminal escapes) made visible.

    Parameters
    ----------
    text : object
        A message.

    Returns
    -------
    str
    """
    flat = " ".join(str(text).split())
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in flat)
