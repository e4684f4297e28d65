"""The command-line spelling of values, parsed: numbers, ``NAME=VALUE`` items, bounds.

The commands and the workflows behind them share these, so a message names the option
the same way wherever a value is checked.
"""

from __future__ import annotations

import math
from typing import Any

from balancer_id.errors import UsageError


def at_least(value: int | float, low: int | float, option: str) -> None:
    """Refuse a number below ``low`` (or not finite).

    Parameters
    ----------
    value : int or float
        The option's value.
    low : int or float
        The smallest value allowed.
    option : str
        The option's name, for the message.

    Raises
    ------
    UsageError
        When ``value`` is below ``low`` or not finite.
    """
    if not (isinstance(value, int) or math.isfinite(value)) or value < low:
        raise UsageError(f"{option} {value}: give a number >= {low}")


def floats(text: str | None, what: str) -> list[float] | None:
    """Numbers separated by commas, or None.

    Parameters
    ----------
    text : str or None
        The option's value.
    what : str
        The option's name, for the error message.

    Returns
    -------
    list of float or None

    Raises
    ------
    UsageError
        When an item is not a number.
    """
    if text is None:
        return None
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UsageError(f"{what} '{text}': give numbers separated by commas") from None


def assignments(items: list[str] | None, what: str) -> dict[str, float]:
    """``NAME=VALUE`` items as a dict.

    Parameters
    ----------
    items : list of str or None
        The repeated option's values.
    what : str
        The option's name, for the error message.

    Returns
    -------
    dict of str to float

    Raises
    ------
    UsageError
        When an item is not ``NAME=NUMBER``.
    """
    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[name.strip()] = float(value)
        except ValueError:
            raise UsageError(f"{what} '{item}': expected NAME=VALUE, e.g. m_a=15.1") from None
    return out


def trajectory(text: str | None) -> Any:
    """The ``--trajectory`` reference move, or None.

    Parameters
    ----------
    text : str or None
        ``trapezoid:distance=..,speed=..,accel=..[,start=..]``.

    Returns
    -------
    Trapezoid, TabulatedMove or None

    Raises
    ------
    UsageError
        When the text is malformed.
    """
    if text is None:  # before any import: a batch's start waits for this
        return None
    from balancer_id.trials import reference_move

    return reference_move(text)


def bounds(items: list[str] | None) -> dict[str, tuple[float, float]]:
    """``NAME=MIN:MAX`` items (``--bounds``) as a dict.

    Parameters
    ----------
    items : list of str or None
        The repeated option's values.

    Returns
    -------
    dict of str to (float, float)

    Raises
    ------
    UsageError
        When an item is not ``NAME=MIN:MAX``.
    """
    out: dict[str, tuple[float, float]] = {}
    for item in items or []:
        name, sep, span = item.partition("=")
        lo, colon, hi = span.partition(":")
        try:
            if not (sep and colon):
                raise ValueError
            out[name.strip()] = (float(lo), float(hi))
        except ValueError:
            raise UsageError(f"--bounds '{item}': expected NAME=MIN:MAX, e.g. m_a=5:30") from None
    return out


def names(items: list[str] | None) -> tuple[str, ...]:
    """Names given repeatedly or joined by commas (``--track A --track D0,D1``).

    Parameters
    ----------
    items : list of str or None
        The repeated option's values.

    Returns
    -------
    tuple of str
        Each name, stripped, in order.
    """
    return tuple(n.strip() for item in items or [] for n in item.split(",") if n.strip())
