"""Small recursive filters compiled once (scipy.signal would load scipy.stats, ~1 s)."""

from __future__ import annotations

import numpy as np

from balancer_id.simulation.jit import jit

__all__ = ["first_order_lag"]


@jit(cache=True)
def _lag_kernel(x: np.ndarray, alpha: float) -> np.ndarray:  # pragma: no cover - compiled
    out = np.empty_like(x)
    y = 0.0
    for k in range(x.size):
        out[k] = y
        y = alpha * y + (1.0 - alpha) * x[k]
    return out


def first_order_lag(x: np.ndarray, alpha: float) -> np.ndarray:
    """``x`` through the discrete first-order lag ``y[k] = alpha y[k-1] + (1-alpha) x[k-1]``
    from ``y[0] = 0`` (``lfilter([0, 1 - alpha], [1, -alpha], x)``).

    Parameters
    ----------
    x : numpy.ndarray
        The input (1-D).
    alpha : float
        The pole, ``exp(-dt / T)`` for a lag ``T`` sampled every ``dt``.

    Returns
    -------
    numpy.ndarray
    """
    return _lag_kernel(np.ascontiguousarray(x, dtype=np.float64), float(alpha))
