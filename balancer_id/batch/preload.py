"""What a batch's fork server loads once, so that every worker forked from it starts ready.

The fork server imports this module (see :func:`balancer_id.batch.executors._mp_context`)
when it starts. Importing it imports the fitting stack and, for each model spec listed
in the environment variable :data:`ENV` (set by the batch only while it starts the
server), loads that model's kernels, and with ``diagnose`` those of its candidate
models too, compiling them first when numba's disk cache does not hold them yet (said
on stderr, with a count). A worker is a fork of the
server: it starts with the imports done and the kernels loaded, so its first log costs
what the others do, and a batch's logs no longer each wait for a second of loading.

Nothing here may stop the server: a model that cannot be resolved or compiled is left
to the workers, which report it per log as they would have.
"""

from __future__ import annotations

import json
import os
import sys

#: Environment variable with what to load: JSON ``{"models": [spec, ...], "diagnose":
#: bool, "trajectory": bool}``.
ENV = "BALANCER_ID_BATCH_PRELOAD"


#: What a fit imports, some of it lazily on its first log (pandas for reading tables,
#: the profile intervals, ``_strptime`` for a log's recording time).
_MODULES = (
    "balancer_id.identify.api",
    "balancer_id.identify.intervals",
    "balancer_id.read.table",
    "pandas",
    "_strptime",
)


def preload(specs: list[str], *, diagnose: bool = False, trajectory: bool = False) -> None:
    """Import the fitting stack and load (or compile) the kernels of ``specs``.

    Parameters
    ----------
    specs : list of str
        Model specs of built-in or installed effects (no user effects files).
    diagnose : bool
        Also the diagnosis and the kernels of each model's candidates (what
        ``batch --diagnose`` refits).
    trajectory : bool
        Whether the batch has a robot reference move (which candidates are tried).
    """
    from importlib import import_module

    from balancer_id.batch.worker import _model, warm_kernel
    from balancer_id.simulation.kernel_compile import compile_models

    for name in _MODULES:
        import_module(name)
    models = []
    for spec in specs:
        try:
            models.append(_model(spec, ()))
        except Exception:
            continue
    if diagnose:
        from balancer_id.diagnostics.candidates import candidates

        import_module("balancer_id.diagnostics.diagnosis")

        for mdl in list(models):
            models += [c.model for c in candidates(mdl, with_trajectory=trajectory)]
    compile_models(models)  # compiles only what the disk cache lacks, with a note
    for mdl in models:
        try:
            warm_kernel(mdl)
        except Exception:
            continue


def _worker_start_failed(kind: type[BaseException], exc: BaseException, tb: object) -> None:
    """The fork server's hook for a worker that fails before it runs: one line, no traceback.

    A worker forked while an interrupted batch removes the pool's semaphores finds them gone
    (an ``OSError``): the batch is stopping and says so itself, so nothing is printed. The
    batch reports any other worker that dies as a failed log.
    """
    if not isinstance(exc, OSError):
        sys.stderr.write(f"balancer-id: a worker process could not start: {kind.__name__}: {exc}\n")


def _from_environment() -> None:
    """Preload what :data:`ENV` names; without it (imported elsewhere), do nothing."""
    if ENV not in os.environ:
        return
    import signal

    # Ctrl-C reaches the whole process group. The fork server ignores it once loaded (and
    # its workers inherit that); ignore it from now, so that a Ctrl-C while loading does
    # not print a traceback from here. The batch itself stops the workers.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    sys.excepthook = _worker_start_failed
    try:
        asked = json.loads(os.environ[ENV] or "{}")
    except ValueError:
        asked = {}
    if not isinstance(asked, dict):
        asked = {}
    specs = asked.get("models")
    import gc

    gc.disable()  # imports make only long-lived objects: collecting them is wasted (~10 %)
    try:
        preload(
            [s for s in specs if isinstance(s, str)] if isinstance(specs, list) else [],
            diagnose=asked.get("diagnose") is True,
            trajectory=asked.get("trajectory") is True,
        )
    except Exception:  # the workers import and load what is missing themselves
        pass
    finally:
        gc.enable()  # the workers inherit it on
        gc.freeze()  # what is loaded stays shared with the forked workers (copy-on-write)


_from_environment()
