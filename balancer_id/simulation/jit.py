"""The one place that decides how kernels are compiled.

numba compiles the simulator's generated kernels to machine code and caches them on
disk. Setting ``BALANCER_ID_NO_JIT=1`` (or a missing numba) runs the very same code as
plain Python, slowly: useful for debugging a user effect.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

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
            cache=cache,
            error_model="numpy",
            nogil=True,
            fastmath=FASTMATH,
            inline="always" if inline else "never",
        )(f)

    return wrap if func is None else wrap(func)
