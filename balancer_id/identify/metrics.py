"""Error figures shared by fit, compare and diagnose (CONTRACT.md ``metrics``)."""

from __future__ import annotations

import numpy as np


def error_metrics(y: np.ndarray, y_model: np.ndarray, n_params: int) -> dict[str, float]:
    """RMSE, NRMSE fit percentage, AIC and BIC of a model over all samples.

    Parameters
    ----------
    y, y_model : numpy.ndarray
        Measured and simulated acceleration over every sample of every trial.
    n_params : int
        Number of fitted parameters.

    Returns
    -------
    dict
        ``rmse`` (m/s^2), ``nrmse_fit_percent`` = 100 (1 - ||y - y_model|| / ||y - mean(y)||),
        ``aic`` = n ln(RSS/n) + 2k and ``bic`` = n ln(RSS/n) + k ln n, ``n_samples``.
    """
    y = np.asarray(y, float)
    y_model = np.asarray(y_model, float)
    n = int(y.size)
    rss = _sum_of_squares(y, y_model)
    spread = float(np.sqrt(_sum_of_squares(y, float(np.mean(y)) if n else 0.0)))
    fit = 100.0 * (1.0 - np.sqrt(rss) / spread) if spread > 0 else float("nan")
    log_l = n * np.log(max(rss, 1e-300) / max(n, 1))
    return {
        "rmse": float(np.sqrt(rss / max(n, 1))),
        "nrmse_fit_percent": float(fit),
        "aic": float(log_l + 2 * n_params),
        "bic": float(log_l + n_params * np.log(max(n, 1))),
        "n_samples": n,
    }


#: Samples per block of :func:`_sum_of_squares` (its temporary stays this long).
BLOCK = 1 << 16


def _sum_of_squares(a: np.ndarray, b: np.ndarray | float) -> float:
    """``sum((a - b)**2)`` a block at a time: no temporary the length of a long log, and
    no BLAS (its threads cost more than they give here)."""
    total = 0.0
    for i in range(0, a.size, BLOCK):
        d = a[i : i + BLOCK] - (b if isinstance(b, float) else b[i : i + BLOCK])
        total += float(np.einsum("i,i", d, d))
    return total
