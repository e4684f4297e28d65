"""The separate valleys of a short log's posterior, and their weights (issue 34.2).

A short log's cost has valleys that fit about alike: the drive lag and the viscous time
swapped (the mirror, ``T_a' = m_a / D``, ``m_a' = D T_a``), the ridge where no viscosity
is reached (``D0`` and ``A`` both large). The fit's starts end in them
(``match.optima``). An ensemble started in one valley stays there, and one spread over
several keeps the share of walkers each started with (its local moves do not cross), so
the credible intervals held the truth only when the fit's own valley was the truth's.

Each valley is sampled on its own (the posterior restricted to the points nearest its
optimum, :func:`region_of`), and the valleys' weights are found from the samples by
bridge sampling: an affine map ``T`` carries valley 0's samples onto valley ``k``'s
(centre to centre, shape to shape), and by detailed balance of the move ``x -> T x``
(accepted with ``min(1, p(T x) |J| / p(x))``)::

    W_k / W_0 = E_0[ min(1, p(T x) |J| / p(x)) ] / E_k[ min(1, p(T^-1 y) / (|J| p(y))) ]

(Meng and Wong's bridge with the Metropolis function; warped, as in Meng and Schilling
2002). Where no sample crosses either way the weights fall back to Laplace's
approximation from each valley's samples.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from balancer_id.identify.matching import MatchResult

__all__ = ["MODE_DELTA", "bridge_weights", "posterior_modes", "region_of", "valleys"]

#: The fit's other optima whose cost is within this many noise variances (widened by the
#: residual's correlation time, as the likelihood is) of the best, as good at 95 %, are
#: the posterior's other valleys (25, a likelihood 4e-6 of the best's, reached too far
#: for a prior that grows as a power of 1 / m_a). On six steps of 1.5 s the mirror is
#: within 4 (the data leave it open): T_a's credible interval then spans it.
MODE_DELTA = 4.0
#: Samples of each valley the bridge evaluates (each one posterior evaluation).
BRIDGE_SAMPLES = 150


def posterior_modes(match: MatchResult, names: Sequence[str]) -> list[np.ndarray]:
    """The fit's other optima the posterior may hold (beside the fit's own).

    Parameters
    ----------
    match : MatchResult
        The fit.
    names : sequence of str
        Its free parameters.

    Returns
    -------
    list of numpy.ndarray
        Each other optimum's values of ``names`` within :data:`MODE_DELTA` noise
        variances of the best, told apart from the fit's and each other as the fit tells
        its optima apart (3 standard errors and 1 %); empty when the fit found one.
    """
    tau = max(float(match.metrics.get("residual_tau", 1.0)), 1.0)
    kept = [np.array([match.parameters[n].value for n in names], float)]
    se = np.array(
        [
            s if (s := match.parameters[n].stderr) is not None and math.isfinite(s) else 0.0
            for n in names
        ]
    )
    out = []
    for o in getattr(match, "optima", None) or []:
        if o.delta_sigma2 / tau > MODE_DELTA or not all(n in o.values for n in names):
            continue
        x = np.array([o.values[n] for n in names], float)
        if not np.all(np.isfinite(x)):
            continue
        if any(
            np.all(np.abs(x - y) <= np.maximum(3 * se, 0.01 * np.maximum(np.abs(x), np.abs(y))))
            for y in kept
        ):
            continue  # the fit's own (or one already kept)
        kept.append(x)
        out.append(x)
    return out


#: Two optima lie in one valley when the log posterior on the straight path between them
#: (the sampler's coordinates) never falls more than this below the lower of the two.
#: Two optima of a short log's D0-A ridge (D0 266 and 51,700) fell steadily from one to
#: the other (no barrier), and sampled as two valleys, split by the nearest optimum, the
#: ridge was cut in the middle and each half paid a chain; the mirror (lag and viscous
#: time swapped) lies behind a barrier of thousands.
BARRIER = 2.0
#: Points on the path between two optima at which the barrier is looked for.
PATH_POINTS = 9


def valleys(u_centres: np.ndarray, log_p: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Which optima share a valley (no barrier of :data:`BARRIER` between them).

    Parameters
    ----------
    u_centres : numpy.ndarray
        ``K x k``: the optima in the sampler's coordinates, the fit's own first.
    log_p : callable
        The log posterior of each row of an ``m x k`` array.

    Returns
    -------
    numpy.ndarray
        ``K`` valley labels, ``0, 1, ...`` in order of each valley's first optimum (the
        fit's optimum's valley is 0).
    """
    k_opt = len(u_centres)
    parent = list(range(k_opt))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    ends = np.asarray(log_p(u_centres), float)
    ts = np.linspace(0.0, 1.0, PATH_POINTS + 2)[1:-1, None]
    for a in range(k_opt):
        for b in range(a + 1, k_opt):
            if root(a) == root(b):
                continue
            path = u_centres[a] + ts * (u_centres[b] - u_centres[a])
            with np.errstate(all="ignore"):
                lp = np.asarray(log_p(path), float)
            floor = min(ends[a], ends[b]) - BARRIER
            if np.all(np.isfinite(lp)) and np.isfinite(floor) and lp.min() >= floor:
                parent[max(root(a), root(b))] = min(root(a), root(b))
    roots = [root(i) for i in range(k_opt)]
    order = {r: v for v, r in enumerate(dict.fromkeys(roots))}
    return np.array([order[r] for r in roots], int)


def region_of(centres: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """The valley a point belongs to: the nearest centre, each coordinate scaled by the
    centres' spread in it.

    Parameters
    ----------
    centres : numpy.ndarray
        ``K x k``: the valleys' optima in the sampler's coordinates.

    Returns
    -------
    callable
        ``x`` (``m x k`` or ``k``) to the index of its valley (``m`` or a scalar array).
    """
    spread = np.ptp(centres, axis=0)
    scale = np.where(spread > 0, spread, 1.0)

    def nearest(x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(x)
        d = (((x[:, None, :] - centres[None, :, :]) / scale) ** 2).sum(axis=2)
        return np.argmin(d, axis=1)

    return nearest


def _shape(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A valley's samples' mean and a square root of their covariance (regularised)."""
    mean = samples.mean(axis=0)
    cov = np.atleast_2d(np.cov(samples, rowvar=False))
    d = np.sqrt(np.maximum(np.diag(cov), 0.0))
    cov = cov + np.diag(1e-9 * np.maximum(d, 1e-12) ** 2 + 1e-300)
    try:
        return mean, np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        return mean, np.diag(np.maximum(d, 1e-12))


def bridge_weights(
    chains: Sequence[np.ndarray],
    log_p: Callable[[np.ndarray], float],
    nearest: Callable[[np.ndarray], np.ndarray],
    rng: np.random.Generator,
) -> np.ndarray:
    """Each valley's share of the posterior, from its own samples (module docstring).

    Parameters
    ----------
    chains : sequence of numpy.ndarray
        Each valley's samples (``m_k x k``, the sampler's coordinates), valley 0 first.
    log_p : callable
        The unrestricted log posterior in the sampler's coordinates.
    nearest : callable
        The valley of a point (:func:`region_of`).
    rng : numpy.random.Generator
        Picks the samples the bridge evaluates.

    Returns
    -------
    numpy.ndarray
        The weights, summing to 1.
    """
    if len(chains) == 1:
        return np.ones(1)
    shapes = [_shape(c) for c in chains]
    log_w = np.zeros(len(chains))

    def picked(c: np.ndarray) -> np.ndarray:
        idx = rng.choice(len(c), size=min(BRIDGE_SAMPLES, len(c)), replace=False)
        return c[idx]

    def crossing(xs: np.ndarray, src: int, dst: int) -> float:
        """Mean Metropolis acceptance of the map from valley ``src`` to ``dst``."""
        (m_s, l_s), (m_d, l_d) = shapes[src], shapes[dst]
        warp = l_d @ np.linalg.inv(l_s)
        log_jac = float(np.sum(np.log(np.abs(np.diag(l_d))) - np.log(np.abs(np.diag(l_s)))))
        ys = m_d + (xs - m_s) @ warp.T
        lands = nearest(ys) == dst
        acc = []
        for x, y, ok in zip(xs, ys, lands, strict=True):
            if not ok:
                acc.append(0.0)
                continue
            with np.errstate(all="ignore"):
                diff = log_p(y) + log_jac - log_p(x)
            acc.append(float(np.exp(min(diff, 0.0))) if math.isfinite(diff) else 0.0)
        return float(np.mean(acc))

    base = picked(chains[0])
    for k in range(1, len(chains)):
        out = crossing(base, 0, k)
        back = crossing(picked(chains[k]), k, 0)
        if out > 0 and back > 0:
            log_w[k] = math.log(out) - math.log(back)
        else:  # no sample crosses: Laplace's approximation from each valley's samples
            log_w[k] = _laplace(chains[k], shapes[k], log_p) - _laplace(
                chains[0], shapes[0], log_p
            )
    w = np.exp(log_w - np.max(log_w))
    return w / w.sum()


def _laplace(samples: np.ndarray, shape: tuple[np.ndarray, np.ndarray], log_p) -> float:
    """Log of a valley's mass by Laplace: the density at its samples' mean times the
    volume of their covariance."""
    mean, chol = shape
    with np.errstate(all="ignore"):
        peak = log_p(mean)
    if not math.isfinite(peak):
        peak = max((log_p(x) for x in samples[:: max(1, len(samples) // 50)]), default=-math.inf)
    return float(peak + np.sum(np.log(np.abs(np.diag(chol)))))
