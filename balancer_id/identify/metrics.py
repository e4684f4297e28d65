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
    r = np.asarray(y, float) - np.asarray(y_model, float)
    n = int(r.size)
    dev = np.asarray(y, float) - np.mean(y)
    rss = float(np.einsum("i,i", r, r))  # not BLAS: its threads cost more than they give
    spread = float(np.sqrt(np.einsum("i,i", dev, dev)))
    fit = 100.0 * (1.0 - np.sqrt(rss) / spread) if spread > 0 else float("nan")
    log_l = n * np.log(max(rss, 1e-300) / max(n, 1))
    return {
        "rmse": float(np.sqrt(rss / max(n, 1))),
        "nrmse_fit_percent": float(fit),
        "aic": float(log_l + 2 * n_params),
        "bic": float(log_l + n_params * np.log(max(n, 1))),
        "n_samples": n,
    }
