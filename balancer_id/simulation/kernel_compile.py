"""Compiling several kernels at once: helper processes, a lock, the numba disk cache.

A first start compiles each missing kernel once per machine; several are compiled in
parallel, each in its own Python process (numba compiles under the GIL), then loaded
here from the cache.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from balancer_id.files import private_folder
from balancer_id.model.registry import USER_MODULE_PREFIX
from balancer_id.model.spec import Model
from balancer_id.simulation import kernel as _kernel
from balancer_id.simulation.jit import HAVE_NUMBA
from balancer_id.simulation.kernel import _import_path, _run_tiny, _run_tiny_sens
from balancer_id.simulation.kernel_cache import (
    _VERBOSE_COMPILE,
    _is_cached,
    _kernel_name,
    _kernel_path,
    cache_dir,
    note,
)

#: Processes compiling kernels at once in :func:`compile_models` (None: one per CPU).
COMPILE_JOBS: int | None = None
#: Longest a compiling process may take (s); past it the kernel is compiled here instead.
COMPILE_TIMEOUT_S = 900.0


def compile_models(models: Sequence[Model], *, sensitivities: bool = True) -> None:
    """Compile (or load from the disk cache) the kernels of several models.

    The first run after an install compiles the built-in models once; each kernel that
    has to be compiled is announced on stderr with a count (``2/5``), so a long first
    start is not mistaken for a hang. Several kernels missing from the disk cache are
    compiled at once, each in its own Python process (numba compiles one function at a
    time under the GIL), and then loaded from the cache here.

    Parameters
    ----------
    models : sequence of Model
        The models whose kernels are needed.
    sensitivities : bool
        Also compile the sensitivity kernel (what a fit uses).

    Notes
    -----
    A model whose kernel cannot be compiled is skipped here; :func:`get_kernel` raises
    its error where the model is used.
    """
    unique = {(m.effects, m.param_names): m for m in models}  # a model named twice: once
    todo = [m for key, m in unique.items() if key not in _kernel._KERNELS]
    need = list(_one_per_file(m for m in todo if not _is_cached(m)).values())
    if not need:
        return
    with _compile_lock():  # one process compiles; the others wait, then load
        need = [m for m in need if not _is_cached(m)]
        if _VERBOSE_COMPILE:
            for k, m in enumerate(need, 1):
                name = _kernel_name(m)
                note(f"compiling the simulation kernel of {name} ({k}/{len(need)}; once)")
        _compile_shared(need, sensitivities)


def _one_per_file(models: Iterable[Model]) -> dict[object, Model]:
    """One model per kernel file (the models of built-in effects share one)."""
    chosen: dict[object, Model] = {}
    for m in models:
        path, _ = _kernel_path(m)
        chosen.setdefault(path or (m.effects, m.param_names), m)
    return chosen


def _compile_here(models: Sequence[Model], sensitivities: bool) -> None:
    for m in models:
        try:
            _kernel._warm(m, _kernel.get_kernel(m, quiet=True), sensitivities)
        except Exception:  # a broken effect is reported where the model is used
            continue


@contextmanager
def _compile_lock() -> Iterator[None]:
    """Hold the kernel cache's lock file: processes started together (test workers, a
    batch's workers, two commands) compile a missing kernel once, not each."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: each process compiles for itself
        yield
        return
    folder = cache_dir()
    if private_folder(folder) is not None:
        yield
        return
    with open(folder / ".compile.lock", "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _compile_shared(models: Sequence[Model], sensitivities: bool) -> None:
    """Compile ``models`` here and in helper processes at once, one share each.

    A helper process imports its kernel files (and the user effects files they need),
    runs each on a tiny input and leaves numba's machine code in the disk cache; this
    process compiles its own share meanwhile, then loads the others' from the cache. A
    kernel whose helper failed is compiled here afterwards, which reports any error.
    """
    import subprocess
    from concurrent.futures import ThreadPoolExecutor

    jobs = min(len(models), COMPILE_JOBS or _cpus())
    if jobs < 2 or not HAVE_NUMBA:
        _compile_here(models, sensitivities)
        return
    shares = [list(models[i::jobs]) for i in range(jobs)]
    commands = [c for c in (_compile_command(s, sensitivities) for s in shares[1:]) if c]
    env = _helper_env()

    def run(command: list[str]) -> None:
        try:
            subprocess.run(
                command,
                env=env,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                timeout=COMPILE_TIMEOUT_S,
                check=False,
            )
        except (OSError, subprocess.SubprocessError):
            pass  # compiled here afterwards

    threads = max(1, len(commands))
    with ThreadPoolExecutor(threads, thread_name_prefix="balancer-id-compile") as pool:
        running = [pool.submit(run, c) for c in commands]
        _compile_here(shares[0], sensitivities)
        for job in running:
            job.result()
    _compile_here([m for share in shares[1:] for m in share], sensitivities)


def _helper_env() -> dict[str, str]:
    """The environment of a compiling helper process: quiet, importing this package."""
    package_root = str(Path(__file__).resolve().parents[2])
    env = dict(os.environ, BALANCER_ID_QUIET="1")
    env["PYTHONPATH"] = os.pathsep.join(
        [package_root, *filter(None, [os.environ.get("PYTHONPATH")])]
    )
    return env


def _compile_command(models: Sequence[Model], sensitivities: bool) -> list[str] | None:
    """The command of a helper process compiling ``models``' kernel files (None: none of
    them has a file, e.g. effects defined inside a function)."""
    import json

    kernels, files = [], []
    for model in models:
        try:
            kernel = _kernel._build(model)
        except Exception:
            continue
        if kernel.path is None:  # compiled in memory: nothing another process can share
            continue
        values = kernel.parameters([q.value for q in model.params])
        kernels.append([str(kernel.path), [float(x) for x in values]])
        files += [
            str(getattr(sys.modules.get(c.__module__), "__file__", ""))
            for c in model.effects
            if c.__module__.startswith(USER_MODULE_PREFIX)
        ]
    if not kernels:
        return None
    job = {"kernels": kernels, "sensitivities": sensitivities, "effects_files": files}
    return helper_command(
        "import json, sys; from balancer_id.simulation.kernel_compile import compile_files; "
        "compile_files(**json.loads(sys.argv[1]))",
        json.dumps(job),
    )


def helper_command(code: str, *args: str) -> list[str]:
    """The command line of a helper Python process running ``code`` with ``args``.

    ``python -c`` puts the working folder first on ``sys.path``: a ``json.py`` lying there
    would run as the user. ``-P`` (Python 3.11) keeps it off.

    Parameters
    ----------
    code : str
        The program.
    *args : str
        Its arguments (``sys.argv[1:]``).

    Returns
    -------
    list of str
    """
    return [sys.executable, "-P", "-c", code, *args]


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def compile_files(
    kernels: Sequence[tuple[str, Sequence[float]]],
    sensitivities: bool,
    effects_files: Sequence[str],
) -> None:
    """Compile kernel files into numba's disk cache (what a helper process runs).

    Parameters
    ----------
    kernels : sequence of (str, sequence of float)
        Each kernel file written by this module and a parameter vector to run it with.
    sensitivities : bool
        Also compile the sensitivity kernels.
    effects_files : sequence of str
        The user effects files the kernels take effects from, loaded first.
    """
    import numpy as np

    from balancer_id.model.registry import import_file_module

    for file in dict.fromkeys(effects_files):
        import_file_module(Path(file))
    for path, values in kernels:
        kernel_path = Path(path)
        try:
            module = _import_path(kernel_path.stem, kernel_path)
            pvec = np.asarray(values, dtype=np.float64)
            _run_tiny(module.simulate_batch, pvec)
            if sensitivities:
                _run_tiny_sens(module.simulate_batch_sens, pvec)
        except Exception:  # the process that asked compiles it again and says why
            continue
