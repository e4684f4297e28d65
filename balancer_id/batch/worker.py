"""The work of one log, run in a worker process: read, fit, return a JSON-ready payload.
"""

from __future__ import annotations

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
) -> Model:
    """Resolve the model, check ``fixed`` against it and warm the kernel's disk cache."""
    from balancer_id.identify.api import resolve_model

    mdl = resolve_model(model, extra)
    unknown = sorted(set(fixed or {}) - set(mdl.param_names))
    if unknown:
        raise UsageError(
            f"--fix {', '.join(unknown)}: not a parameter of '{mdl.spec}' "
            f"(its parameters: {', '.join(mdl.param_names)})"
        )
    if mdl.needs_reference_move and not with_trajectory:
        names = "+".join(e.name for e in mdl.effects if e.needs_reference_move())
        raise UsageError(
            f"a model with '{names}' needs the robot's reference move: give --trajectory "
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

    from balancer_id.simulation.engine import TrialInput, simulate_many
    from balancer_id.simulation.inputs import Thrust
    from balancer_id.simulation.kernel import get_kernel

    get_kernel(model)
    simulate_many(
        model, model.defaults(), [TrialInput(np.array([0.0, 0.005, 0.01]), Thrust.step(0.0, 1.0))]
    )


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
        from balancer_id.identify.api import fit  # a worker's first log pays the import

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
