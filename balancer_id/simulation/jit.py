"""The one place that decides how kernels are compiled.

numba compiles the simulator's generated kernels to machine code and caches them on
disk. Setting ``BALANCER_ID_NO_JIT=1`` (or a missing numba) runs the very same code as
plain Python, slowly: useful for debugging a user effect.

Where numba caches machine code on disk is decided here, for this package's functions
only (a locator put first in numba's list): the package's own compiled functions cache in
the user's private cache folder (``$BALANCER_ID_CACHE/numba``, see
:func:`balancer_id.files.cache_root`), never beside the package's files, where they would
outlive a reinstall and turn the package folder into a namespace package; the generated
kernels (private files below the cache folder) cache beside themselves. Neither follows
``NUMBA_CACHE_DIR``: numba's cache holds pickles, and a folder that another user can write
would let them run code as this one. When no private folder can be had, nothing is cached.
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from balancer_id.files import cache_root, private_folder

#: This package's folder: its compiled functions cache in the private cache folder.
_PACKAGE = Path(__file__).resolve().parents[1]

FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}
_DISABLED = os.environ.get("BALANCER_ID_NO_JIT", "") not in ("", "0")



try:  # pragma: no cover - exercised through both branches by environment
    if _DISABLED:
        raise ImportError
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover
    numba = None  # type: ignore[assignment]
    HAVE_NUMBA = False


def private_cache_path(py_file: str) -> str | None:
    """Where numba caches the machine code of a function defined in ``py_file``, when that
    is this package's business (None: another file, numba's own rules apply).

    Parameters
    ----------
    py_file : str
        The source file of the function being compiled.

    Returns
    -------
    str or None
        ``$BALANCER_ID_CACHE/numba/<folder>`` for a file of this package, the file's own
        ``__pycache__`` for a generated kernel below ``$BALANCER_ID_CACHE``, else None.
    """
    path = Path(os.path.abspath(py_file))
    root = Path(os.path.abspath(cache_root()))
    if _PACKAGE in path.parents:
        relative = path.parent.relative_to(_PACKAGE)
        return str(root / "numba" / "_".join(("balancer_id", *relative.parts)))
    if root in path.parents:
        return str(path.parent / "__pycache__")
    return None


def _may_cache(func: Callable[..., Any]) -> bool:
    """Whether ``func``'s machine code may be cached on disk: outside this package numba
    decides; this package's functions and kernels only in a private folder, and only when
    its locator is in place (else numba would pick the package folder or a
    ``NUMBA_CACHE_DIR`` anyone may write)."""
    try:
        source = inspect.getfile(func)
    except TypeError:
        return False
    path = private_cache_path(source)
    if path is None:
        return True
    return _LOCATOR and private_folder(Path(path)) is None


def _install_locator() -> bool:
    """Put this package's cache locator first in numba's list; False when numba's
    internals have moved (then the package's functions are not cached on disk)."""
    try:
        from numba.core import caching

        impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # type: ignore[attr-defined]
        base = caching._CacheLocator
        mixin = caching._SourceFileBackedLocatorMixin
    except (ImportError, AttributeError):
        return False

    class PrivateLocator(mixin, base):  # type: ignore[misc, valid-type]
        """numba's cache for this package's functions and kernels: see the module."""

        def __init__(self, py_func: Any, py_file: str, cache_path: str) -> None:
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = cache_path

        def get_cache_path(self) -> str:
            return self._cache_path

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> PrivateLocator | None:
            path = private_cache_path(py_file)
            if path is None or not os.path.exists(py_file):
                return None
            return cls(py_func, py_file, path)

    if not any(c.__name__ == "PrivateLocator" for c in impl._locator_classes):
        impl._locator_classes.insert(0, PrivateLocator)
    return True


_LOCATOR = HAVE_NUMBA and _install_locator()


def jit(
    func: Callable[..., Any] | None = None, *, cache: bool = False, inline: bool = False
) -> Any:
    """Compile ``func`` in numba's nopython mode, or return it unchanged without numba.

    Usable bare (``@jit``), with options (``@jit(cache=True)``) or as a call
    (``jit(f)``). Compilation uses numpy's error model and fast-math flags
    :data:`FASTMATH`, and releases the GIL (candidate refits run in threads).

    Parameters
    ----------
    func : callable, optional
        The scalar function to compile; None returns a decorator.
    cache : bool
        Let numba cache the machine code on disk (the function must live in an
        importable file).
    inline : bool
        Inline the function into its callers at numba's IR level (``inline="always"``):
        no call, no reference counting of array arguments, at some compile time.

    Returns
    -------
    callable
        The compiled dispatcher (or ``func`` itself without numba), or a decorator
        producing it when ``func`` is None.
    """

    def wrap(f: Callable[..., Any]) -> Any:
        if not HAVE_NUMBA:
            return f
        return numba.njit(
            cache=cache and _may_cache(f),
            error_model="numpy",
            nogil=True,
            fastmath=FASTMATH,
            inline="always" if inline else "never",
        )(f)

    return wrap if func is None else wrap(func)
