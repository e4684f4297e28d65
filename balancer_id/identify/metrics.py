"""Error figures shared by fit, compare and diagnose (CONTRACT.md ``metrics``), and the
correlation time of a residual or a noise."""

from __future__ import annotations

from collections.abc import Sequence

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


def correlation_time(segments: Sequence[np.ndarray], removed: int = 1, max_lag: int = 50) -> float:
    """Integrated autocorrelation time ``tau = 1 + 2 sum(rho_k)`` of a noise (samples).

    The long-run variance factor of a coloured noise: a mean of ``L`` samples varies as
    ``tau / L`` times the variance (``(1 + r) / (1 - r)`` for AR(1) noise, 1 for white
    noise). ``rho_k`` is the pooled autocorrelation of the segments, summed while it
    stands above its white-noise band ``2/sqrt(N)`` (Geyer's initial positive sequence),
    and never less than the AR(1) value of the first lag. Segments whose mean (and
    slope) were removed have their autocorrelation pulled down by about
    ``removed * tau / L``; a few fixed-point rounds undo it.

    Parameters
    ----------
    segments : sequence of numpy.ndarray
        Noise segments, each with its mean (``removed=1``) or its line (``2``) removed.
    removed : int
        Terms fitted and removed from each segment.
    max_lag : int
        Most lags summed.

    Returns
    -------
    float
        ``tau`` (1 for white noise or without samples).
    """
    segs = [np.asarray(x, float) for x in segments if np.size(x) >= 2]
    n = int(sum(x.size for x in segs))
    rss = float(sum(float(x @ x) for x in segs))
    if n == 0 or rss <= 0:
        return 1.0
    band = 2.0 / np.sqrt(n)
    acf = []
    for k in range(1, max_lag + 1):
        pairs = [x for x in segs if x.size > k]
        if not pairs:
            break
        rho = float(sum(float(x[:-k] @ x[k:]) for x in pairs)) / rss
        if rho <= band:
            break
        acf.append(rho)
    length = n / len(segs)
    tau = 1.0 + 2.0 * sum(acf)
    for _ in range(5):
        share = min(removed * tau / length, 0.5)
        corrected = [r * (1.0 - share) + share for r in acf]
        # short segments cut the sum early; the AR(1) extrapolation of the first lag
        # (a sensor's low-pass) keeps the tail the band hides
        r1 = min(corrected[0], 0.95) if corrected else 0.0
        tau = max(1.0 + 2.0 * sum(corrected), (1.0 + r1) / (1.0 - r1))
    return float(tau)
