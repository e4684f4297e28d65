"""The paper's method: steady acceleration, 3 T_a settling, m_a by a line through the origin.

Per trial, a first-order step ``a(t) = a_zc (1 - exp(-(t - t0)/T_a))`` is fitted to the
first seconds after the onset (the least-squares form of the paper's rule "the time to
reach the steady value is 3 T_a"; it averages through the sensor's 0.2 m/s^2
quantization). Then ``f_in = m_a a_zc`` over all trials gives ``m_a`` (Fig. 7) and the
per-trial ``T_a`` shows its drift with thrust and direction (Fig. 8). The method assumes
little viscosity during the window (the paper sets D = 0 for it).

The step fit is separable: for a given ``T`` the best ``a_zc`` is a linear
least-squares slope, so the fit is a search over ``T`` alone (variable projection) --
a log-spaced grid over the bounds evaluated at once, then a bounded Brent search in the
grid's best bracket. It finds the least-squares minimum a general solver would, in a
fraction of its time, and the global one on the bounds rather than the one nearest a
start value.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from balancer_id.identify.data import TrialData
from balancer_id.model.spec import Model

#: Length of the window after the onset used for the first-order fit (s).
CLASSIC_WINDOW_S = 2.0
#: Bounds of the per-trial time constant T_a (s).
T_BOUNDS = (0.005, 5.0)
#: Points of the log-spaced grid over ``T_BOUNDS`` (about 16 % apart).
_GRID_POINTS = 48


@dataclass
class ClassicTrial:
    """Paper-method figures of one trial."""

    index: int
    thrust_N: float
    direction: str
    a_zc: float
    T_a: float
    settling_time: float

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "index": self.index,
            "thrust_N": self.thrust_N,
            "direction": self.direction,
            "a_zc": self.a_zc,
            "T_a": self.T_a,
            "settling_time_s": self.settling_time,
        }


@dataclass
class ClassicResult:
    """The paper's identification over all trials.

    Attributes
    ----------
    m_a : float
        Slope of ``f_in = m_a a_zc`` through the origin (kg).
    m_a_stderr : float
        Its standard error from the scatter about the line (kg).
    T_a : float
        Median of the per-trial time constants (s).
    intercept_N : float
        Intercept a free line ``f_in = m a_zc + c`` would have (N): far from 0 hints at
        friction (a thrust that produces no motion).
    free_slope : float
        Slope of that free line (kg).
    scatter_N : float
        RMS of ``f_in - m_a a_zc`` (N).
    trials : list of ClassicTrial
    """

    m_a: float
    m_a_stderr: float
    T_a: float
    intercept_N: float
    free_slope: float
    scatter_N: float
    trials: list[ClassicTrial] = field(default_factory=list)

    def T_a_table(self) -> list[dict[str, object]]:
        """Mean T_a per thrust level and direction (the paper's Fig. 8 as a table)."""
        groups: dict[tuple[float, str], list[float]] = {}
        for t in self.trials:
            groups.setdefault((round(abs(t.thrust_N), 2), t.direction), []).append(t.T_a)
        return [
            {"thrust_N": k[0], "direction": k[1], "T_a": float(np.mean(v)), "n": len(v)}
            for k, v in sorted(groups.items())
        ]

    def start_values(self, model: Model) -> dict[str, float]:
        """Start values of a simulation-matching fit of ``model`` from the paper's method.

        ``m_a`` starts ``m_a``; ``T_a`` starts every parameter the model declares as its
        drive lag (``T_a``, or ``T_up`` and ``T_down``). A value that is not finite or not
        strictly inside the parameter's bounds is left out (the parameter's own start
        value is used).

        Parameters
        ----------
        model : Model
            The model to be fitted.

        Returns
        -------
        dict of str to float
            Parameter name -> start value.
        """
        wanted = {"m_a": self.m_a, **{name: self.T_a for name in model.drive_lag_names}}
        out: dict[str, float] = {}
        for name, value in wanted.items():
            if name not in model.param_names:
                continue
            p = model.param(name)
            if np.isfinite(value) and p.min < value < p.max:
                out[name] = float(value)
        return out

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict (CONTRACT.md ``classic`` plus details)."""
        return {
            "m_a": self.m_a,
            "T_a": self.T_a,
            "m_a_stderr": self.m_a_stderr,
            "intercept_N": self.intercept_N,
            "free_slope": self.free_slope,
            "scatter_N": self.scatter_N,
            "trials": [t.to_dict() for t in self.trials],
            "T_a_by_thrust": self.T_a_table(),
        }


def first_order_step(trial: TrialData, window_s: float = CLASSIC_WINDOW_S) -> ClassicTrial:
    """Fit ``a_zc (1 - exp(-(t - t0)/T))`` to the window after the onset of one trial.

    The median acceleration before the onset (at least five samples) is taken as the
    sensor offset and removed first.

    Parameters
    ----------
    trial : TrialData
        One step trial.
    window_s : float
        Length of the window after the onset that is fitted (s).

    Returns
    -------
    ClassicTrial
        The steady acceleration ``a_zc`` (m/s^2), the time constant ``T_a`` (s) and the
        settling time ``3 T_a`` (s); NaN when the window holds fewer than five samples
        or non-finite values.
    """
    t, a = trial.time, trial.accel
    rest = t < trial.t_step
    offset = float(np.median(a[rest])) if rest.sum() >= 5 else 0.0
    sel = (t >= trial.t_step) & (t <= trial.t_step + window_s)
    tt, aa = t[sel] - trial.t_step, a[sel] - offset
    if tt.size < 5:
        return ClassicTrial(trial.index, trial.thrust_N, trial.direction, np.nan, np.nan, np.nan)
    if not np.all(np.isfinite(aa)):
        return ClassicTrial(trial.index, trial.thrust_N, trial.direction, np.nan, np.nan, np.nan)
    a_zc, T = fit_first_order(tt, aa)
    return ClassicTrial(trial.index, trial.thrust_N, trial.direction, a_zc, T, 3 * T)


def fit_first_order(
    t: np.ndarray, a: np.ndarray, bounds: tuple[float, float] = T_BOUNDS
) -> tuple[float, float]:
    """Least-squares ``a_zc (1 - exp(-t/T))`` through ``(t, a)``, ``T`` within ``bounds``.

    For a fixed ``T`` the model is linear in ``a_zc``: with ``phi = 1 - exp(-t/T)`` the
    best gain is ``phi.a / phi.phi`` and the residual sum of squares is
    ``a.a - (phi.a)^2 / phi.phi``. The search over ``T`` evaluates that on a log-spaced
    grid (all at once), then refines the best point by a bounded Brent search between its
    neighbours (to 1e-9 of ``T``).

    Parameters
    ----------
    t : numpy.ndarray
        Time since the step (s), at least two distinct positive values.
    a : numpy.ndarray
        Acceleration, offset removed (m/s^2), finite.
    bounds : (float, float)
        Range of ``T`` (s), ``0 < low < high``.

    Returns
    -------
    a_zc : float
        Steady acceleration (m/s^2); 0 when ``a`` is all zero.
    T : float
        Time constant (s).
    """
    from scipy.optimize import minimize_scalar

    lo, hi = bounds
    grid = np.geomspace(lo, hi, _GRID_POINTS)
    phi = -np.expm1(-t[None, :] / grid[:, None])
    num = phi @ a
    den = np.einsum("ij,ij->i", phi, phi)
    gain = np.where(den > 0, num**2 / np.where(den > 0, den, 1.0), 0.0)
    k = int(np.argmax(gain))

    def explained(T: float) -> float:
        f = -np.expm1(-t / T)
        d = float(f @ f)
        return -(float(f @ a) ** 2) / d if d > 0 else 0.0

    left, right = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    best = minimize_scalar(
        explained, bounds=(left, right), method="bounded", options={"xatol": 1e-9 * grid[k]}
    )
    T = float(best.x) if best.fun <= -gain[k] else float(grid[k])
    f = -np.expm1(-t / T)
    d = float(f @ f)
    a_zc = float(f @ a) / d if d > 0 else 0.0
    return a_zc, T


def paper_method(trials: Sequence[TrialData], window_s: float = CLASSIC_WINDOW_S) -> ClassicResult:
    """Identify ``m_a`` and ``T_a`` the paper's way.

    Parameters
    ----------
    trials : sequence of TrialData
        The step trials.
    window_s : float
        Window after each onset for the first-order fit (s).

    Returns
    -------
    ClassicResult
    """
    per = [first_order_step(t, window_s) for t in trials]
    ok = [p for p in per if np.isfinite(p.a_zc) and abs(p.a_zc) > 0]
    f = np.array([p.thrust_N for p in ok])
    a = np.array([p.a_zc for p in ok])
    if a.size == 0:
        return ClassicResult(np.nan, np.nan, np.nan, np.nan, np.nan, np.nan, per)
    m_a = float(f @ a / (a @ a))
    resid = f - m_a * a
    dof = max(a.size - 1, 1)
    m_se = float(np.sqrt(resid @ resid / dof / (a @ a))) if a.size > 1 else np.nan
    if a.size >= 2 and np.ptp(a) > 0:
        slope, intercept = np.polyfit(a, f, 1)
    else:
        slope, intercept = m_a, 0.0
    T_a = float(np.median([p.T_a for p in ok]))
    return ClassicResult(
        m_a=m_a,
        m_a_stderr=m_se,
        T_a=T_a,
        intercept_N=float(intercept),
        free_slope=float(slope),
        scatter_N=float(np.sqrt(np.mean(resid**2))),
        trials=per,
    )
