"""The work of one log, run in a worker process: read, fit, return a JSON-ready payload."""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from balancer_id.batch.rows import INTERNAL_EXIT_CODE, Payload, _failure
from balancer_id.errors import BalancerIdError, UsageError

if TYPE_CHECKING:
    from balancer_id.model.spec import Model
    from balancer_id.trials import ReadOptions


def _prepare_model(
    model: str | None,
    fixed: Mapping[str, float] | None,
    extra: Sequence[str],
    with_trajectory: bool = False,
    *,
    warm: bool = True,
) -> Model:
    """Resolve the model, check ``fixed`` against it and (with ``warm``) load its kernel.

    Only the model layer is imported: the fitting stack (scipy, pandas, numba) is left to
    whoever fits, so a batch whose fork server preloads it starts without it.
    """
    from balancer_id.model.registry import default_registry
    from balancer_id.model.spec import DEFAULT_SPEC, parse_model

    mdl = parse_model(model or DEFAULT_SPEC, default_registry(extra))
    unknown = sorted(set(fixed or {}) - set(mdl.param_names))
    if unknown:
        raise UsageError(
            f"--fix {', '.join(unknown)}: not a parameter of '{mdl.spec}' "
            f"(its parameters: {', '.join(mdl.param_names)})"
        )
    mdl.require_reference_move(True if with_trajectory else None)
    if warm:
        warm_kernel(mdl)
    return mdl


def warm_kernel(model: Model) -> None:
    """Compile ``model``'s kernels in this process (or load them from numba's disk cache).

    ``get_kernel`` alone only builds the dispatchers; numba compiles (or loads from its
    cache) on the first call, so a tiny simulation is run, with and without the
    sensitivities a fit asks for: after this, no fit in this process (or in a process
    forked from it) loads a kernel of ``model`` again.

    Parameters
    ----------
    model : Model
        The model the workers will fit.
    """
    import numpy as np

    from balancer_id.simulation.engine import PackedTrials, TrialInput
    from balancer_id.simulation.inputs import Thrust
    from balancer_id.simulation.kernel import get_kernel

    get_kernel(model)
    packed = PackedTrials.pack([TrialInput(np.array([0.0, 0.005, 0.01]), Thrust.step(0.0, 1.0))])
    pvec = np.array([p.value for p in model.params], dtype=float)
    packed.run(model, pvec)
    packed.run_sens(model, pvec, list(range(pvec.size)))


def _compile_candidates(model: Model, with_trajectory: bool) -> None:
    """Compile (into numba's disk cache) what ``--diagnose`` refits: ``model``'s candidates.

    Only kernels missing from the cache are compiled (with a note and a count on stderr);
    the workers then load them instead of each compiling them again.
    """
    from balancer_id.diagnostics.candidates import candidates
    from balancer_id.simulation.kernel_compile import compile_models

    compile_models([c.model for c in candidates(model, with_trajectory=with_trajectory)])


_MODELS: dict[tuple[object, ...], Model] = {}


def _model(spec: str, effects_files: Sequence[str]) -> Model:
    """``spec`` resolved once per process (and again when an effects file changes).

    Resolving builds the registry, which scans the installed plug-ins' entry points:
    milliseconds a log, when the model is the same for the whole batch.
    """
    from balancer_id.identify.api import resolve_model

    stamps: list[object] = [spec]
    for f in effects_files:
        try:
            st = os.stat(f)
            stamps.append((f, st.st_mtime_ns, st.st_size))
        except OSError:
            stamps.append((f, None))
    key = tuple(stamps)
    found = _MODELS.get(key)
    if found is None:
        found = _MODELS[key] = resolve_model(spec, effects_files)
    return found


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
    diagnose: bool = False,
) -> Payload:
    """Fit one log; never raises an ``Exception`` (a failure is a payload too).

    Warnings raised by the fit go into the result's ``warnings`` list rather than to
    the worker's stderr (or, under a strict warnings filter, failing the log). The
    result carries when the log was recorded (:func:`recording_time`) and, with
    ``diagnose``, the diagnosis's verdict, summary, first three suggestions and discovered
    force (formula and command, or None).
    """
    start = time.perf_counter()
    try:
        from balancer_id.identify.api import fit  # a worker's first log pays the import

        start = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("default")
            result = fit(
                [path],
                model=_model(model, effects_files),
                fixed=fixed,
                options=options,
                effects_files=effects_files,
                trajectory=trajectory,
            )
            data: dict[str, Any] = dict(result.to_dict())
            if diagnose:
                from balancer_id.diagnostics.diagnosis import diagnose as diagnose_fit
                from balancer_id.identify.result import FitResult

                assert isinstance(result, FitResult), "a fit without per_log is one fit"
                found = diagnose_fit(result, threads=1)  # the workers share the cores
                data["diagnosis"] = {
                    "verdict": found.verdict,
                    "summary": found.summary,
                    "suggestions": [s.to_dict() for s in found.suggestions[:3]],
                    # a force no library effect explains, found in the states: its formula
                    # and the command that writes it as an effect (the fleet view shows it)
                    "discovery": None
                    if found.discovery is None
                    else {"formula": found.discovery.formula, "command": found.discovery.command},
                }
        data["recorded"] = recording_time(result, path)
        notes = [str(w.message) for w in caught if not issubclass(w.category, _QUIET)]
        data["warnings"] = list(dict.fromkeys([*data.get("warnings", []), *notes]))
        return {"status": "ok", "result": data, "seconds": time.perf_counter() - start}
    except BalancerIdError as exc:
        return _failure(str(exc), exc.exit_code, time.perf_counter() - start)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # SystemExit too: user code may exit (issue 13)
        message, code = _unexpected(exc, effects_files)
        return _failure(message, code, time.perf_counter() - start)


def _unexpected(exc: BaseException, effects_files: Sequence[str]) -> tuple[str, int]:
    """The row's error and exit code for an exception that is not one of ours.

    With user effects loaded, the fit runs their code: an exception or exit there is the
    effect's failure on this log (exit 4, identification impossible), said with the file.
    Without them it is an internal error.
    """
    what = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    if isinstance(exc, SystemExit):
        what = f"exit({exc.code!r})"
    if effects_files:
        files = ", ".join(str(f) for f in effects_files)
        return (
            f"the fit stopped with {what} while running the user effects of {files}; "
            "fix the effect (or leave its --effects-file out) and run the batch again with "
            "--resume",
            4,
        )
    return f"internal error: {what}", INTERNAL_EXIT_CODE


def recording_time(result: Any, path: str) -> dict[str, str | None]:
    """When a log was recorded: the reader's clock for it, else the file's time.

    The reader takes a run's start from the export itself (a date-and-time column, an
    epoch clock in the time column) whatever its layout and delimiter
    (:attr:`~balancer_id.read.recording.Recording.started_at`); other logs fall back to
    the file's modification time, which a copy may have changed. ``source`` says which.

    Parameters
    ----------
    result : FitResult
        The log's fit (its trial set holds the log as read).
    path : str
        The log.

    Returns
    -------
    dict
        ``{"time": ISO 8601 or None, "source": "export" | "file time" | None}``.
    """
    from datetime import UTC, datetime

    starts = [
        rec.started_at
        for loaded in getattr(result.trial_set, "logs", [])
        for rec in loaded.log.recordings
        if rec.started_at is not None
    ]
    if starts:
        stamp = datetime.fromtimestamp(min(starts), tz=UTC).isoformat(timespec="seconds")
        return {"time": stamp, "source": "export"}
    try:
        mtime = os.stat(path).st_mtime
    except OSError:
        return {"time": None, "source": None}
    stamp = datetime.fromtimestamp(mtime, tz=UTC).isoformat(timespec="seconds")
    return {"time": stamp, "source": "file time"}
