"""The parameters of a fit as every renderer shows them: the columns and each cell's text.

Beside :data:`~balancer_id.metric_fields.FIT_METRICS`: the terminal (from the JSON's
``parameters``), the notebook table and the HTML/PDF report (from the fit's parameters)
list :data:`PARAM_FIELDS`, so an estimate, its error, its interval and its note read the
same everywhere, and a new column is one line here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from balancer_id.numbers import format_estimate, format_interval, format_number

__all__ = ["PARAM_FIELDS", "ParamField", "interval_text", "note_text", "parameter_cells"]


def _get(p: Any, key: str, default: Any = None) -> Any:
    """A parameter's ``key``, whether it is the JSON's mapping or a fit's object."""
    if isinstance(p, Mapping):
        return p.get(key, default)
    return getattr(p, key, default)


def _value_text(p: Any) -> str:
    """The estimate to the digits its error holds (a bound claimed instead, issue 31)."""
    claim = _get(p, "claim")
    if claim:
        return str(claim)
    return format_estimate(_get(p, "value"), _get(p, "stderr"))[0]


def _stderr_text(p: Any) -> str:
    if not _get(p, "vary", True):
        return "-"
    return format_estimate(_get(p, "value"), _get(p, "stderr"))[1]


def interval_text(p: Any) -> str:
    """The 95 % interval of an estimate: the profile one marked so, else Wald's.

    Parameters
    ----------
    p : mapping or object
        A parameter (``value``, ``stderr``, ``vary``, ``ci95``, ``ci95_method``).

    Returns
    -------
    str
        ``lo .. hi`` (``(profile)`` after a profile-likelihood interval); ``-`` for a
        held parameter or one without an error.
    """
    if not _get(p, "vary", True):
        return "-"
    ci = _get(p, "ci95")
    if _get(p, "ci95_method") == "profile" and ci is not None:
        return f"{format_number(ci[0], 3)} .. {format_number(ci[1], 3)} (profile)"
    return format_interval(_get(p, "value"), _get(p, "stderr"))


def note_text(p: Any) -> str:
    """What a reader must know of an estimate: held, a bound only, at a bound, loose.

    Parameters
    ----------
    p : mapping or object
        A parameter.

    Returns
    -------
    str
        ``held (not fitted)``, ``not trusted`` (a check such as the drive's timing moved
        it beyond its error), ``not reached``/``not resolved`` (a bound claimed),
        ``at upper bound``, ``poorly determined`` (an error larger than the value), or ''.
    """
    if not _get(p, "vary", True):
        return "held (not fitted)"
    if _get(p, "distrust"):  # a check moved it beyond its error: this one not trusted
        return "not trusted"
    if _get(p, "claim"):  # a bound, not a value (issue 31)
        return "not reached" if _get(p, "not_reached") == "above" else "not resolved"
    if _get(p, "at_bound"):
        return f"at {_get(p, 'at_bound')} bound"
    se, value = _get(p, "stderr"), _get(p, "value")
    if se is None or not math.isfinite(se) or se > abs(value):
        return "poorly determined"
    return ""


@dataclass(frozen=True)
class ParamField:
    """One column of the parameter table.

    Attributes
    ----------
    key : str
        Its name (``value``, ``stderr``...).
    heading : str
        The column's heading.
    text : callable
        The cell's text of a parameter (the JSON's mapping or a fit's object).
    """

    key: str
    heading: str
    text: Callable[[Any], str]


#: The columns of the parameter table, after the parameter's name, in the order every
#: renderer shows them.
PARAM_FIELDS: tuple[ParamField, ...] = (
    ParamField("value", "value", _value_text),
    ParamField("stderr", "std. error", _stderr_text),
    ParamField("interval", "95 % interval", interval_text),
    ParamField("unit", "unit", lambda p: str(_get(p, "unit", "") or "")),
    ParamField("note", "note", note_text),
)


def parameter_cells(p: Any) -> dict[str, str]:
    """Every column's text of one parameter.

    Parameters
    ----------
    p : mapping or object
        A parameter: the JSON's ``parameters[name]`` or a fit's parameter.

    Returns
    -------
    dict of str to str
        :attr:`ParamField.key` -> text, in :data:`PARAM_FIELDS`' order.
    """
    return {f.key: f.text(p) for f in PARAM_FIELDS}
