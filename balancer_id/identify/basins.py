"""Basins searched, not hoped for: spread starts, and the distinct optima they end at.

A least-squares cost with limits, friction or lags has more than one minimum: a speed
limit that clips a trial trades with the mass and the lag, a friction can hide a
viscosity, a lag can trade with the mass. One start from the data finds the basin it
starts in. Here:

* :func:`scaled_starts`: start values of the parameters the response start does not
  give, at the data's own scale (a friction from the thrust, a speed limit from the
  measured speed), instead of a default made for the paper's balancer;
* :func:`spread_starts`: a few more starts spread around the data's start (mass and
  lags up and down together and against each other, each limit, friction and delay
  across its plausible range), deterministic so a fit is reproducible;
* :func:`wants_spread`: whether a model has such parameters (the default fit then tries
  the spread starts too), or the first start ended where a basin is suspect (a parameter
  on a bound it did not choose, one the data cannot determine);
* :func:`distinct_optima`: the ends told apart, each with its cost.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from balancer_id.identify.data import TrialData
from balancer_id.model.spec import Model

#: The parameters of the viscous base laws; any other parameter is a limit, a friction,
#: a lag or a delay whose cost has basins (the default fit then spreads its starts).
SMOOTH_PARAMETERS = frozenset({"m_a", "T_a", "D0", "A", "b"})

#: Spread starts of the default fit for a model with such parameters (or a first start
#: that ended where a basin is suspect): measured to find the basins of
#: ``benchmarks/bench_universe.py``'s worlds at about 3x the time of one start.
DEFAULT_SPREAD = 3

#: Model evaluations a default search's other starts may take each (the first start has
#: the whole budget): enough to settle in a basin, not to crawl along a flat direction.
SPREAD_NFEV = 150

#: Rounds of :data:`MORE_STARTS` random starts a default fit adds while its best end is
#: still suspect after the designed starts, where the cost has basins (a speed limit
#: fitted to six steps ended at 7 distinct optima from 8 starts; the lowest, the truth,
#: came from the seventh).
MORE_ROUNDS = 3
MORE_STARTS = 4

#: The drive lags of the designed starts (s): the first two against the mass's factor
#: (heavy and quick, light and slow), the third in between.
LAG_GRID_S = (0.03, 1.5, 0.3)

#: The viscous times m_a / D0 (s) of the designed starts where the data's start has no
#: viscosity.
VISCOUS_TIMES_S = (1.0, 0.3, 3.0)

#: A |u| at the median thrust of the designed starts.
THRUST_FALLS = (0.1, 1.0, 0.3)

#: Log-factor by which mass and lags are spread (x3 up and down).
SPREAD_LOG = float(np.log(3.0))


def data_scales(trials: Sequence[TrialData]) -> tuple[float, float]:
    """The median absolute thrust (N) and the peak measured speed (m/s) of the trials.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials as fitted.

    Returns
    -------
    (float, float)
        NaN where no trial gives it.
    """
    thrusts = [abs(td.thrust_N) for td in trials if td.thrust_N != 0]
    peak = 0.0
    for td in trials[:60]:
        t = np.asarray(td.time, dtype=float)
        a = np.asarray(td.accel, dtype=float)
        if t.size < 3:
            continue
        v = np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))])
        v = v[np.isfinite(v)]
        if v.size:
            peak = max(peak, float(np.max(np.abs(v))))
    u = float(np.median(thrusts)) if thrusts else float("nan")
    return u, (peak if peak > 0 else float("nan"))


def scaled_starts(model: Model, trials: Sequence[TrialData]) -> dict[str, float]:
    """Start values, at the data's scale, of parameters whose default is the paper's.

    A force (unit ``N``: a friction) starts at a tenth of the median thrust; a speed
    (``m/s``: a speed limit) at 1.2 times the peak measured speed, where it does not clip.

    Parameters
    ----------
    model : Model
        The model to fit.
    trials : sequence of TrialData
        The trials.

    Returns
    -------
    dict of str to float
        Only for the model's parameters of those units (inside their bounds).
    """
    u, v_peak = data_scales(trials)
    out: dict[str, float] = {}
    for p in model.params:
        if p.name in SMOOTH_PARAMETERS:
            continue
        value = None
        if p.unit == "N" and np.isfinite(u):
            value = 0.1 * u
        elif p.unit == "m/s" and np.isfinite(v_peak):
            value = 1.2 * v_peak
        if value is not None:
            out[p.name] = float(np.clip(value, p.min, p.max))
    return out


def wants_spread(model: Model, free: Sequence[str]) -> bool:
    """Whether a fit of ``model`` varying ``free`` has parameters whose cost has basins.

    Parameters
    ----------
    model : Model
        The model fitted.
    free : sequence of str
        The parameters varied.

    Returns
    -------
    bool
        True when a varied parameter is a limit, a friction, a delay or a second lag.
    """
    return any(name not in SMOOTH_PARAMETERS for name in free)


def spread_starts(
    model: Model,
    free: Sequence[str],
    x0: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    count: int,
    trials: Sequence[TrialData],
    seed: int = 0,
) -> list[np.ndarray]:
    """``count`` starts spread around ``x0`` (deterministic for a seed).

    The first two move mass and lags against each other (heavy and quick, light and
    slow: the trade a lag makes with a mass), the third together; a viscosity that
    starts at 0 gets a viscous time ``m_a / D0`` of 0.3-10 s and ``A`` an ``A |u|`` of
    0.1-2 at the median thrust; every other parameter
    is spread across its plausible range (a force between 2 % and 60 % of the median
    thrust, a speed between 0.6 and 3 times the peak measured speed, a delay between
    0 and 3 times the drive lag), further starts drawn at random around ``x0``.

    Parameters
    ----------
    model : Model
        The model fitted.
    free : sequence of str
        The parameters varied, in the order of ``x0``.
    x0 : numpy.ndarray
        The data's start.
    lo, hi : numpy.ndarray
        The fit's bounds of the free parameters.
    count : int
        Starts to return.
    trials : sequence of TrialData
        The trials (their thrust and speed scale the spread).
    seed : int
        Seed of the random starts beyond the designed ones.

    Returns
    -------
    list of numpy.ndarray
        Each strictly inside the bounds.
    """
    u, v_peak = data_scales(trials)
    lag = model.drive_lag(dict(zip(free, x0, strict=True)), default=0.3)
    rng = np.random.default_rng(seed)
    # (mass, lag) log-factors: heavy-quick, light-slow, both up, then random
    design = [(1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
    fractions = [0.6, 0.02, 0.25]  # of the thrust (friction), of the range elsewhere
    speeds = [0.6, 3.0, 1.0]
    out = []
    for k in range(count):
        x = np.asarray(x0, dtype=float).copy()
        if k < len(design):
            sm, sl = design[k]
        else:
            sm, sl = rng.normal(0.0, 1.0, 2)
        mass_factor = float(np.exp(sm * SPREAD_LOG))
        mass = mass_factor * (float(x[list(free).index("m_a")]) if "m_a" in free else 1.0)
        for j, name in enumerate(free):
            p = model.param(name)
            if name == "m_a":
                x[j] *= mass_factor
            elif name in model.drive_lag_names:
                # a lag spread over what the samples resolve up to 2 s, whatever the start
                x[j] = max(x[j], 1e-3) * float(np.exp(sl * SPREAD_LOG))
                if k < len(LAG_GRID_S):
                    x[j] = max(LAG_GRID_S[k], lo[j] * 4)
            elif name == "D0" and x[j] * VISCOUS_TIMES_S[-1] < 1e-3 * mass:
                # a start with no viscosity stays without one under a factor: a viscous
                # time m_a / D0 of 0.3-10 s instead (a push-and-let-go log's data start
                # can say 0, and from 0 the fit slid into a viscosity that vanishes
                # whenever anyone pushes)
                tau = VISCOUS_TIMES_S[k] if k < 3 else float(np.exp(rng.uniform(-1.2, 2.3)))
                x[j] = mass / tau
            elif name == "A" and np.isfinite(u) and u > 0:
                # the viscosity's fall with the thrust, A |u| at the median thrust of
                # 0.1-2 (a start of A |u| near 1 can slide to a viscosity that vanishes
                # whenever anyone pushes, A |u| of 100)
                x[j] = (THRUST_FALLS[k] if k < 3 else float(np.exp(rng.uniform(-2.3, 0.7)))) / u
            elif name in SMOOTH_PARAMETERS:
                x[j] = x[j] * float(np.exp(rng.normal(0.0, 0.5))) if x[j] != 0 else x[j]
            elif p.unit == "N" and np.isfinite(u):
                x[j] = (fractions[k] if k < 3 else float(rng.uniform(0.01, 0.6))) * u
            elif p.unit == "m/s" and np.isfinite(v_peak):
                x[j] = (speeds[k] if k < 3 else float(rng.uniform(0.5, 3.0))) * v_peak
            elif p.unit == "s":
                x[j] = (0.5 * k if k < 3 else float(rng.uniform(0.0, 2.0))) * lag
            else:
                x[j] = x[j] * float(np.exp(rng.normal(0.0, 0.7))) if x[j] != 0 else x[j]
        out.append(inside(x, lo, hi))
    return out


def mirror_start(
    model: Model, free: Sequence[str], x: np.ndarray, trials: Sequence[TrialData]
) -> np.ndarray | None:
    """The start with the drive lag and the viscous time constant swapped, or None.

    A step through a first-order drive lag ``T_a`` into a mass on a viscosity ``D``
    moves as ``1 / ((T_a s + 1)(m_a s + D))``: symmetric in ``T_a`` and ``m_a / D``. The
    mirror ``T_a' = m_a / D``, ``m_a' = D T_a`` answers a step from rest exactly as the
    original does; only a viscosity that changes with the thrust (``A``, two levels or
    more) or another effect tells them apart. Both are started from, and when they end
    about as well the fit says the trials do not decide (``fit.starts_disagree``).

    Parameters
    ----------
    model : Model
        The model fitted.
    free : sequence of str
        The parameters varied, in the order of ``x``.
    x : numpy.ndarray
        A start.
    trials : sequence of TrialData
        The trials (the median thrust sets the viscosity of a variable one).

    Returns
    -------
    numpy.ndarray or None
        None when the model has not one drive lag, a mass and a viscosity all varied, or
        the mirror is within 20 % of ``x``.
    """
    lags = [n for n in model.drive_lag_names if n in free]
    if len(lags) != 1 or "m_a" not in free or "D0" not in free:
        return None
    pos = {n: j for j, n in enumerate(free)}
    m_a, lag, d0 = float(x[pos["m_a"]]), float(x[pos[lags[0]]]), float(x[pos["D0"]])
    u, _ = data_scales(trials)
    a = float(x[pos["A"]]) if "A" in pos else 0.0
    d_eff = d0 * float(np.exp(-a * u)) if np.isfinite(u) else d0
    if not (d_eff > 0 and m_a > 0 and lag > 0):
        return None
    tau_v = m_a / d_eff
    if 1 / 1.2 < tau_v / lag < 1.2:
        return None
    out = np.asarray(x, dtype=float).copy()
    out[pos[lags[0]]] = tau_v
    out[pos["m_a"]] = d_eff * lag
    return out


def inside(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``x`` moved strictly inside ``[lo, hi]`` (a start on a bound has no gradient).

    Parameters
    ----------
    x : numpy.ndarray
        Start values.
    lo, hi : numpy.ndarray
        Their bounds (infinite where unbounded).

    Returns
    -------
    numpy.ndarray
        ``x`` at least a thousandth of the span (or of ``|lo|``) inside each bound.
    """
    span = np.where(np.isfinite(hi - lo), hi - lo, np.abs(lo) + 1.0)
    inner = np.minimum(1e-3 * span, np.abs(lo) + 1e-9)
    return np.clip(x, lo + inner, hi - 1e-3 * span)


@dataclass(frozen=True)
class Optimum:
    """One optimum a start ended at.

    Attributes
    ----------
    values : dict of str to float
        The free parameters there.
    chisqr : float
        The sum of squared residuals.
    delta_sigma2 : float
        Its cost above the best's, in noise variances (0 for the best; about 4 is as
        good as the best at 95 %).
    starts : int
        How many starts ended there.
    """

    values: dict[str, float]
    chisqr: float
    delta_sigma2: float
    starts: int

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "parameters": dict(self.values),
            "chisqr": self.chisqr,
            "delta_cost_noise_variances": self.delta_sigma2,
            "starts": self.starts,
        }


def distinct_optima(
    ends: Sequence[tuple[np.ndarray, float]],
    free: Sequence[str],
    stderr: Sequence[float],
    n_samples: int,
) -> list[Optimum]:
    """The ends of the starts told apart (best first).

    Two ends are the same optimum when every parameter is within 3 standard errors (and
    1 %) of the other's.

    Parameters
    ----------
    ends : sequence of (x, chisqr)
        Each start's end.
    free : sequence of str
        The names of ``x``'s entries.
    stderr : sequence of float
        The best fit's standard errors (0 or NaN: 1 % only).
    n_samples : int
        Samples fitted (the noise variance is the best's ``chisqr / (n - k)``).

    Returns
    -------
    list of Optimum
    """
    good = sorted(
        ((np.asarray(x, float), float(c)) for x, c in ends if np.isfinite(c)), key=lambda e: e[1]
    )
    if not good:
        return []
    se = np.nan_to_num(np.asarray(stderr, dtype=float), nan=0.0)
    s2 = good[0][1] / max(n_samples - len(free), 1)
    groups: list[list[tuple[np.ndarray, float]]] = []
    for x, c in good:
        for g in groups:
            ref = g[0][0]
            tol = np.maximum(3 * se, 0.01 * np.maximum(np.abs(ref), np.abs(x)))
            if np.all(np.abs(x - ref) <= tol + 1e-12):
                g.append((x, c))
                break
        else:
            groups.append([(x, c)])
    return [
        Optimum(
            {n: float(v) for n, v in zip(free, g[0][0], strict=True)},
            g[0][1],
            (g[0][1] - good[0][1]) / s2 if s2 > 0 else 0.0,
            len(g),
        )
        for g in groups
    ]
