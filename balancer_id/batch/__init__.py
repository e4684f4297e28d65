"""Identify many logs, one fit per log, in parallel: what ``balancer-id batch`` runs.

One module per job: :mod:`.inputs` (the logs found, the output folder's lock, what a
resumed batch keeps), :mod:`.worker` (one log in a worker process), :mod:`.executors`
(the process pool with crash isolation, Dask), :mod:`.rows` (rows, per-log JSON,
``summary.csv``); :func:`run_batch` here runs them in order.

Each log is fitted on its own, in a pool of worker processes
(:class:`concurrent.futures.ProcessPoolExecutor`) or on a Dask cluster. A log that
cannot be read or identified becomes a failed row; the others go on. Results land in
the output folder as they arrive: one JSON per log and, at the end, ``summary.csv``
with one row per log (CONTRACT.md, ``batch``). Every file is written atomically.

Where the platform has it, workers are forked from a ``forkserver`` that, while this
process goes on, imports the fitting code once and loads the model's kernels (with
``diagnose``, its candidates' too), compiling them first when numba's disk cache lacks
them (:mod:`.preload`): a new worker costs a fork, not an interpreter start nor a second
of kernel loading, and forking stays safe in a process that runs threads. A model with
user effects is compiled in this process before the pool starts (an effect that cannot
be compiled stops the batch at once; with ``diagnose`` its candidates are compiled here
too); its workers load them on first use.
Elsewhere workers are spawned and import lazily. Each worker runs one BLAS/OpenMP
thread. As with any ``spawn`` or ``forkserver`` pool, a script that calls
:func:`run_batch` with ``jobs > 1`` needs the ``if __name__ == "__main__":`` guard.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

from balancer_id.batch.executors import (
    _dask,
    _mp_context,
    _run_dask,
    _sigterm_as_interrupt,
    available_cpus,
    run_in_processes,
)
from balancer_id.batch.inputs import (
    LOCK_NAME,
    _check_out_dir,
    _folder_lock,
    _irregular,
    _is_regular,
    _output_names,
    _resumed_row,
    check_own_outputs,
    collect_logs,
    request_key,
)
from balancer_id.batch.rows import (
    INTERNAL_EXIT_CODE,
    LEADING_PARAMETERS,
    METRIC_COLUMNS,
    SUMMARY_NAME,
    BatchResult,
    BatchRow,
    Payload,
    _describe,
    _failure,
    _fill_missing,
    _Task,
    _write_log_result,
    summary_columns,
    write_summary,
)
from balancer_id.batch.worker import (
    _compile_candidates,
    _identify,
    _prepare_model,
    warm_kernel,
)
from balancer_id.errors import OutputExistsError, UsageError
from balancer_id.model.spec import DEFAULT_SPEC

if TYPE_CHECKING:
    from balancer_id.trials import ReadOptions

__all__ = [
    "INTERNAL_EXIT_CODE",
    "LEADING_PARAMETERS",
    "LOCK_NAME",
    "METRIC_COLUMNS",
    "SUMMARY_NAME",
    "BatchResult",
    "BatchRow",
    "Payload",
    "_folder_lock",
    "available_cpus",
    "collect_logs",
    "request_key",
    "run_batch",
    "run_in_processes",
    "summary_columns",
    "warm_kernel",
    "write_summary",
]


def _tasks(logs: list[Path], out: Path, *, replace: bool) -> list[_Task]:
    """One task per log, its output named in ``out`` (refused when it may not be written)."""
    tasks = [
        _Task(str(log), str(log.resolve()), out / name)
        for log, name in zip(logs, _output_names(logs), strict=True)
    ]
    check_own_outputs([t.output for t in tasks], out, replace=replace)
    return tasks


def _tick(tick: Callable[[int, int], None] | None, rows: Sequence[BatchRow | None]) -> None:
    """Tell the progress bar how many logs are settled."""
    if tick is not None:
        tick(sum(r is not None for r in rows), len(rows))


def _fleet_shared(final: list[BatchRow], out: Path, per_log: Sequence[str],
                  **fit_options: Any) -> dict[str, Any] | None:
    """The counted logs fitted together (``per_log``): ``shared_fit.json``."""
    from balancer_id.batch.shared import fit_fleet_shared

    return fit_fleet_shared(final, out, per_log, **fit_options)


def _start(
    model: str | None,
    fixed: Mapping[str, float] | None,
    extra: tuple[str, ...],
    pooled: bool,
    diagnose: bool,
    with_trajectory: bool,
) -> tuple[Any, Any]:
    """The pool's process context (None without a pool) and the checked model.

    A pool's fork server loads the kernels of a model of built-in effects (and with
    ``diagnose`` its candidates') once, while this process goes on, and every worker is
    forked with them loaded; user effects are compiled here first, so that an effect
    that cannot be compiled stops the batch before any log, and the workers load it.
    The server starts first: its imports are the longest part of a batch's start.
    """
    preloaded = pooled and not extra
    context = (
        _mp_context(
            [model or DEFAULT_SPEC] if preloaded else [],
            diagnose=diagnose,
            trajectory=with_trajectory,
        )
        if pooled
        else None
    )
    mdl = _prepare_model(model, fixed, extra, with_trajectory, warm=not preloaded)
    if pooled and diagnose and not preloaded:  # compiled once here, not in every worker
        _compile_candidates(mdl, with_trajectory)
    return context, mdl


def _refuse_earlier(out: Path, replace: bool) -> None:
    """Refuse a folder holding an earlier batch's results, unless resumed or replaced."""
    if (out / SUMMARY_NAME).exists() and not replace:
        raise OutputExistsError(
            f"--out {out} holds the results of an earlier batch; add --resume to keep "
            "them and fit only what is missing or changed, or --overwrite to replace them"
        )


def _check_workers(jobs: int | None, scheduler: str | None) -> None:
    """Refuse fewer than one worker, an empty scheduler address, Dask missing."""
    if jobs is not None and jobs < 1:
        raise UsageError(f"--jobs {jobs}: give at least 1 worker process")
    if scheduler is not None:
        if not scheduler.strip():
            raise UsageError("--scheduler: give a Dask scheduler address or 'local'")
        _dask()  # fail fast when Dask is missing


def _to_fit(
    tasks: list[_Task],
    rows: list[BatchRow | None],
    record: Callable[[int, Payload], None],
    keys: list[str | None],
    fit_keys: list[str | None] | None,
    *,
    resume: bool,
    say: Callable[[str], None],
) -> list[tuple[int, str]]:
    """The logs to fit: not kept by ``resume`` (kept rows go into ``rows``), regular files
    (others are recorded as failed). ``fit_keys``: the keys of the same fits without a
    diagnosis, when one is asked for (a result without it is fitted again)."""
    items = []
    undiagnosed = 0
    for k, task in enumerate(tasks):
        kept = _resumed_row(task, keys[k]) if resume else None
        if kept is None and fit_keys is not None and _resumed_row(task, fit_keys[k]):
            undiagnosed += 1
        if kept is not None:
            rows[k] = kept
        elif not _is_regular(Path(task.path)):
            record(k, _failure(_irregular(task.display), 3))
        else:
            items.append((k, task.path))
    if resume:
        say(f"resuming: {len(tasks) - len(items)} of {len(tasks)} log(s) already done")
        if undiagnosed:
            say(
                f"{undiagnosed} log(s) were identified without --diagnose: identified "
                "and diagnosed again"
            )
    return items


def _dispatch(
    worker: Callable[[str], Payload],
    items: list[tuple[int, str]],
    record: Callable[[int, Payload], None],
    scheduler: str | None,
    n_workers: int,
    pooled: bool,
    context: Any,
    say: Callable[[str], None],
) -> None:
    """Fit ``items`` on Dask, in a pool of ``n_workers`` processes (``pooled``), or here."""
    if not items:
        return
    if scheduler is not None:
        _run_dask(worker, items, record, scheduler, n_workers, say)
    elif pooled and len(items) > 1:
        n = min(n_workers, len(items))
        say(f"identifying {len(items)} logs with {n} worker processes")
        run_in_processes(worker, items, record, n, context=context, notify=say)
    else:
        say(f"identifying {len(items)} log(s) in this process")
        for index, path in items:
            record(index, worker(path))


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
    diagnose: bool = False,
    tick: Callable[[int, int], None] | None = None,
    per_log: Sequence[str] = (),
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
    diagnose : bool
        Diagnose each fit too (what ``balancer-id diagnose`` does): the per-log JSON then
        holds ``diagnosis`` (verdict, summary, first three suggestions), which the fleet
        report (:mod:`balancer_id.report.fleet`) lists.
    tick : callable, optional
        Called as ``tick(done, total)`` when a log is settled (fitted, failed or kept by
        ``resume``): what a progress bar follows.
    per_log : sequence of str
        Then fit the logs the fleet view counts together, these parameters each log's
        own and the rest shared (a fleet of one type, ``--per-log``): ``shared_fit.json``
        in ``out_dir`` and :attr:`BatchResult.shared_fit`
        (:func:`~balancer_id.batch.shared.fit_fleet_shared`).

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
    _check_workers(jobs, scheduler)
    if isinstance(paths, str | Path):
        paths = [paths]
    out = Path(out_dir)
    logs = collect_logs(paths, out_dir=out)
    _check_out_dir(out, paths, logs)
    n_workers = min(jobs or available_cpus(), len(logs))
    pooled = scheduler is None and n_workers > 1
    extra = tuple(str(Path(f).resolve()) for f in effects_files)
    context, mdl = _start(model, fixed, extra, pooled, diagnose, trajectory is not None)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--out {out}: cannot create the folder ({exc.strerror})") from None
    with _folder_lock(out), _sigterm_as_interrupt():
        _refuse_earlier(out, resume or overwrite)
        tasks = _tasks(logs, out, replace=resume or overwrite)
        worker = partial(_identify, model=mdl.spec, fixed=dict(fixed or {}), options=options,
                         effects_files=extra, trajectory=trajectory, diagnose=diagnose)
        rows: list[BatchRow | None] = [None] * len(tasks)
        request = partial(request_key, spec=mdl.spec, fixed=fixed, options=options,
                          effects_files=extra, trajectory=trajectory)
        keys = [request(task.path, diagnose=diagnose) for task in tasks]
        # the same fit without its diagnosis: a diagnosed result also serves a resume
        # that does not ask for one (never the other way round)
        fit_keys = [request(task.path, diagnose=False) for task in tasks] if diagnose else keys

        def record(index: int, payload: Payload) -> None:
            row = _write_log_result(
                tasks[index], payload, mdl.spec, keys[index], fit_request=fit_keys[index]
            )
            rows[index] = row
            say(f"[{sum(r is not None for r in rows)}/{len(tasks)}] {_describe(row)}")
            _tick(tick, rows)

        items = _to_fit(tasks, rows, record, keys, fit_keys if resume and diagnose else None,
                        resume=resume, say=say)
        _tick(tick, rows)
        try:
            _dispatch(worker, items, record, scheduler, n_workers, pooled, context, say)
        except BaseException:
            # keep what was done: a consistent summary of every log, finished or not
            write_summary(out / SUMMARY_NAME, _fill_missing(rows, tasks, mdl.spec))
            raise
        final = _fill_missing(rows, tasks, mdl.spec)
        summary = write_summary(out / SUMMARY_NAME, final)
        shared = None
        if per_log:
            say(f"fitting the counted logs together ({', '.join(per_log)} per log)")
            shared = _fleet_shared(
                final, out, per_log, model=model, fixed=fixed, options=options,
                effects_files=effects_files, trajectory=trajectory,
            )
    return BatchResult(
        final, out, summary, seconds=time.perf_counter() - started, shared_fit=shared
    )
