"""The diagnosis's fields as every renderer takes them: the JSON key, where it is read
from, and, for a figure shown as one line, that line.

Beside :data:`~balancer_id.param_fields.PARAM_FIELDS`:
:meth:`~balancer_id.diagnostics.diagnosis.Diagnosis.to_dict` builds the ``diagnose``
object by walking :data:`DIAGNOSIS_FIELDS` in order, and the terminal
(:func:`~balancer_id.report.terminal.print_diagnosis`), the notebook
(``Diagnosis.summary()``) and the report's Diagnosis section show every field that has a
``line`` through :func:`fact_lines`. A new field of the diagnosis is its dataclass line
and its line here.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["DIAGNOSIS_FIELDS", "DiagnosisField", "fact_lines"]


@dataclass(frozen=True)
class DiagnosisField:
    """One key of the ``diagnose`` JSON object.

    Attributes
    ----------
    key : str
        The JSON key (CONTRACT.md).
    of : callable
        Its value, from the :class:`~balancer_id.diagnostics.diagnosis.Diagnosis`
        (JSON-ready after :func:`~balancer_id.jsonsafe.json_ready`).
    line : callable or None
        The one line every renderer shows for the JSON value (not shown when the value
        is None); None: the renderers' own sections show it (a table, a paragraph).
    """

    key: str
    of: Callable[[Any], Any]
    line: Callable[[Any], str] | None = None


def _metrics(d: Any) -> dict[str, Any]:
    return {
        **d.match.metrics,
        "noise_floor": d.context.noise_floor,
        "excess_rmse": d.context.excess_rmse(),
    }


#: The ``diagnose`` object's keys, in order.
DIAGNOSIS_FIELDS: tuple[DiagnosisField, ...] = (
    DiagnosisField("model", lambda d: d.match.model.spec),
    DiagnosisField("metrics", _metrics),
    DiagnosisField("parameters", lambda d: {k: p.to_dict() for k, p in d.match.parameters.items()}),
    DiagnosisField("residual_tests", lambda d: d.tests.to_dict()),
    DiagnosisField("verdict", lambda d: d.verdict),
    DiagnosisField("summary", lambda d: d.summary),
    DiagnosisField("suggestions", lambda d: [s.to_dict() for s in d.suggestions]),
    DiagnosisField("failed_candidates", lambda d: d.failures),
    DiagnosisField("tests", lambda d: d.checks),
    DiagnosisField("explanations", lambda d: [e.to_dict() for e in d.explanations]),
    DiagnosisField("ambiguity", lambda d: d.ambiguity),
    DiagnosisField("notes", lambda d: [n.to_dict() for n in d.notes]),
    DiagnosisField(
        "discovery", lambda d: d.discovery.to_dict() if d.discovery is not None else None
    ),
)


def fact_lines(data: Mapping[str, Any]) -> list[str]:
    """The one-line figures of a ``diagnose`` object, in the fields' order.

    Parameters
    ----------
    data : mapping
        The ``diagnose`` JSON object (or the values of the fields with a ``line``).

    Returns
    -------
    list of str
        One line per field with a ``line`` whose value is present and not None.
    """
    return [
        f.line(data[f.key])
        for f in DIAGNOSIS_FIELDS
        if f.line is not None and data.get(f.key) is not None
    ]
