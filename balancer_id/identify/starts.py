"""Start values and bounds of a fit from the response itself, at any scale.

The paper's method gives ``m_a`` and ``T_a`` from the steady accelerations; it needs
step trials that reach a steady level and it can come out negative or far off on logs
unlike the paper's (a lab cart, a bungee, a hoist of two tonnes). The start here needs
neither: it is the equation-error fit of the model's own equations

    m_a a = f - D v,     T_a df/dt = u - f

to the measured acceleration ``a``, its integral ``v`` and the thrust ``u`` passed
through a first-order lag ``T`` for ``T`` on a grid: for each ``T``, the acceleration is
regressed on ``(f_T, v, 1)`` (noise stays in the regressand, so the slopes are not
attenuated), giving ``m_a = 1 / b_f`` and ``D = -b_v / b_f``; the ``T`` with the
smallest residual is the lag. Everything scales with the data: the slope's units carry
the mass, so a 0.2 kg cart and a 2000 kg hoist start where they are.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from balancer_id.identify.classic import ClassicResult
from balancer_id.identify.data import TrialData
from balancer_id.model.spec import Model
from balancer_id.notes import Note

#: Lags tried (s): none, then a log grid from 1 ms to 5 s.
LAG_GRID_S = np.concatenate([[0.0], np.geomspace(1e-3, 5.0, 40)])

#: RK4 on a step of ``h`` is stable for ``h / T_a`` below about 2.78; the lower bound of
#: a drive lag is this fraction of the longest sample interval fitted (the response of a
#: shorter lag is not resolved by the samples anyway).
LAG_FLOOR_OF_STEP = 0.5


@dataclass(frozen=True)
class ResponseStart:
    """Start values from the equation-error fit.

    Attributes
    ----------
    m_a : float
        Mass (kg); NaN when the data do not determine it.
    T_a : float
        Drive lag (s) of the best grid point (0: no lag resolved).
    D : float
        Viscosity (kg/s), clipped at 0.
    r2 : float
        Fraction of the acceleration's variance the regression explains.
    """

    m_a: float
    T_a: float
    D: float
    r2: float

    @property
    def usable(self) -> bool:
        """Whether the mass came out finite and positive, with some explained variance."""
        return bool(np.isfinite(self.m_a) and self.m_a > 0 and self.r2 > 0.05)


#: Trials the response start is computed from, spread evenly over a longer session: the
#: start only has to be near (the fit then uses every trial), and its lag grid costs a
#: regression over every sample it sees.
MAX_START_TRIALS = 60


def _lagged(t: np.ndarray, u: np.ndarray, lag: float) -> np.ndarray:
    """``u`` through ``T df/dt = u - f`` from ``f = u[0]`` (the median sample interval)."""
    if lag <= 0 or u.size < 2:
        return u.copy()
    from balancer_id.simulation.filters import first_order_lag

    alpha = float(np.exp(-np.median(np.diff(t)) / lag))
    return u[0] + first_order_lag(u - u[0], alpha)


def response_start(trials: Sequence[TrialData]) -> ResponseStart:
    """Start values of ``m_a``, ``T_a`` and a viscosity from the trials' own response.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials as fitted (measured vertical acceleration and the thrust driving them);
        at most :data:`MAX_START_TRIALS` of them, spread evenly, are used.

    Returns
    -------
    ResponseStart
        The best grid lag's mass, viscosity and explained variance (NaN mass when the
        regression is degenerate).
    """
    parts = []
    if len(trials) > MAX_START_TRIALS:  # a start needs no shift's worth of trials
        keep = np.unique(np.linspace(0, len(trials) - 1, MAX_START_TRIALS).round().astype(int))
        trials = [trials[int(k)] for k in keep]
    for td in trials:
        t = np.asarray(td.time, dtype=float)
        a = np.asarray(td.accel, dtype=float)
        ok = np.isfinite(t) & np.isfinite(a)
        if ok.sum() < 10:
            continue
        t, a = t[ok], a[ok]
        u = np.asarray(td.input.thrust.at(t), dtype=float)
        x0 = td.input.x0
        v0 = 0.0 if x0 is None else float(x0[1])
        v = v0 + np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))])
        parts.append((t, a, u, v))
    nan = ResponseStart(np.nan, np.nan, np.nan, 0.0)
    if not parts:
        return nan
    y = np.concatenate([p[1] for p in parts])
    v = np.concatenate([p[3] for p in parts])
    var = float(np.var(y))
    if not np.isfinite(var) or var <= 0:
        return nan
    best: tuple[float, float, np.ndarray] | None = None
    for lag in LAG_GRID_S:
        f = np.concatenate([_lagged(p[0], p[2], lag) for p in parts])
        design = np.column_stack([f, v, np.ones_like(f)])
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        sse = float(np.sum((y - design @ coef) ** 2))
        if best is None or sse < best[0]:
            best = (sse, float(lag), coef)
    assert best is not None
    sse, lag, coef = best
    b_f, b_v = float(coef[0]), float(coef[1])
    if not (np.isfinite(b_f) and b_f > 0):
        return ResponseStart(np.nan, lag, np.nan, 1.0 - sse / (var * y.size))
    return ResponseStart(1.0 / b_f, lag, max(-b_v / b_f, 0.0), 1.0 - sse / (var * y.size))


def lag_floor(trials: Sequence[TrialData]) -> float:
    """The shortest drive lag the samples resolve (s): half the longest sample interval.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials as fitted.

    Returns
    -------
    float
        ``LAG_FLOOR_OF_STEP`` times the largest median sample interval of the trials.
    """
    steps = [float(np.median(np.diff(td.time))) for td in trials if td.time.size > 2]
    return LAG_FLOOR_OF_STEP * max(steps) if steps else 0.0


def fit_start(
    model: Model, trials: Sequence[TrialData], classic: ClassicResult
) -> tuple[dict[str, float], list[Note]]:
    """Start values of a fit of ``model`` at the data's own scale, and why.

    The paper's method gives ``m_a`` and the drive lags when it is plausible: a finite,
    positive mass within a factor of 3 of the response's own (:func:`response_start`).
    Otherwise the response gives them, and a paper's mass that is not positive is a note
    (``fit.start_contradicted``): the steady accelerations do not grow with the thrust
    as a mass's would. The viscosity starts from the response; ``A`` from the thrusts
    (``A |u|`` of about 1 at the median thrust, as in the paper).

    Parameters
    ----------
    model : Model
        The model to fit.
    trials : sequence of TrialData
        The trials to fit.
    classic : ClassicResult
        The paper's method on the same trials.

    Returns
    -------
    start : dict of str to float
        Start values (only of ``model``'s parameters; strictly inside their bounds).
    notes : list of Note
        What the start had to overrule.
    """
    names = set(model.param_names)
    response = response_start(trials)
    notes: list[Note] = []
    start: dict[str, float] = {}
    thrusts = np.array([abs(td.thrust_N) for td in trials if td.thrust_N != 0], dtype=float)
    median_u = float(np.median(thrusts)) if thrusts.size else float("nan")
    if "A" in names and np.isfinite(median_u) and median_u > 0:
        start["A"] = 1.0 / median_u
    if response.usable:
        start["m_a"] = response.m_a
        for name in model.drive_lag_names:
            start[name] = max(response.T_a, lag_floor(trials) * 2.0)
        if "D0" in names and np.isfinite(response.D):
            start["D0"] = response.D * float(np.exp(start.get("A", 0.0) * median_u))
    m_c = classic.m_a
    plausible = bool(np.isfinite(m_c) and m_c > 0) and (
        not response.usable or 1 / 3 < m_c / response.m_a < 3
    )
    if plausible:
        start.update(classic.start_values(model))
    elif np.isfinite(m_c) and response.usable:
        reason = (
            "is not positive: the steady accelerations do not grow with the thrust as a "
            "mass's would (no steady level reached, a spring or a lag the method ignores?)"
            if m_c <= 0
            else f"is {m_c / response.m_a:.2g} times the response's own"
        )
        notes.append(
            Note(
                "fit.start_contradicted",
                f"the paper's method gives m_a = {m_c:.3g} kg, which {reason}; the fit starts "
                f"from the response instead (m_a {response.m_a:.3g} kg, T_a "
                f"{response.T_a:.2g} s)",
                subject="m_a",
            )
        )
    out: dict[str, float] = {}
    for name, value in start.items():
        if name not in names or not np.isfinite(value):
            continue
        p = model.param(name)
        out[name] = float(np.clip(value, p.min, p.max))
    return out, notes
