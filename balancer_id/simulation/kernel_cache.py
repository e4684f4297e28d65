"""The disk cache of generated kernels: where each lives, its name, writing, purging.

A kernel file is named by a SHA-256 of its source, its effects' code and numba's version;
it is imported only when its content equals the source generated now. Numba keeps the
machine code beside it (:func:`_is_cached_path`).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import inspect
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

from balancer_id.files import cache_root, private_folder
from balancer_id.model.effect import Effect
from balancer_id.model.spec import Model
from balancer_id.simulation.jit import HAVE_NUMBA, private_cache_path
from balancer_id.simulation.kernel_source import (
    SharedPlaces,
    _assemble,
    _shared_layout,
    generate_source,
    shared_places,
)
from balancer_id.simulation.kernel_templates import KERNEL_VERSION


def cache_dir() -> Path:
    """Folder of generated kernels: ``$BALANCER_ID_CACHE`` or ``~/.cache/balancer-id``."""
    return cache_root() / "kernels"


def _effect_fingerprint(cls: type[Effect]) -> str:
    """What a kernel compiled from ``cls`` depends on: its module's whole source (a
    module-level constant a hook reads is compiled into the machine code), else the
    class's, else its hooks' byte code."""
    try:
        module = sys.modules.get(cls.__module__)
        return inspect.getsource(module) if module is not None else inspect.getsource(cls)
    except (OSError, TypeError):
        return repr([(h, getattr(cls, h).__code__.co_code) for h in cls.hooks()])


def note(message: str) -> None:
    """Tell the user something on stderr (one line, never on stdout).

    Parameters
    ----------
    message : str
        The note, without the ``balancer-id:`` prefix.
    """
    sys.stderr.write(f"balancer-id: {message}\n")
    sys.stderr.flush()


#: Say on stderr when a kernel is compiled rather than loaded (off: ``BALANCER_ID_QUIET=1``).
_VERBOSE_COMPILE = os.environ.get("BALANCER_ID_QUIET", "") in ("", "0")


def _kernel_name(model: Model) -> str:
    places = _shared_choice(model)
    if places is None:
        return f"'{model.spec}'"
    with_ = " with " + "+".join(c.name for c in places.fixed) if places.fixed else ""
    return f"the built-in effects{with_} (shared by their models)"


def _numba_cache_of(path: Path) -> Path:
    """The folder where numba caches the machine code of the kernel file ``path``."""
    return Path(private_cache_path(str(path)) or path.parent / "__pycache__")


def _is_cached_path(path: Path) -> bool:
    """Whether numba's cache already holds machine code for the kernel at ``path``."""
    cached = _numba_cache_of(path)
    return path.exists() and all(
        any(cached.glob(f"{path.stem}.{func}-*.nbi"))
        for func in ("simulate_batch", "simulate_batch_sens")
    )


def _is_cached(model: Model) -> bool:
    if not HAVE_NUMBA:
        return True
    path, _ = _kernel_path(model)
    return path is None or _is_cached_path(path)


def _purge(path: Path) -> None:
    """Remove a kernel's source and every cached artefact of it (numba's and Python's)."""
    sys.modules.pop(path.stem, None)
    artefacts = [*(path.parent / "__pycache__").glob(f"{path.stem}.*")]
    artefacts += _numba_cache_of(path).glob(f"{path.stem}.*")
    for f in [path, *artefacts]:
        try:
            f.unlink()
        except OSError:
            pass


@contextlib.contextmanager
def compile_lock(model: Model) -> Iterator[None]:
    """Hold, across processes, the lock of ``model``'s kernel while it is built and compiled.

    Processes started together on a fresh machine (a batch's workers, a test run's
    workers) that need the same kernel would each compile it, seconds of work apiece;
    with the lock the first compiles and the others wait for it, then load its cached
    machine code. A kernel already cached, compiled in memory, or a system without
    ``fcntl`` (Windows) takes no lock. The lock is released when its holder exits, even
    by a crash.

    Parameters
    ----------
    model : Model
        The model whose kernel is about to be built.

    Yields
    ------
    None
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    path = _kernel_path(model)[0] if HAVE_NUMBA else None
    if path is None or _is_cached_path(path) or private_folder(path.parent) is not None:
        yield
        return
    try:
        fd = os.open(path.with_suffix(".lock"), os.O_RDWR | os.O_CREAT, 0o600)
    except OSError:
        yield
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _kernel_path(model: Model) -> tuple[Path | None, str]:
    """Where the kernel this process uses for ``model`` is cached (None: compiled in
    memory) and its source: see :func:`_shared_choice`."""
    places = _shared_choice(model)
    if places is not None:
        name, source = _shared_source(places.fixed)
        return cache_dir() / name, source
    return _own_kernel_path(model)


#: The kernel chosen for each model in this process: where its parameters sit in its
#: shared kernel, or None for a kernel of its own.
_CHOSEN: dict[tuple[object, ...], SharedPlaces | None] = {}


def _shared_choice(model: Model) -> SharedPlaces | None:
    """Where ``model``'s parameters sit in the shared kernel it runs on in this process,
    or None when it runs on a kernel of its own.

    A model runs as fast on the kernel it shares with the models of the same fixed
    effects (:func:`_shared_layout`) as on its own (within 10 %), and a handful of shared
    kernels, compiled once per machine, serve every combination of the built-in effects
    that can be switched, where each model's own kernel costs 2-6 s to compile.
    ``BALANCER_ID_KERNELS=own`` (the other value being ``shared``, the default) gives each
    its own kernel. The choice is made once per process and model.
    """
    key = (model.effects, model.param_names)
    if key not in _CHOSEN:
        policy = os.environ.get("BALANCER_ID_KERNELS", "shared").strip().lower()
        own = not HAVE_NUMBA or policy == "own"
        _CHOSEN[key] = None if own else shared_places(model)
    return _CHOSEN[key]


def _own_kernel_path(model: Model) -> tuple[Path | None, str]:
    """Where ``model``'s own kernel is cached (None: compiled in memory) and its source.

    The name carries a SHA-256 of the source, the effects' code and the numba version;
    the file is only imported when its content equals the source generated now.
    """
    source, _ = generate_source(model, cache=True)
    if any("(in memory)" in line for line in source.splitlines()[:40]):
        return None, source
    return cache_dir() / f"bid_kernel_{_digest(source, model.effects)}.py", source


def _digest(source: str, effects: Sequence[type[Effect]]) -> str:
    fingerprint = "\n".join(_effect_fingerprint(c) for c in effects)
    return hashlib.sha256(
        (KERNEL_VERSION + source + fingerprint + _numba_version()).encode()
    ).hexdigest()[:24]


@functools.cache
def _shared_source(fixed: tuple[type[Effect], ...]) -> tuple[str, str]:
    """The file name and source of the shared kernel with the effects ``fixed``."""
    layout = _shared_layout(fixed)
    source, _ = _assemble(layout, cache=True)
    return f"bid_kernel_builtin_{_digest(source, layout.effects)}.py", source


def _write_private(path: Path, text: str) -> None:
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
    os.replace(tmp, path)


def _write_kernel_file(path: Path, source: str) -> None:
    """Write ``source`` to ``path`` unless it is there already (a stale file is purged)."""
    try:
        current = path.read_text(encoding="utf-8")
    except (FileNotFoundError, UnicodeDecodeError):
        current = None
    if current != source:
        if path.exists():
            note(f"cached kernel {path.name} did not match its model; rewriting it")
            _purge(path)
        _write_private(path, source)


def _numba_version() -> str:
    if not HAVE_NUMBA:
        return "python"
    import numba

    return numba.__version__
