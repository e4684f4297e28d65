"""Identify many logs, one fit per log, in parallel: what ``balancer-id batch`` runs.

Each log is fitted on its own, in a pool of worker processes
(:class:`concurrent.futures.ProcessPoolExecutor`) or on a Dask cluster. A log that
cannot be read or identified becomes a failed row; the others go on. Results land in
the output folder as they arrive: one JSON per log and, at the end, ``summary.csv``
with one row per log (CONTRACT.md, ``batch``). Every file is written atomically.

Before the pool starts, the model's kernel is compiled once in this process, so
numba's disk cache is warm and no worker compiles it again; a worker's first log pays
for loading it (about a second), the next ones do not. Where the platform has it,
workers are forked from a ``forkserver`` that imports the fitting code once, while this
process compiles: a new worker costs a fork, not an interpreter start, and forking
stays safe in a process that runs threads. Elsewhere workers are spawned and import
lazily. Each worker runs one BLAS/OpenMP thread. As with any ``spawn`` or
``forkserver`` pool, a script that calls :func:`run_batch` with ``jobs > 1`` needs the
``if __name__ == "__main__":`` guard.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import os
import stat
import sys
import time
import warnings
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

from balancer_id.errors import BalancerIdError, OutputExistsError, UsageError
from balancer_id.files import atomic_write_text

if TYPE_CHECKING:
    from balancer_id.model.spec import Model
    from balancer_id.pipeline import ReadOptions

#: Name of the summary table written into the output folder.
SUMMARY_NAME = "summary.csv"

#: Fit metrics copied into the summary (CONTRACT.md ``fit`` ``metrics``).
METRIC_COLUMNS = ("rmse", "nrmse_fit_percent", "aic", "bic")

#: Parameters that always have their own columns, first (MODEL.md's classic pair).
LEADING_PARAMETERS = ("m_a", "T_a")

#: Modules a forkserver imports once, so forked workers start with them loaded.
_PRELOAD = ("balancer_id.fit.api", "balancer_id.read", "balancer_id.segment", "lmfit")

#: Each worker process runs one BLAS/OpenMP thread: the pool is the parallelism (and
#: the fits' small matrices run faster on one thread anyway). A value the user set wins.
_THREAD_ENV = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

#: Exit code of a failed row that is not a balancer-id error (as the CLI's internal error).
INTERNAL_EXIT_CODE = 1

_DASK_HINT = "pip install 'balancer-id[dask]'"

#: How a batch's own ``summary.csv`` starts; such files in an input folder are skipped.
_SUMMARY_SIGNATURE = "file,status,error,exit_code,"

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
        (3 unreadable log, 4 identification impossible, 1 internal error).
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

    @property
    def ok(self) -> bool:
        """Whether the log was identified."""
        return self.status == "ok"

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
        }

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
    """

    rows: list[BatchRow]
    out_dir: Path
    summary_path: Path
    seconds: float = 0.0

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
        }


@dataclass(frozen=True)
class _Task:
    display: str  # the path as the user gave it
    path: str  # absolute: workers may run elsewhere, or from another folder
    output: Path  # the per-log JSON


def run_batch(
    paths: Sequence[str | Path],
    out_dir: str | Path,
    *,
    model: str | None = None,
    fixed: Mapping[str, float] | None = None,
    options: ReadOptions | None = None,
    effects_files: Sequence[str | Path] = (),
    jobs: int | None = None,
    scheduler: str | None = None,
    progress: Callable[[str], None] | None = None,
    resume: bool = False,
    overwrite: bool = False,
    trajectory: Any = None,
) -> BatchResult:
    """Identify each log on its own, in parallel, and write the results into ``out_dir``.

    Only one batch writes into a folder at a time (a lock file, released by the system
    even when the process is killed). SIGTERM stops the batch like Ctrl-C: the workers
    are stopped, finished results stay and ``summary.csv`` lists every log; no worker
    outlives the batch (on Linux a worker dies with its parent, even after SIGKILL).
    With ``resume`` a log whose result exists for the same input bytes, model and options
    is not fitted again.

    Parameters
    ----------
    paths : sequence of path
        Logs and folders; a folder stands for the CSV files below it (recursively,
        sorted; hidden folders, ``out_dir`` and earlier batches' ``summary.csv``
        skipped). Duplicates are dropped.
    out_dir : path
        Output folder, created if needed: ``<stem>.json`` per log (a numeric suffix
        tells apart logs with the same stem) and ``summary.csv``.
    model : str, optional
        Model spec (default ``variable_viscosity``).
    fixed : mapping, optional
        Parameters held at known values, for every log.
    options : ReadOptions, optional
        Reading and segmentation options, for every log.
    effects_files : sequence of path
        User effect files.
    jobs : int, optional
        Worker processes (default: the CPUs this process may use, see
        :func:`available_cpus`); 1 fits in this process. With ``scheduler="local"``,
        the number of Dask workers; ignored with a scheduler address.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``) to run the fits on, or
        ``"local"`` for a local Dask cluster. Needs ``pip install 'balancer-id[dask]'``
        and balancer-id installed on the workers, which must see the logs at the same
        absolute paths.
    progress : callable, optional
        Called with a one-line message as each log finishes.
    resume : bool
        Keep the results already in ``out_dir`` whose log, model and options are unchanged
        (an interrupted batch continues); fit only the others.
    overwrite : bool
        Allow replacing the results of an earlier batch in ``out_dir`` (without
        ``resume`` or ``overwrite``, a folder holding a ``summary.csv`` is refused).
    trajectory : Trapezoid or TabulatedMove, optional
        A robot's reference move, the same for every log (``servo``); its start is
        found in each log unless given.

    Returns
    -------
    BatchResult
        Rows in input order; ``exit_code`` is 3 when any log failed.

    Raises
    ------
    UsageError
        No log found; ``out_dir`` is a file or holds an input; bad ``jobs``; unknown
        model or parameter; a scheduler without Dask installed, or unreachable; another
        batch writing into ``out_dir``; earlier results without ``resume``/``overwrite``.
    """
    started = time.perf_counter()
    say = progress or (lambda message: None)
    if jobs is not None and jobs < 1:
        raise UsageError(f"--jobs {jobs}: give at least 1 worker process")
    if scheduler is not None:
        if not scheduler.strip():
            raise UsageError("--scheduler: give a Dask scheduler address or 'local'")
        _dask()  # fail fast when Dask is missing
    if isinstance(paths, str | Path):
        paths = [paths]
    out = Path(out_dir)
    logs = collect_logs(paths, out_dir=out)
    _check_out_dir(out, paths, logs)
    n_workers = min(jobs or available_cpus(), len(logs))
    pooled = scheduler is None and n_workers > 1
    context = _mp_context() if pooled else None  # the fork server starts while we compile
    extra = tuple(str(Path(f).resolve()) for f in effects_files)
    mdl = _prepare_model(model, fixed, extra, trajectory is not None)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--out {out}: cannot create the folder ({exc.strerror})") from None
    with _folder_lock(out), _sigterm_as_interrupt():
        if (out / SUMMARY_NAME).exists() and not (resume or overwrite):
            raise OutputExistsError(
                f"--out {out} holds the results of an earlier batch; add --resume to keep "
                "them and fit only what is missing or changed, or --overwrite to replace them"
            )
        tasks = [
            _Task(str(log), str(log.resolve()), out / name)
            for log, name in zip(logs, _output_names(logs), strict=True)
        ]
        worker = partial(
            _identify,
            model=mdl.spec,
            fixed=dict(fixed or {}),
            options=options,
            effects_files=extra,
            trajectory=trajectory,
        )
        rows: list[BatchRow | None] = [None] * len(tasks)
        keys = [
            request_key(task.path, mdl.spec, fixed, options, extra, trajectory) for task in tasks
        ]

        def record(index: int, payload: Payload) -> None:
            row = _write_log_result(tasks[index], payload, mdl.spec, keys[index])
            rows[index] = row
            done = sum(r is not None for r in rows)
            say(f"[{done}/{len(tasks)}] {_describe(row)}")

        items = []
        for k, task in enumerate(tasks):
            kept = _resumed_row(task, keys[k]) if resume else None
            if kept is not None:
                rows[k] = kept
            elif not _is_regular(Path(task.path)):
                record(k, _failure(_irregular(task.display), 3))
            else:
                items.append((k, task.path))
        if resume:
            say(f"resuming: {len(tasks) - len(items)} of {len(tasks)} log(s) already done")
        try:
            if not items:
                pass
            elif scheduler is not None:
                _run_dask(worker, items, record, scheduler, n_workers, say)
            elif pooled and len(items) > 1:
                n = min(n_workers, len(items))
                say(f"identifying {len(items)} logs with {n} worker processes")
                run_in_processes(worker, items, record, n, context=context, notify=say)
            else:
                say(f"identifying {len(items)} log(s) in this process")
                for index, path in items:
                    record(index, worker(path))
        except BaseException:
            # keep what was done: a consistent summary of every log, finished or not
            write_summary(out / SUMMARY_NAME, _fill_missing(rows, tasks, mdl.spec))
            raise
        final = _fill_missing(rows, tasks, mdl.spec)
        summary = write_summary(out / SUMMARY_NAME, final)
    return BatchResult(final, out, summary, seconds=time.perf_counter() - started)


def request_key(
    path: str,
    spec: str,
    fixed: Mapping[str, float] | None,
    options: ReadOptions | None,
    effects_files: Sequence[str],
    trajectory: Any = None,
) -> str | None:
    """What one log's result depends on: its bytes, the model, the options, the effects.

    Parameters
    ----------
    path : str
        The log.
    spec : str
        The model spec.
    fixed : mapping, optional
        Parameters held at known values.
    options : ReadOptions, optional
        Reading and segmentation options.
    effects_files : sequence of str
        User effect files (their bytes count too).
    trajectory : Trapezoid or TabulatedMove, optional
        A robot's reference move (counts when given).

    Returns
    -------
    str or None
        A SHA-256 key (see :func:`balancer_id.cache.result_key`), or None when a file
        cannot be read.
    """
    from balancer_id.cache import result_key

    request = {"model": spec, "fixed": dict(fixed or {}), "options": repr(options)}
    if trajectory is not None:
        request["trajectory"] = repr(trajectory)
    return result_key("batch", [path, *effects_files], request)


def _resumed_row(task: _Task, key: str | None) -> BatchRow | None:
    """The row of a result already written for the same request, or None."""
    if key is None:
        return None
    try:
        doc = json.loads(task.output.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("request") != key:
        return None
    row = BatchRow(
        file=task.display,
        status=str(doc.get("status", "failed")),
        model=str(doc.get("model", "")),
        seconds=doc.get("seconds"),
        json=str(task.output),
    )
    if row.status == "ok":
        row.n_trials = len(doc.get("trials", []))
        row.parameters = {
            name: {"value": p.get("value"), "stderr": p.get("stderr")}
            for name, p in doc.get("parameters", {}).items()
        }
        row.metrics = {k: doc.get("metrics", {}).get(k) for k in METRIC_COLUMNS}
    else:
        row.error = str(doc.get("error", "failed"))
        row.exit_code = int(doc.get("exit_code") or INTERNAL_EXIT_CODE)
    return row


def _is_regular(path: Path) -> bool:
    try:
        return stat.S_ISREG(path.stat().st_mode)
    except OSError:
        return True  # let the reader say why it cannot be read


def _irregular(display: str) -> str:
    """Why a path that is not a regular file is not a log."""
    if Path(display).is_dir():
        return f"{display}: a folder that cannot be listed (permission?); check its access rights"
    return f"{display}: not a regular file (a pipe or a device); give a CSV file"


#: Lock file that keeps two batches from writing into one folder.
LOCK_NAME = ".balancer-id-batch.lock"


@contextmanager
def _folder_lock(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``out`` (refuse at once when another batch holds it)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    path = out / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise UsageError(f"--out {out}: cannot write into the folder ({exc.strerror})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            raise UsageError(
                f"--out {out}: another batch (process {holder}) is writing into this folder; "
                "wait for it to finish, or give another --out"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        try:
            yield
        finally:
            path.unlink(missing_ok=True)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Within, SIGTERM (and SIGHUP) stops the batch as Ctrl-C does (main thread only)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: object) -> None:
        raise KeyboardInterrupt(f"stopped by signal {signum}")

    saved = {}
    for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None:
            saved[sig] = signal.signal(sig, stop)
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def available_cpus() -> int:
    """CPUs this process may run on (``os.cpu_count()`` narrowed by CPU affinity).

    Returns
    -------
    int
        At least 1.
    """
    counter = getattr(os, "process_cpu_count", None)  # Python 3.13
    if counter is not None:
        return counter() or 1
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _fill_missing(rows: list[BatchRow | None], tasks: list[_Task], spec: str) -> list[BatchRow]:
    """Rows in task order; a log without a result (the batch stopped early) is failed."""
    return [
        row
        if row is not None
        else BatchRow(
            file=task.display,
            status="failed",
            error=f"{task.display}: not identified: the batch stopped before this log",
            exit_code=INTERNAL_EXIT_CODE,
            model=spec,
        )
        for row, task in zip(rows, tasks, strict=True)
    ]


def collect_logs(paths: Iterable[str | Path], out_dir: str | Path | None = None) -> list[Path]:
    """The logs that ``paths`` stand for: files as given, folders expanded.

    Parameters
    ----------
    paths : iterable of path
        Files (kept as given, whatever their suffix) and folders (the ``.csv`` files
        below them, recursively and sorted; hidden files and folders, and the
        ``summary.csv`` of earlier batches, skipped).
    out_dir : path, optional
        A folder never to descend into (the batch's output).

    Returns
    -------
    list of Path
        In order, each log once (duplicates by resolved path dropped).

    Raises
    ------
    UsageError
        No log at all.
    """
    skip = Path(out_dir).resolve() if out_dir is not None else None
    found: list[Path] = []
    seen: set[Path] = set()
    given = [Path(p) for p in paths]
    for path in given:
        for log in _expand(path, skip) if path.is_dir() else [path]:
            key = log.resolve()
            if key not in seen:
                seen.add(key)
                found.append(log)
    if not found:
        where = ", ".join(str(p) for p in given) or "(nothing given)"
        raise UsageError(f"no log found in {where}: give CSV files or folders that hold them")
    return found


def _expand(folder: Path, skip: Path | None) -> list[Path]:
    """The CSV files below ``folder``; a subfolder that cannot be listed is returned as an
    entry of its own, so that it becomes a failed row instead of vanishing."""
    logs = []
    unreadable: list[Path] = []

    def onerror(exc: OSError) -> None:
        if exc.filename is not None:
            unreadable.append(Path(exc.filename))

    for root, dirs, names in os.walk(folder, onerror=onerror):
        base = Path(root)
        dirs[:] = [
            d
            for d in dirs
            if not d.startswith(".") and (skip is None or (base / d).resolve() != skip)
        ]
        logs += [
            base / n
            for n in names
            if n.lower().endswith(".csv") and not n.startswith(".") and not _is_summary(base / n)
        ]
    found = sorted(logs, key=lambda p: p.relative_to(folder).parts)
    return found + [p for p in unreadable if p != folder or not found]


def _is_summary(path: Path) -> bool:
    """Whether a CSV is the ``summary.csv`` of an earlier batch (not a log)."""
    if not _is_regular(path):  # never open a pipe or a device: it could block
        return False
    try:
        with path.open(encoding="utf-8", errors="replace") as handle:
            head = handle.readline(200)
    except OSError:
        return False
    return head.startswith(_SUMMARY_SIGNATURE)


def _check_out_dir(out: Path, given: Sequence[str | Path], logs: Sequence[Path]) -> None:
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: is a file; give a folder for the results")
    target = out.resolve()
    for path in [*map(Path, given), *logs]:
        resolved = path.resolve()
        if resolved == target or target in resolved.parents:
            raise UsageError(
                f"--out {out}: holds the input {path}; write the results into another folder"
            )


def _prepare_model(
    model: str | None,
    fixed: Mapping[str, float] | None,
    extra: Sequence[str],
    with_trajectory: bool = False,
) -> Model:
    """Resolve the model, check ``fixed`` against it and warm the kernel's disk cache."""
    from balancer_id.fit.api import resolve_model

    mdl = resolve_model(model, extra)
    unknown = sorted(set(fixed or {}) - set(mdl.param_names))
    if unknown:
        raise UsageError(
            f"--fix {', '.join(unknown)}: not a parameter of '{mdl.spec}' "
            f"(its parameters: {', '.join(mdl.param_names)})"
        )
    if mdl.has("servo") and not with_trajectory:
        raise UsageError(
            "a model with 'servo' needs the robot's reference move: give --trajectory "
            "'trapezoid:distance=...,speed=...,accel=...' or a CSV of time,position"
        )
    warm_kernel(mdl)
    return mdl


def warm_kernel(model: Model) -> None:
    """Compile ``model``'s kernel in this process, so numba's disk cache holds it.

    ``get_kernel`` alone only builds the dispatchers; numba compiles (or loads from its
    cache) on the first call, so a tiny simulation is run.

    Parameters
    ----------
    model : Model
        The model the workers will fit.
    """
    import numpy as np

    from balancer_id.simulate.engine import TrialInput, simulate_many
    from balancer_id.simulate.inputs import Thrust
    from balancer_id.simulate.kernel import get_kernel

    get_kernel(model)
    simulate_many(
        model, model.defaults(), [TrialInput(np.array([0.0, 0.005, 0.01]), Thrust.step(0.0, 1.0))]
    )


def _output_names(logs: Sequence[Path]) -> list[str]:
    """``<stem>.json`` per log; later logs with a taken stem get ``_2``, ``_3``, ..."""
    taken: set[str] = set()
    names = []
    for log in logs:
        stem = log.stem or "log"
        name, k = stem, 2
        while name.lower() in taken:
            name, k = f"{stem}_{k}", k + 1
        taken.add(name.lower())
        names.append(f"{name}.json")
    return names


# Workers ------------------------------------------------------------------------------
_QUIET = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)


def _identify(
    path: str,
    *,
    model: str,
    fixed: Mapping[str, float],
    options: ReadOptions | None,
    effects_files: Sequence[str],
    trajectory: Any = None,
) -> Payload:
    """Fit one log; never raises an ``Exception`` (a failure is a payload too).

    Warnings raised by the fit go into the result's ``warnings`` list rather than to
    the worker's stderr (or, under a strict warnings filter, failing the log).
    """
    start = time.perf_counter()
    try:
        from balancer_id.fit.api import fit  # a worker's first log pays the import

        start = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("default")
            result = fit(
                [path],
                model=model,
                fixed=fixed,
                options=options,
                effects_files=effects_files,
                trajectory=trajectory,
            )
            data: dict[str, Any] = dict(result.to_dict())
        notes = [str(w.message) for w in caught if not issubclass(w.category, _QUIET)]
        data["warnings"] = list(dict.fromkeys([*data.get("warnings", []), *notes]))
        return {"status": "ok", "result": data, "seconds": time.perf_counter() - start}
    except BalancerIdError as exc:
        return _failure(str(exc), exc.exit_code, time.perf_counter() - start)
    except Exception as exc:
        return _failure(
            f"internal error: {type(exc).__name__}: {exc}",
            INTERNAL_EXIT_CODE,
            time.perf_counter() - start,
        )


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


@contextmanager
def _one_thread_env() -> Iterator[None]:
    """Processes started inside inherit one BLAS/OpenMP thread (unless the user chose)."""
    added = [name for name in _THREAD_ENV if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


def _mp_context() -> Any:
    """``forkserver`` with the fitting code preloaded where available, else ``spawn``.

    The fork server is launched now (when not running yet), so it imports the fitting
    code while this process does other work; it then serves every later pool.
    """
    import multiprocessing

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    from multiprocessing import forkserver

    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(_PRELOAD))
    try:
        with _one_thread_env():
            forkserver.ensure_running()
    except OSError:  # the pool will try again, and report
        pass
    return ctx


def run_in_processes(
    func: Callable[[Any], Payload],
    items: Sequence[tuple[int, Any]],
    record: Callable[[int, Payload], None],
    jobs: int,
    *,
    context: Any = None,
    notify: Callable[[str], None] | None = None,
) -> None:
    """Call ``func(arg)`` for each ``(key, arg)`` in a process pool; ``record`` each result.

    A worker that dies (killed, out of memory, a crash in native code) breaks the whole
    pool. Results that arrived are kept; the items that did not finish run again, each
    in a process of its own (``jobs`` at a time), so a crash fails only its own item.

    Parameters
    ----------
    func : callable
        A picklable function returning a payload (``{"status": ...}``).
    items : sequence of (key, argument)
        The work.
    record : callable
        ``record(key, payload)``, called in this process as each result arrives.
    jobs : int
        Worker processes.
    context : multiprocessing context, optional
        How workers start (default: see :func:`_mp_context`).
    notify : callable, optional
        Told, in one line, when a worker died and the rest run one process each.
    """
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    ctx = context or _mp_context()
    retry: list[tuple[int, Any]] = []
    pool = ProcessPoolExecutor(
        max_workers=min(jobs, len(items)),
        mp_context=ctx,
        initializer=_die_with_parent,
        initargs=(os.getpid(),),
    )
    try:
        futures = {}
        with _one_thread_env():  # workers start on submit
            for n, (key, arg) in enumerate(items):
                try:
                    futures[pool.submit(func, arg)] = (key, arg)
                except BrokenProcessPool:
                    retry += items[n:]
                    break
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                key, arg = futures[fut]
                try:
                    payload = fut.result()
                except BrokenProcessPool:
                    retry.append((key, arg))
                    continue
                except Exception as exc:  # e.g. a result that cannot be pickled
                    payload = _internal(exc)
                record(key, payload)
    except BaseException:
        _stop_workers(pool)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    if retry:
        if notify is not None:
            notify(
                f"a worker process died; {len(retry)} unfinished item(s) run again, "
                "one process each"
            )
        _run_isolated(func, sorted(retry, key=lambda item: item[0]), record, jobs, ctx)


def _run_isolated(
    func: Callable[[Any], Payload],
    items: Sequence[tuple[int, Any]],
    record: Callable[[int, Payload], None],
    jobs: int,
    ctx: Any,
) -> None:
    """One single-worker pool per item, ``jobs`` at a time: a crash fails one item."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    queue = deque(items)
    active: dict[Any, tuple[int, ProcessPoolExecutor]] = {}
    try:
        while queue or active:
            while queue and len(active) < jobs:
                key, arg = queue.popleft()
                pool = ProcessPoolExecutor(
                    max_workers=1,
                    mp_context=ctx,
                    initializer=_die_with_parent,
                    initargs=(os.getpid(),),
                )
                with _one_thread_env():
                    active[pool.submit(func, arg)] = (key, pool)
            done, _ = wait(list(active), return_when=FIRST_COMPLETED)
            for fut in done:
                key, pool = active.pop(fut)
                try:
                    payload = fut.result()
                except BrokenProcessPool:
                    payload = _crashed("the worker process died while on this item")
                except Exception as exc:
                    payload = _internal(exc)
                pool.shutdown(wait=True)
                record(key, payload)
    except BaseException:
        for _, pool in active.values():
            _stop_workers(pool)
        raise
    finally:
        for _, pool in active.values():
            pool.shutdown(wait=True, cancel_futures=True)


def _die_with_parent(batch_pid: int) -> None:
    """Worker initializer: the worker ends when the batch process is gone.

    A forkserver's workers are children of the fork server, which itself only exits when
    the workers have, so neither notices a batch killed with SIGKILL. Each worker therefore
    watches the batch's process id from a daemon thread (twice a second) and exits when it
    is gone; on Linux it also asks for SIGKILL when its own parent dies.

    Parameters
    ----------
    batch_pid : int
        Process id of the batch that started the pool.
    """
    import threading

    if sys.platform.startswith("linux"):
        try:
            import ctypes
            import signal

            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # PDEATHSIG
        except (OSError, AttributeError):
            pass

    def watch() -> None:
        while True:
            time.sleep(0.5)
            try:
                os.kill(batch_pid, 0)
            except ProcessLookupError:
                os._exit(1)
            except OSError:
                pass

    threading.Thread(target=watch, name="balancer-id-watch-batch", daemon=True).start()


def _stop_workers(pool: Any) -> None:
    """Terminate a pool's worker processes now (an interrupted batch must not wait)."""
    for proc in list(getattr(pool, "_processes", {}).values()):
        try:
            proc.terminate()
        except (OSError, ValueError):
            pass


def _dask() -> Any:
    try:
        import dask.distributed as distributed
    except ImportError:
        raise UsageError(f"--scheduler needs Dask: {_DASK_HINT}") from None
    return distributed


def _run_dask(
    func: Callable[[Any], Payload],
    items: Sequence[tuple[int, Any]],
    record: Callable[[int, Payload], None],
    scheduler: str,
    n_workers: int,
    say: Callable[[str], None],
) -> None:
    """Run the items on a Dask cluster (``"local"``: a LocalCluster of ``n_workers``)."""
    distributed = _dask()
    cluster = None
    try:
        if scheduler == "local":
            cluster = distributed.LocalCluster(
                n_workers=n_workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
            client = distributed.Client(cluster)
            where = f"a local Dask cluster of {n_workers} workers"
        else:
            client = distributed.Client(scheduler)
            where = f"the Dask cluster at {scheduler}"
    except (OSError, TimeoutError, ValueError) as exc:
        if cluster is not None:
            cluster.close()
        raise UsageError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    try:
        say(f"identifying {len(items)} logs on {where}")
        futures = {client.submit(func, arg, pure=False): key for key, arg in items}
        for fut in distributed.as_completed(futures):
            key = futures[fut]
            try:
                payload = fut.result()
            except Exception as exc:  # KilledWorker, lost scheduler, ...
                payload = _crashed(f"the Dask task failed: {type(exc).__name__}: {exc}")
            record(key, payload)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


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
    task: _Task, payload: Payload, spec: str, request: str | None = None
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
        row.n_trials = len(data.get("trials", []))
        row.parameters = {
            name: {"value": p.get("value"), "stderr": p.get("stderr")}
            for name, p in data.get("parameters", {}).items()
        }
        row.metrics = {k: data.get("metrics", {}).get(k) for k in METRIC_COLUMNS}
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


def _describe(row: BatchRow) -> str:
    if not row.ok:
        return f"failed (exit {row.exit_code}): {row.error}"
    m_a = row.parameters.get("m_a", {}).get("value")
    mass = f", m_a = {m_a:.3g} kg" if isinstance(m_a, float) else ""
    took = f", {row.seconds:.1f} s" if row.seconds is not None else ""
    return f"{row.file}: ok ({row.n_trials} trials{mass}{took})"


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
        appearance), then ``rmse, nrmse_fit_percent, aic, bic, seconds, json``.
    parameters : list of str
        The parameter names, in column order.
    """
    names = list(LEADING_PARAMETERS)
    for row in rows:
        names += [n for n in row.parameters if n not in names]
    columns = ["file", "status", "error", "exit_code", "model", "n_trials"]
    for name in names:
        columns += [name, f"{name}_stderr"]
    columns += [*METRIC_COLUMNS, "seconds", "json"]
    return columns, names


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
        writer.writerow({k: "" if v is None else v for k, v in rec.items()})
    path = Path(path)
    atomic_write_text(path, buffer.getvalue())
    return path
