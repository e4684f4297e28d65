"""The simulation kernel of a model: built, loaded, warmed up, memoized per process.

One module per job: :mod:`.kernel_templates` (the source templates),
:mod:`.kernel_source` (a model's source from its effects' hooks, the shared layouts),
:mod:`.kernel_cache` (the disk cache: names, writing, purging), :mod:`.kernel_compile`
(several kernels compiled at once in helper processes, under a lock); this module builds
a :class:`Kernel` and runs it once so that a compile error names the model's effects.

The hooks of a model's effects (see :mod:`balancer_id.model.effect`) are stitched into
one right-hand side and one fixed-step RK4 integrator, written out as Python source,
and compiled by numba. The source goes to a cache directory named after its hash, so
numba's on-disk cache makes the next command start quickly. Effects that cannot be
imported by name (a class defined inside a function) are compiled in memory instead.

Integration: classical RK4 with at most ``dt / n_sub`` per step. Thrust breakpoints
(shifted by the dead time) split the steps, so a step input is exact to the sample and
the response is smooth in ``tau_d``. Where the velocity changes sign under friction, the step is
split at the (linearly located) event and the velocity snapped, so sticking holds
without chattering. The speed limit is approached with a short time constant
(:data:`SPEED_LIMIT_TAU`), which keeps the cost of a fit smooth in every parameter.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from balancer_id.errors import EffectError
from balancer_id.files import private_folder
from balancer_id.model.effect import Effect
from balancer_id.model.spec import Model
from balancer_id.simulation.jit import HAVE_NUMBA
from balancer_id.simulation.kernel_cache import (  # noqa: F401  (the cache's names, here too)
    _CHOSEN,
    _VERBOSE_COMPILE,
    _effect_fingerprint,
    _is_cached_path,
    _kernel_name,
    _kernel_path,
    _purge,
    _shared_choice,
    _write_kernel_file,
    _write_private,
    cache_dir,
    compile_lock,
    note,
)
from balancer_id.simulation.kernel_source import (  # noqa: F401
    SharedPlaces,
    generate_source,
    shared_places,
)
from balancer_id.simulation.kernel_templates import (  # noqa: F401
    KERNEL_VERSION,
    OUT_COLUMNS,
    REL_STEP,
    SPEED_LIMIT_TAU,
)


@dataclass(frozen=True)
class Kernel:
    """The compiled functions of one model.

    Attributes
    ----------
    simulate_trial, simulate_batch, rhs : callables
        The generated functions (numba dispatchers, or plain Python).
    simulate_batch_sens : callable
        :func:`simulate_batch` that also integrates the forward sensitivities of the
        output with respect to chosen parameters and initial states (see
        :meth:`balancer_id.simulation.engine.PackedTrials.run_sens`).
    source : str
        The generated source.
    path : Path or None
        Where the source was written (None when compiled in memory).
    shared : SharedPlaces or None
        Where the model's parameters sit when the kernel is one the built-in effects
        share (None: the model's own kernel). Call the functions with
        :meth:`parameters` and :meth:`columns`.
    """

    simulate_trial: Any
    simulate_batch: Any
    rhs: Any
    source: str
    path: Path | None
    simulate_batch_sens: Any = None
    shared: SharedPlaces | None = None

    def parameters(self, values: Any) -> Any:
        """The kernel's parameter vector for a model's parameters.

        Parameters
        ----------
        values : array_like
            The model's parameters, in ``model.param_names`` order.

        Returns
        -------
        numpy.ndarray
            ``values`` for a model's own kernel; the shared vector for a shared kernel.
        """
        import numpy as np

        values = np.ascontiguousarray(values, dtype=np.float64)
        return values if self.shared is None else self.shared.parameters(values)

    def columns(self, cols: Any) -> Any:
        """The kernel's sensitivity columns for the model's.

        Parameters
        ----------
        cols : numpy.ndarray
            Columns of the model (see :meth:`SharedPlaces.columns`).

        Returns
        -------
        numpy.ndarray
        """
        return cols if self.shared is None else self.shared.columns(cols)


_KERNELS: dict[tuple[object, ...], Kernel] = {}


def get_kernel(model: Model, *, quiet: bool = False) -> Kernel:
    """Return the compiled kernel of ``model`` (memoized per process, cached on disk).

    A kernel whose cached files fail to load (a corrupted source, a stale or damaged
    numba cache) is regenerated and compiled again, with a note on stderr; only when the
    fresh kernel fails too are the model's effects blamed.

    Parameters
    ----------
    model : Model
        The model to simulate.
    quiet : bool
        Do not announce a compilation on stderr (the caller already did).

    Returns
    -------
    Kernel

    Raises
    ------
    EffectError
        When the model's hooks cannot be compiled or run.
    """
    key = (model.effects, model.param_names)
    failed = _FAILED.get(key)
    if failed is not None:  # a model whose hooks fail is not compiled again and again
        raise failed
    kernel = _KERNELS.get(key)
    if kernel is None:
        try:
            kernel = _load_or_compile(model, quiet)
        except EffectError as exc:
            _FAILED[key] = exc
            raise
        _KERNELS[key] = kernel
    return kernel


#: The models whose kernel failed in this process, with the error (raised again at once).
_FAILED: dict[tuple[object, ...], EffectError] = {}


def _load_or_compile(model: Model, quiet: bool) -> Kernel:
    """The kernel of ``model``, from the disk cache or compiled; a cached kernel that fails
    is regenerated once before the model's effects are blamed."""
    with compile_lock(model):
        kernel = _build(model)
        try:
            _compile_now(model, kernel, quiet)
        except EffectError:
            if kernel.path is None:
                raise
            note(
                f"the cached kernel of model '{model.spec}' in {kernel.path.parent} failed "
                "to load; regenerating and compiling it again"
            )
            _purge(kernel.path)
            kernel = _build(model)
            _compile_now(model, kernel, quiet=True)
    return kernel


def _tiny_trial() -> tuple[Any, ...]:
    """The arguments before the parameters of a two-sample trial at rest (one segment)."""
    import numpy as np

    t = np.array([0.0, 0.005])
    z = np.zeros(2)
    return (
        t,
        np.array([0, 2]),
        np.array([0.0]),
        np.array([0.0]),
        np.array([0, 1]),
        z,
        z,
        np.zeros((1, 3)),
    )


def _run_tiny(simulate_batch: Any, pvec: Any) -> None:
    """Run a state kernel once on a two-sample trial (compiles it, or loads it)."""
    import numpy as np

    simulate_batch(*_tiny_trial(), pvec, 1, np.empty((2, len(OUT_COLUMNS))))


def _run_tiny_sens(simulate_batch_sens: Any, pvec: Any) -> None:
    """Run a sensitivity kernel once on a two-sample trial (compiles it, or loads it)."""
    import numpy as np

    cols = np.arange(pvec.size, dtype=np.int64)
    simulate_batch_sens(
        *_tiny_trial(),
        pvec,
        1,
        cols,
        np.empty((2, len(OUT_COLUMNS))),
        np.empty((2, cols.size)),
        np.zeros((1, 3, cols.size)),
        np.empty((1, 3, cols.size)),
    )


def _warm(model: Model, kernel: Kernel, sensitivities: bool) -> None:
    """Run the sensitivity kernel once on a tiny input (compiles or loads it)."""

    if not sensitivities:
        return
    _run_tiny_sens(kernel.simulate_batch_sens, kernel.parameters([p.value for p in model.params]))


def _compile_now(model: Model, kernel: Kernel, quiet: bool = False) -> None:
    """Run the kernel once on a tiny input, so compile errors name the model's effects."""

    fresh = kernel.path is not None and not _is_cached_path(kernel.path)
    if fresh and not quiet and _VERBOSE_COMPILE and kernel.path is not None:
        note(
            f"compiling the simulation kernel of {_kernel_name(model)} (once; cached in "
            f"{kernel.path.parent})"
        )
    try:
        _run_tiny(kernel.simulate_batch, kernel.parameters([p.value for p in model.params]))
        if fresh:  # the fit's kernel too, under the same note, into the same cache
            _warm(model, kernel, True)
    except Exception as exc:
        names = ", ".join(e.name for e in model.effects) or "base"
        first = re.sub(r"\x1b\[[0-9;]*m", "", str(exc)).strip().splitlines()
        detail = next((line for line in first if line.strip()), type(exc).__name__)
        raise EffectError(
            f"model '{model.spec}' (effects {names}) cannot be simulated: "
            f"{type(exc).__name__}: {detail.strip()}; hooks must be plain scalar Python "
            "(arithmetic, math, if) returning a float"
        ) from None


_REFUSED: set[str] = set()


def _build(model: Model) -> Kernel:
    if not HAVE_NUMBA:
        return _exec_in_memory(*generate_source(model, cache=False))
    path, source = _kernel_path(model)
    if path is None:
        return _exec_in_memory(*generate_source(model, cache=False))
    problem = private_folder(path.parent)
    if problem is not None:
        if str(path.parent) not in _REFUSED:
            _REFUSED.add(str(path.parent))
            note(f"kernel cache not used: {problem}; compiling in memory (slower start)")
        return _exec_in_memory(*generate_source(model, cache=False))
    try:
        _write_kernel_file(path, source)
    except OSError as exc:
        note(f"kernel cache not used ({exc.strerror or exc}); compiling in memory")
        return _exec_in_memory(*generate_source(model, cache=False))
    try:
        module = _import_path(path.stem, path)
    except Exception as exc:  # a damaged bytecode or numba cache: start over once
        note(f"cached kernel {path.name} failed to load ({type(exc).__name__}); recompiling")
        _purge(path)
        try:
            _write_private(path, source)
            module = _import_path(path.stem, path)
        except Exception:
            sys.modules.pop(path.stem, None)
            return _exec_in_memory(*generate_source(model, cache=False))
    return Kernel(
        module.simulate_trial,
        module.simulate_batch,
        module.rhs,
        source,
        path,
        module.simulate_batch_sens,
        _shared_choice(model),
    )


def _import_path(name: str, path: Path) -> Any:
    loaded = sys.modules.get(name)
    if loaded is not None and getattr(loaded, "__file__", None) == str(path):
        return loaded
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def _exec_in_memory(source: str, aliases: dict[str, type[Effect]]) -> Kernel:
    namespace: dict[str, Any] = dict(aliases)
    exec(compile(source, f"<balancer_id kernel {id(source)}>", "exec"), namespace)
    return Kernel(
        namespace["simulate_trial"],
        namespace["simulate_batch"],
        namespace["rhs"],
        source,
        None,
        namespace["simulate_batch_sens"],
    )
