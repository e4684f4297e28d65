"""The outcome of a batch: one row per log, the per-log JSON and ``summary.csv``.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from balancer_id.errors import BalancerIdError
from balancer_id.files import atomic_write_text

if TYPE_CHECKING:
    pass


#: Name of the summary table written into the output folder.
SUMMARY_NAME = "summary.csv"


#: Fit metrics copied into the summary (CONTRACT.md ``fit`` ``metrics``).
METRIC_COLUMNS = ("rmse", "nrmse_fit_percent", "aic", "bic")


#: Parameters that always have their own columns, first (MODEL.md's classic pair).
LEADING_PARAMETERS = ("m_a", "T_a")


#: Exit code of a failed row that is not a balancer-id error (as the CLI's internal error).
INTERNAL_EXIT_CODE = 1
#: The exit code of a log the batch never reached because it was interrupted (CONTRACT.md:
#: 130, interrupted): not a bug, and ``--resume`` identifies it.
INTERRUPTED_EXIT_CODE = 130


Payload = dict[str, Any]


@dataclass
class BatchRow:
    """The outcome of one log.

    Attributes
    ----------
    file : str
        The log, as given (or as found in a given folder).
    status : str
        ``"ok"`` or ``"failed"``.
    json : str or None
        The per-log JSON written into the output folder.
    error : str or None
        One-line message of a failed log (it names the file).
    exit_code : int
        0 when identified, else what ``balancer-id fit`` would have exited with
        (3 unreadable log, 4 identification impossible, 5 fitted but not trusted, 1
        internal error).
    model : str or None
        The model's spec.
    n_trials : int or None
        Trials fitted.
    parameters : dict
        Name -> ``{"value", "stderr"}`` of each fitted parameter.
    metrics : dict
        ``rmse``, ``nrmse_fit_percent``, ``aic``, ``bic``.
    seconds : float or None
        Wall time of the fit in its worker (None when the worker died).
    warnings : list of str
        The fit's warnings (poorly determined parameters, bounds reached, ...).
    trusted : bool
        False when the fit's notes say its values cannot be trusted (``fit`` ``trusted``).
    diagnosis_verdict : str or None
        The log's own diagnosis verdict (``batch --diagnose``), else None.
    """

    file: str
    status: str
    json: str | None = None
    error: str | None = None
    exit_code: int = 0
    model: str | None = None
    n_trials: int | None = None
    parameters: dict[str, dict[str, float | None]] = field(default_factory=dict)
    metrics: dict[str, float | None] = field(default_factory=dict)
    seconds: float | None = None
    warnings: list[str] = field(default_factory=list)
    trusted: bool = True
    diagnosis_verdict: str | None = None

    @property
    def ok(self) -> bool:
        """Whether the log was identified."""
        return self.status == "ok"

    @property
    def verdict(self) -> str:
        """What summary.csv says of the log.

        ``failed``; ``not trusted`` (a parameter at a bound the data did not choose,
        starts that disagree); with ``--diagnose`` the diagnosis's own verdict
        (``adequate``, ``effect missing``, ...); else ``identified`` or ``identified,
        check the warnings``. A fit that cannot determine a parameter is not just "ok".
        """
        if not self.ok:
            return "failed"
        if not self.trusted:
            return "not trusted"
        if self.diagnosis_verdict is not None:  # --diagnose: the log's own diagnosis says
            return self.diagnosis_verdict
        return "identified, check the warnings" if self.warnings else "identified"

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "file": self.file,
            "status": self.status,
            "json": self.json,
            "error": self.error,
            "exit_code": self.exit_code,
            "model": self.model,
            "n_trials": self.n_trials,
            "parameters": {k: dict(v) for k, v in self.parameters.items()},
            "metrics": dict(self.metrics),
            "seconds": self.seconds,
            "verdict": self.verdict,
            "warnings": list(self.warnings),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> BatchRow:
        """The row a :meth:`to_dict` object describes (``to_dict`` gives it back).

        The ``verdict`` tells what the row held: ``not trusted``, a diagnosis's verdict, or
        neither (``identified``...).

        Parameters
        ----------
        data : mapping
            A row of ``batch --json``'s ``rows``.

        Returns
        -------
        BatchRow
        """
        verdict = str(data.get("verdict", ""))
        plain = {"failed", "not trusted", "identified", "identified, check the warnings"}
        return cls(
            file=str(data["file"]),
            status=str(data["status"]),
            json=data.get("json"),
            error=data.get("error"),
            exit_code=int(data.get("exit_code") or 0),
            model=data.get("model"),
            n_trials=data.get("n_trials"),
            parameters={k: dict(v) for k, v in (data.get("parameters") or {}).items()},
            metrics=dict(data.get("metrics") or {}),
            seconds=data.get("seconds"),
            warnings=[str(w) for w in data.get("warnings") or []],
            trusted=verdict != "not trusted",
            diagnosis_verdict=None if verdict in plain else verdict,
        )

    def summary_record(self, parameter_names: Sequence[str]) -> dict[str, object]:
        """The row's cells of ``summary.csv`` (see :func:`summary_columns`).

        Parameters
        ----------
        parameter_names : sequence of str
            The parameters that have columns (those this row lacks stay empty).

        Returns
        -------
        dict
            Column name -> value (None for an empty cell).
        """
        rec: dict[str, object] = {
            "file": self.file,
            "status": self.status,
            "error": self.error,
            "exit_code": self.exit_code,
            "model": self.model,
            "n_trials": self.n_trials,
        }
        for name in parameter_names:
            par = self.parameters.get(name, {})
            rec[name] = par.get("value")
            rec[f"{name}_stderr"] = par.get("stderr")
        for name in METRIC_COLUMNS:
            rec[name] = self.metrics.get(name)
        rec["seconds"] = self.seconds
        rec["json"] = self.json
        rec["verdict"] = self.verdict
        rec["warnings"] = " | ".join(self.warnings) or None
        return rec


@dataclass
class BatchResult:
    """Everything ``balancer-id batch`` reports.

    Attributes
    ----------
    rows : list of BatchRow
        One per log, in input order.
    out_dir : Path
        The output folder.
    summary_path : Path
        ``summary.csv`` in the output folder.
    seconds : float
        Wall time of the whole batch.
    shared_fit : dict or None
        With ``per_log``: the counted logs fitted together (``shared_fit.json``).
    """

    rows: list[BatchRow]
    out_dir: Path
    summary_path: Path
    seconds: float = 0.0
    shared_fit: dict[str, Any] | None = None

    @property
    def n_ok(self) -> int:
        """Logs identified."""
        return sum(row.ok for row in self.rows)

    @property
    def n_failed(self) -> int:
        """Logs that failed."""
        return len(self.rows) - self.n_ok

    @property
    def exit_code(self) -> int:
        """0 when every log was identified, 3 when any failed (CONTRACT.md)."""
        return 0 if self.n_failed == 0 else 3

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict: counts, paths and every row."""
        return {
            "out_dir": str(self.out_dir),
            "summary": str(self.summary_path),
            "n_logs": len(self.rows),
            "n_ok": self.n_ok,
            "n_failed": self.n_failed,
            "exit_code": self.exit_code,
            "seconds": self.seconds,
            "rows": [row.to_dict() for row in self.rows],
            **({"shared_fit": self.shared_fit} if self.shared_fit is not None else {}),
        }


@dataclass(frozen=True)
class _Task:
    display: str  # the path as the user gave it
    path: str  # absolute: workers may run elsewhere, or from another folder
    output: Path  # the per-log JSON


def _fill_missing(rows: list[BatchRow | None], tasks: list[_Task], spec: str) -> list[BatchRow]:
    """Rows in task order; a log without a result (the batch stopped early) is failed."""
    return [
        row
        if row is not None
        else BatchRow(
            file=task.display,
            status="failed",
            error=(
                f"{task.display}: not identified: the batch was stopped before this log "
                "(run it again with --resume)"
            ),
            exit_code=INTERRUPTED_EXIT_CODE,
            model=spec,
        )
        for row, task in zip(rows, tasks, strict=True)
    ]


def _failure(message: str, exit_code: int, seconds: float | None = None) -> Payload:
    return {
        "status": "failed",
        "error": " ".join(str(message).split()),
        "exit_code": exit_code,
        "seconds": seconds,
    }


def _internal(exc: BaseException) -> Payload:
    return _failure(f"internal error: {type(exc).__name__}: {exc}", INTERNAL_EXIT_CODE)


def _crashed(what: str) -> Payload:
    return _failure(f"internal error: {what} (killed, or out of memory?)", INTERNAL_EXIT_CODE)


# Output -------------------------------------------------------------------------------
def _relabel(obj: Any, old: str, new: str) -> Any:
    """Replace the absolute path the worker saw by the path the user gave."""
    if old == new:
        return obj
    if isinstance(obj, str):
        return obj.replace(old, new)
    if isinstance(obj, dict):
        return {k: _relabel(v, old, new) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_relabel(v, old, new) for v in obj]
    return obj


def _write_log_result(
    task: _Task,
    payload: Payload,
    spec: str,
    request: str | None = None,
    *,
    fit_request: str | None = None,
) -> BatchRow:
    """Turn a worker's payload into a row, and write the log's JSON (with its request key,
    so that ``--resume`` knows what it was computed from)."""
    payload = _relabel(payload, task.path, task.display)
    row = BatchRow(file=task.display, status="failed", model=spec, seconds=payload.get("seconds"))
    if payload.get("status") == "ok":
        data = payload["result"]
        doc: dict[str, Any] = {"file": task.display, "status": "ok", **data}
        row.status = "ok"
        row.model = data.get("model", spec)
        take_fit(row, data)
    else:
        error = str(payload.get("error") or "failed")
        if task.display not in error:
            error = f"{task.display}: {error}"
        row.error = error
        row.exit_code = int(payload.get("exit_code") or INTERNAL_EXIT_CODE)
        doc = {"file": task.display, "status": "failed", "error": error}
        doc["exit_code"] = row.exit_code
        doc["model"] = spec
    doc["seconds"] = row.seconds
    doc["request"] = request
    if fit_request is not None and fit_request != request:
        doc["request_fit"] = fit_request  # the key of the same fit without its diagnosis
    try:
        atomic_write_text(
            task.output, json.dumps(doc, indent=2, allow_nan=False, default=str) + "\n"
        )
        row.json = str(task.output)
    except (OSError, ValueError, BalancerIdError) as exc:
        row.status = "failed"
        row.error = f"{task.display}: cannot write {task.output}: {exc}"
        row.exit_code = INTERNAL_EXIT_CODE
    return row


def take_fit(row: BatchRow, doc: Mapping[str, Any]) -> None:
    """Fill an identified log's row from its fit: the trials, the parameters, the
    metrics, the warnings, then its trust and verdict (:func:`judge_row`).

    A fresh worker's result and a result read back for ``--resume`` fill it alike.

    Parameters
    ----------
    row : BatchRow
        An identified log's row.
    doc : mapping
        The log's result (``fit`` JSON, with ``diagnosis`` under ``--diagnose``).
    """
    row.n_trials = len(doc.get("trials", []))
    row.parameters = {
        name: {"value": p.get("value"), "stderr": p.get("stderr")}
        for name, p in doc.get("parameters", {}).items()
    }
    row.metrics = {k: doc.get("metrics", {}).get(k) for k in METRIC_COLUMNS}
    row.warnings = [str(w) for w in doc.get("warnings", [])]
    judge_row(row, doc)


def judge_row(row: BatchRow, doc: Mapping[str, Any]) -> None:
    """Set a row's ``trusted`` and ``diagnosis_verdict`` from its log's JSON.

    Parameters
    ----------
    row : BatchRow
        An identified log's row.
    doc : dict
        The log's result (``fit`` JSON, with ``diagnosis`` under ``--diagnose``).
    """
    row.trusted = doc.get("trusted") is not False
    if not row.trusted:  # the row leads with why, and carries fit's own exit code
        from balancer_id.errors import UNTRUSTED_EXIT_CODE

        why = [str(w) for w in doc.get("untrusted_because") or []]
        row.error = "not trusted: " + (" | ".join(why) or "see the warnings")
        row.exit_code = UNTRUSTED_EXIT_CODE
    diagnosis = doc.get("diagnosis")
    if isinstance(diagnosis, dict) and diagnosis.get("verdict"):
        row.diagnosis_verdict = str(diagnosis["verdict"])



def _describe(row: BatchRow) -> str:
    if not row.ok:
        return f"failed (exit {row.exit_code}): {row.error}"
    m_a = row.parameters.get("m_a", {}).get("value")
    mass = f", m_a = {m_a:.3g} kg" if isinstance(m_a, float) else ""
    took = f", {row.seconds:.1f} s" if row.seconds is not None else ""
    warn = f"; {len(row.warnings)} warning(s)" if row.warnings else ""
    return f"{row.file}: ok ({row.n_trials} trials{mass}{took}{warn})"


def summary_columns(rows: Sequence[BatchRow]) -> tuple[list[str], list[str]]:
    """The columns of ``summary.csv`` and the parameter names among them.

    Parameters
    ----------
    rows : sequence of BatchRow
        The batch's rows.

    Returns
    -------
    columns : list of str
        ``file, status, error, exit_code, model, n_trials``, then ``NAME, NAME_stderr``
        for ``m_a``, ``T_a`` and every other parameter fitted in any row (in order of
        appearance), then ``rmse, nrmse_fit_percent, aic, bic, seconds, json, verdict,
        warnings``.
    parameters : list of str
        The parameter names, in column order.
    """
    names = list(LEADING_PARAMETERS)
    for row in rows:
        names += [n for n in row.parameters if n not in names]
    columns = ["file", "status", "error", "exit_code", "model", "n_trials"]
    for name in names:
        columns += [name, f"{name}_stderr"]
    columns += [*METRIC_COLUMNS, "seconds", "json", "verdict", "warnings"]
    return columns, names


#: What a spreadsheet reads as the start of a formula (CSV injection, OWASP).
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def spreadsheet_cell(value: object) -> object:
    """``value`` safe in a CSV opened by a spreadsheet or printed on a terminal.

    Text starting like a formula (``=``, ``+``, ``-``, ``@``) gets a leading apostrophe,
    which spreadsheets show as text; control characters (a carriage return that would break
    the row, a terminal escape) are written visibly (``\\r``, ``\\x1b``). Numbers and
    None pass unchanged.

    Parameters
    ----------
    value : object
        A cell.

    Returns
    -------
    object
    """
    if not isinstance(value, str):
        return "" if value is None else value
    text = "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in value)
    return "'" + text if value.startswith(_FORMULA_START) else text


def write_summary(path: str | Path, rows: Sequence[BatchRow]) -> Path:
    """Write ``summary.csv``: one row per log (atomically).

    Parameters
    ----------
    path : path
        The file to write.
    rows : sequence of BatchRow
        The rows, in order.

    Returns
    -------
    Path
        The file written.
    """
    columns, names = summary_columns(rows)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        rec = row.summary_record(names)
        writer.writerow({k: spreadsheet_cell(v) for k, v in rec.items()})
    path = Path(path)
    atomic_write_text(path, buffer.getvalue())
    return path
