"""A parameter that wanders, seen through noisy local estimates: Kalman filter, RTS
smoother, the walk's variance by likelihood.

Two state-space models of one parameter in time (issue 33), both observed as::

    y_k = x_k + v_k,       v_k ~ N(0, c s_k^2)                  a block's own fit sees it

* ``walk``: a random walk, ``x_k = x_{k-1} + w_k`` with ``w_k ~ N(0, c r dt)``: the
  parameter is locally constant and moves at any time (steps, oscillations);
* ``trend``: an integrated random walk (local linear trend), level and slope with the
  slope walking (``Q = c r [[dt^3/3, dt^2/2], [dt^2/2, dt]]``): the parameter drifts
  smoothly (warming, wear), and at ``r = 0`` is a straight line.

``y_k`` and ``s_k`` are the local estimates and their standard errors; ``c >= 1`` scales
the standard errors up (the local fits may understate them: a misfit that varies from
block to block) and ``r`` is the walk's variance relative to it. ``c`` is profiled out in
closed form; ``r`` is chosen by likelihood, and so is the model (the same two
hyperparameters each, the likelihoods over the same innovations: the first two
estimates start the filter, a diffuse start). Whether the parameter moves at all is the
likelihood ratio of the walk against a constant (``r = 0``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The local standard errors are never scaled down: below 1 a walk can claim that
#: consecutive estimates agree better than their own fits say, and its band collapses.
MIN_SCALE = 1.0
#: Walk variances searched, over the session, in units of the local estimates' median
#: variance: from a walk far below one estimate's noise to one that follows every block.
RATIO_GRID = np.logspace(-3, 5, 33)
#: Innovations that start the filter (left out of every likelihood).
DIFFUSE = 2
#: The diffuse start's variance, in units of the estimates' spread.
DIFFUSE_SCALE = 1e6
KINDS = ("walk", "trend")


@dataclass
class WalkFit:
    """The smoothed path of one parameter.

    Attributes
    ----------
    time : numpy.ndarray
        Times of the local estimates (s).
    value : numpy.ndarray
        Smoothed value at each time.
    variance : numpy.ndarray
        Its smoothed variance.
    gain : list of numpy.ndarray
        The smoother's gains ``J_k`` (``Cov(x_k, x_{k+1} | all) = J_k P_{k+1|N}``).
    smoothed_cov : list of numpy.ndarray
        The smoothed state covariances ``P_{k|N}`` (scaled by ``scale``).
    kind : str
        ``"walk"`` or ``"trend"`` (the model the likelihood chose).
    ratio : float
        The walk variance over ``scale`` (per second, or per second cubed for a trend).
    scale : float
        The factor ``c`` on the local variances.
    loglik : float
        Log-likelihood of the chosen model.
    loglik_walk : float
        Log-likelihood of the best random walk.
    loglik_constant : float
        Log-likelihood of a constant parameter (a walk of variance 0).
    """

    time: np.ndarray
    value: np.ndarray
    variance: np.ndarray
    gain: list[np.ndarray]
    smoothed_cov: list[np.ndarray]
    kind: str
    ratio: float
    scale: float
    loglik: float
    loglik_walk: float
    loglik_constant: float

    @property
    def lr(self) -> float:
        """Likelihood-ratio statistic of the random walk against a constant (>= 0)."""
        return max(0.0, 2.0 * (self.loglik_walk - self.loglik_constant))

    @property
    def p_value(self) -> float:
        """P-value of "constant" against "walks": the walk's variance sits on its bound
        under the null, so the statistic is a 50:50 mixture of 0 and chi-square(1)."""
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
        m = np.eye(self.smoothed_cov[j].shape[0])
        for k in range(i, j):
            m = m @ self.gain[k]
        return float((m @ self.smoothed_cov[j])[0, 0])


def _system(kind: str, dt: float, ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition matrix and process noise (for ``c = 1``) over ``dt``."""
    if kind == "walk":
        return np.eye(1), np.array([[ratio * dt]])
    f = np.array([[1.0, dt], [0.0, 1.0]])
    q = ratio * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    return f, q


def _filter(kind: str, y: np.ndarray, s2: np.ndarray, dt: np.ndarray, ratio: float):
    """Kalman filter with ``c = 1``: filtered and predicted means and covariances, and the
    innovations' normalized squares and log variances (after the diffuse start)."""
    n = y.size
    d = 1 if kind == "walk" else 2
    big = DIFFUSE_SCALE * (float(np.var(y)) + float(np.max(s2)))
    x = np.zeros(d)
    x[0] = y[0]
    p = np.eye(d) * big
    xs, ps, xp, pp = [], [], [], []
    e2f, logf = [], []
    for k in range(n):
        if k > 0:
            f, q = _system(kind, float(dt[k - 1]), ratio)
            x = f @ x
            p = f @ p @ f.T + q
        xp.append(x.copy())
        pp.append(p.copy())
        fk = p[0, 0] + s2[k]
        e = y[k] - x[0]
        g = p[:, 0] / fk
        x = x + g * e
        p = p - np.outer(g, p[0, :])
        p = 0.5 * (p + p.T)
        xs.append(x.copy())
        ps.append(p.copy())
        if k >= DIFFUSE:
            e2f.append(e * e / fk)
            logf.append(np.log(fk))
    return xs, ps, xp, pp, np.asarray(e2f), float(np.sum(logf))


def _profiled_loglik(
    kind: str, y: np.ndarray, s2: np.ndarray, dt: np.ndarray, ratio: float
) -> tuple[float, float]:
    """Log-likelihood with ``c >= 1`` profiled out, and that ``c``."""
    *_, e2f, logf = _filter(kind, y, s2, dt, ratio)
    n = e2f.size
    if n == 0:
        return 0.0, 1.0
    c = max(float(np.mean(e2f)), MIN_SCALE)
    return float(-0.5 * (n * np.log(2 * np.pi * c) + logf + float(np.sum(e2f)) / c)), c


def _best_ratio(kind: str, y: np.ndarray, s2: np.ndarray, dt: np.ndarray, span: float):
    """The walk variance of highest likelihood (grid, then refined): (loglik, ratio)."""
    from scipy.optimize import minimize_scalar

    unit = float(np.median(s2)) / (span if kind == "walk" else span**3)
    grid = RATIO_GRID * unit
    scores = [(_profiled_loglik(kind, y, s2, dt, float(r))[0], float(r)) for r in grid]
    best_ll, best_r = max(scores)
    k = int(np.argmin(np.abs(grid - best_r)))
    lo, hi = np.log(grid[max(k - 1, 0)]), np.log(grid[min(k + 1, grid.size - 1)])
    res = minimize_scalar(
        lambda q: -_profiled_loglik(kind, y, s2, dt, float(np.exp(q)))[0],
        bounds=(lo, hi),
        method="bounded",
        options={"xatol": 1e-2},
    )
    if -res.fun > best_ll:
        best_ll, best_r = float(-res.fun), float(np.exp(res.x))
    return best_ll, best_r


def smooth_walk(
    time: np.ndarray, y: np.ndarray, se: np.ndarray, kinds: tuple[str, ...] = KINDS
) -> WalkFit:
    """Fit a walk (or a trend) to local estimates by likelihood and smooth it (RTS).

    Parameters
    ----------
    time : numpy.ndarray
        Increasing times of the estimates (s).
    y : numpy.ndarray
        The local estimates.
    se : numpy.ndarray
        Their standard errors (positive, finite).
    kinds : tuple of str
        The models to choose from (``"walk"``, ``"trend"``).

    Returns
    -------
    WalkFit
    """
    time = np.asarray(time, dtype=float)
    y = np.asarray(y, dtype=float)
    s2 = np.asarray(se, dtype=float) ** 2
    dt = np.maximum(np.diff(time), 1e-9)
    span = max(float(time[-1] - time[0]), 1e-9)
    ll0, _ = _profiled_loglik("walk", y, s2, dt, 0.0)
    ll_walk, r_walk = _best_ratio("walk", y, s2, dt, span)
    if ll_walk <= ll0:
        ll_walk, r_walk = ll0, 0.0
    choices = {"walk": (ll_walk, r_walk)}
    if "trend" in kinds and y.size > DIFFUSE + 2:
        choices["trend"] = _best_ratio("trend", y, s2, dt, span)
    if "walk" not in kinds:
        choices.pop("walk")
    kind = max(choices, key=lambda k: choices[k][0])
    loglik, ratio = choices[kind]
    _, c = _profiled_loglik(kind, y, s2, dt, ratio)
    xs, ps, xp, pp, _, _ = _filter(kind, y, s2, dt, ratio)
    n = y.size
    ms = [x.copy() for x in xs]
    pss = [p.copy() for p in ps]
    gains: list[np.ndarray] = []
    for k in range(n - 2, -1, -1):
        f, _ = _system(kind, float(dt[k]), ratio)
        g = ps[k] @ f.T @ np.linalg.pinv(pp[k + 1])
        ms[k] = xs[k] + g @ (ms[k + 1] - xp[k + 1])
        pss[k] = ps[k] + g @ (pss[k + 1] - pp[k + 1]) @ g.T
        gains.append(g)
    gains.reverse()
    cov = [p * c for p in pss]
    return WalkFit(
        time=time,
        value=np.array([m[0] for m in ms]),
        variance=np.maximum(np.array([p[0, 0] for p in cov]), 0.0),
        gain=gains,
        smoothed_cov=cov,
        kind=kind,
        ratio=ratio,
        scale=c,
        loglik=loglik,
        loglik_walk=ll_walk,
        loglik_constant=ll0,
    )


def window_means(
    time: np.ndarray, y: np.ndarray, se: np.ndarray, width_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Sliding-window estimates: the weighted mean of the local estimates within
    ``width_s / 2`` of each time, and its standard error (the local variances scaled by
    the scatter about the windows' means): the alternative to the walk (bench_tracking).

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
    scale = max(float(np.mean((y - value) ** 2 * w)), 1.0) if y.size > 1 else 1.0
    return value, np.sqrt(var * scale)
