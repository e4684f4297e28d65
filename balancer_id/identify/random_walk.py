"""A random walk seen through noisy local estimates: Kalman filter, RTS smoother, likelihood.

The state-space model of one parameter tracked in time (issue 33)::

    x_k = x_{k-1} + w_k,   w_k ~ N(0, c r (t_k - t_{k-1}))      the parameter walks
    y_k = x_k + v_k,       v_k ~ N(0, c s_k^2)                  a local fit sees it

``y_k`` and ``s_k`` are the local estimates and their standard errors; ``c >= 1`` scales
the standard errors up (the local fits may understate them: a misfit that varies from
block to block) and ``r`` is the walk's variance per second relative to it. ``c`` is
profiled out in closed form; ``r`` is
chosen by likelihood, ``r = 0`` being a constant parameter (the weighted mean). The first
estimate starts the filter (a diffuse start), so the likelihoods of all ``r`` are over
the same innovations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The local standard errors are never scaled down: below 1 the walk can claim that
#: consecutive estimates agree better than their own fits say, and its band collapses.
MIN_SCALE = 1.0
#: Walk-to-noise ratios searched (per second, relative to the scaled local variance).
RATIO_GRID = np.logspace(-7, 1, 41)


@dataclass
class WalkFit:
    """The smoothed walk of one parameter.

    Attributes
    ----------
    time : numpy.ndarray
        Times of the local estimates (s).
    value : numpy.ndarray
        Smoothed value at each time.
    variance : numpy.ndarray
        Its smoothed variance.
    gain : numpy.ndarray
        The smoother's gains ``J_k`` (``Cov(x_k, x_{k+1} | all) = J_k P_{k+1|N}``).
    ratio : float
        The walk variance per second over ``scale`` (0: constant).
    scale : float
        The factor ``c`` on the local variances.
    loglik : float
        Log-likelihood at ``ratio``.
    loglik_constant : float
        Log-likelihood of a constant parameter (``ratio = 0``, ``c`` profiled).
    """

    time: np.ndarray
    value: np.ndarray
    variance: np.ndarray
    gain: np.ndarray
    ratio: float
    scale: float
    loglik: float
    loglik_constant: float

    @property
    def walk_sd_per_sqrt_s(self) -> float:
        """The walk's standard deviation per square-root second (parameter units)."""
        return float(np.sqrt(self.ratio * self.scale))

    @property
    def lr(self) -> float:
        """Likelihood-ratio statistic of the walk against a constant (>= 0)."""
        return max(0.0, 2.0 * (self.loglik - self.loglik_constant))

    @property
    def p_value(self) -> float:
        """P-value of "constant" against "walks": the ratio sits on its bound under the
        null, so the statistic is a 50:50 mixture of 0 and chi-square(1)."""
        from scipy.stats import chi2

        return float(0.5 * chi2.sf(self.lr, 1)) if self.lr > 0 else 1.0

    def covariance(self, i: int, j: int) -> float:
        """Smoothed covariance of the values at two times.

        Parameters
        ----------
        i, j : int
            Positions in :attr:`time`.

        Returns
        -------
        float
        """
        if i > j:
            i, j = j, i
        return float(np.prod(self.gain[i:j]) * self.variance[j])


def _filter(
    y: np.ndarray, s2: np.ndarray, dt: np.ndarray, ratio: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Kalman filter with ``c = 1``: filtered means and variances, predicted variances,
    and the profiled scale ``c`` with the log-likelihood's sum of log innovation variances.

    Returns (m, p, p_pred, e2_over_f, sum_log_f) where the innovations' normalized squares
    give ``c`` and the likelihood.
    """
    n = y.size
    m = np.empty(n)
    p = np.empty(n)
    pp = np.empty(n)
    e2f = np.empty(max(n - 1, 0))
    logf = 0.0
    m[0], p[0], pp[0] = y[0], s2[0], np.inf
    for k in range(1, n):
        pk = p[k - 1] + ratio * dt[k - 1]
        pp[k] = pk
        f = pk + s2[k]
        e = y[k] - m[k - 1]
        g = pk / f
        m[k] = m[k - 1] + g * e
        p[k] = (1.0 - g) * pk
        e2f[k - 1] = e * e / f
        logf += np.log(f)
    return m, p, pp, e2f, logf


def _profiled_loglik(
    y: np.ndarray, s2: np.ndarray, dt: np.ndarray, ratio: float
) -> tuple[float, float]:
    """Log-likelihood with ``c`` profiled out, and that ``c``."""
    _, _, _, e2f, logf = _filter(y, s2, dt, ratio)
    n = e2f.size
    if n == 0:
        return 0.0, 1.0
    c = max(float(np.mean(e2f)), MIN_SCALE)
    return float(-0.5 * (n * np.log(2 * np.pi * c) + logf + float(np.sum(e2f)) / c)), c


def smooth_walk(time: np.ndarray, y: np.ndarray, se: np.ndarray) -> WalkFit:
    """Fit a random walk to local estimates by likelihood and smooth it (RTS).

    Parameters
    ----------
    time : numpy.ndarray
        Increasing times of the estimates (s).
    y : numpy.ndarray
        The local estimates.
    se : numpy.ndarray
        Their standard errors (positive, finite).

    Returns
    -------
    WalkFit
    """
    from scipy.optimize import minimize_scalar

    time = np.asarray(time, dtype=float)
    y = np.asarray(y, dtype=float)
    s2 = np.asarray(se, dtype=float) ** 2
    dt = np.maximum(np.diff(time), 1e-9)
    ll0, c0 = _profiled_loglik(y, s2, dt, 0.0)
    scores = [(_profiled_loglik(y, s2, dt, float(r))[0], float(r)) for r in RATIO_GRID]
    best_ll, best_r = max(scores)
    k = int(np.argmin(np.abs(RATIO_GRID - best_r)))
    lo, hi = np.log(RATIO_GRID[max(k - 1, 0)]), np.log(RATIO_GRID[min(k + 1, RATIO_GRID.size - 1)])
    if hi > lo:
        res = minimize_scalar(
            lambda q: -_profiled_loglik(y, s2, dt, float(np.exp(q)))[0],
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": 1e-3},
        )
        if -res.fun > best_ll:
            best_ll, best_r = float(-res.fun), float(np.exp(res.x))
    ratio, loglik = (best_r, best_ll) if best_ll > ll0 else (0.0, ll0)
    _, c = _profiled_loglik(y, s2, dt, ratio)
    m, p, pp, _, _ = _filter(y, s2, dt, ratio)
    n = y.size
    ms, ps = m.copy(), p.copy()
    gain = np.zeros(max(n - 1, 0))
    for k in range(n - 2, -1, -1):
        g = p[k] / pp[k + 1] if pp[k + 1] > 0 else 1.0
        gain[k] = g
        ms[k] = m[k] + g * (ms[k + 1] - m[k])
        ps[k] = p[k] + g * g * (ps[k + 1] - pp[k + 1])
    return WalkFit(
        time=time,
        value=ms,
        variance=np.maximum(ps, 0.0) * c,
        gain=gain,
        ratio=ratio,
        scale=c,
        loglik=loglik,
        loglik_constant=ll0 if c0 > 0 else loglik,
    )


def window_means(
    time: np.ndarray, y: np.ndarray, se: np.ndarray, width_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Sliding-window estimates: the weighted mean of the local estimates within
    ``width_s / 2`` of each time, and its standard error (the local variances scaled by
    the scatter about the windows' means), the alternative to the walk (bench_tracking).

    Parameters
    ----------
    time, y, se : numpy.ndarray
        The local estimates' times, values and standard errors.
    width_s : float
        The window's width (s).

    Returns
    -------
    (value, stderr) : tuple of numpy.ndarray
    """
    w = 1.0 / np.asarray(se, dtype=float) ** 2
    value = np.empty(y.size)
    var = np.empty(y.size)
    for k, t in enumerate(time):
        inside = np.abs(time - t) <= width_s / 2
        value[k] = np.sum(w[inside] * y[inside]) / np.sum(w[inside])
        var[k] = 1.0 / np.sum(w[inside])
    scale = max(float(np.mean((y - value) ** 2 * w)), 1e-300) if y.size > 1 else 1.0
    return value, np.sqrt(var * scale)
