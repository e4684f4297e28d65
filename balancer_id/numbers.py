"""The one number formatter: every medium (text, terminal, notebook, HTML, PDF, plots)
shows numbers through these functions, with the same thresholds.

- :func:`format_number`: significant digits, trailing zeros kept (``0.03000``), ``-`` for
  missing or non-finite values.
- :func:`format_estimate`: an estimate and its standard error to two significant digits
  of the error (``15.08``, ``0.12``); an error that swamps the value gets two digits each.
- :func:`format_with_uncertainty`: the same as one text, ``15.08 ± 0.12``.
- :func:`format_interval`: the approximate 95 % interval ``value ± 1.96 stderr``.
"""

from __future__ import annotations

import math

__all__ = ["format_estimate", "format_interval", "format_number", "format_with_uncertainty"]

#: Values shown in fixed-point notation with an error's decimals lie in this range;
#: outside it, significant digits.
FIXED_RANGE = (1e-3, 1e6)
#: Most decimals an error may ask for.
MAX_DECIMALS = 8


def _finite(x: object) -> float | None:
    try:
        xf = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None
    return xf if math.isfinite(xf) else None


def format_number(x: object, digits: int = 4) -> str:
    """A number to ``digits`` significant digits, trailing zeros kept.

    Parameters
    ----------
    x : float or None
        The number (anything ``float`` accepts; other objects are shown as text).
    digits : int
        Significant digits.

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
    if not math.isfinite(xf):
        return "-"
    text = f"{xf:#.{digits}g}"  # keeps trailing zeros: 0.03000, not 0.03
    mantissa, e, exponent = text.partition("e")
    return mantissa.rstrip(".") + e + exponent


def _decimals(stderr: float | None) -> int | None:
    """Decimals that show two significant digits of ``stderr``."""
    err = _finite(stderr)
    if err is None or err <= 0:
        return None
    return int(min(max(1 - math.floor(math.log10(err)), 0), MAX_DECIMALS))


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
        ``(value, stderr)``.
    """
    dec = _decimals(stderr)
    v = _finite(value)
    if dec is not None and v is not None and float(stderr) > abs(v):  # type: ignore[arg-type]
        # the error swamps the value: no digits the data do not hold ("6 ± 7253")
        return format_number(value, 2), format_number(stderr, 2)
    if dec is None or v is None or not FIXED_RANGE[0] <= abs(v) < FIXED_RANGE[1]:
        return format_number(value), format_number(stderr, 2)
    return f"{v:.{dec}f}", f"{float(stderr):.{dec}f}"  # type: ignore[arg-type]


def format_with_uncertainty(value: float, stderr: float | None) -> str:
    """An estimate and its error as one text: ``15.08 ± 0.12``; the value alone without
    a usable error.

    Parameters
    ----------
    value : float
        The estimate.
    stderr : float or None
        Its standard error.

    Returns
    -------
    str
    """
    shown, err = format_estimate(value, stderr)
    return shown if _decimals(stderr) is None else f"{shown} ± {err}"


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
    err = _finite(stderr)
    if err is None:
        return "-"
    dec = _decimals(err)
    lo, hi = value - 1.96 * err, value + 1.96 * err
    if dec is None or not FIXED_RANGE[0] <= max(abs(lo), abs(hi)) < FIXED_RANGE[1]:
        return f"{format_number(lo)} .. {format_number(hi)}"
    return f"{lo:.{dec}f} .. {hi:.{dec}f}"
