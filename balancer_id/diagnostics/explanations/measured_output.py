"""The fit shared by the sensor's kinds: the model's output seen through the sensor.

A sensor's effect acts on the measured signal, not on the balancer: the model is
simulated as it is, its output mapped by the sensor (shifted in time, scaled, clipped)
and compared with the measurement; the map's one parameter is fitted with the model's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

# the arena module, not its names: it imports this package while it loads
from balancer_id.diagnostics import arena

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.diagnostics.explanations.base import Explanation
    from balancer_id.identify.result import FitResult

#: A map of one trial's simulated output: ``(trial, output, parameter) -> measured``.
OutputMap = Callable[[int, np.ndarray, float], np.ndarray]


@dataclass(frozen=True)
class MappedFit:
    """The model refitted with its output mapped by the sensor.

    Attributes
    ----------
    parts : list of numpy.ndarray
        Residuals, one array per trial.
    values : dict
        The balancer's parameters, corrected for the sensor.
    param : float
        The map's fitted parameter.
    stderr : float or None
        Its standard error (from the Jacobian, widened for a correlated residual).
    delta_bic, rmse : float
        The arena's score.
    """

    parts: list[np.ndarray]
    values: dict[str, float]
    param: float
    stderr: float | None
    delta_bic: float
    rmse: float


def fit_mapped(
    inp: ArenaInput,
    output_map: OutputMap,
    start: float,
    lo: float,
    hi: float,
    *,
    k_extra: int = 1,
    values: dict[str, float] | None = None,
    max_nfev: int = 60,
    chains: list[list[int]] | None = None,
) -> MappedFit:
    """The model's parameters and the map's parameter fitted together.

    Parameters
    ----------
    inp : ArenaInput
        The current fit and its trials.
    output_map : callable
        ``(trial index, simulated output, parameter) -> measured output``.
    start, lo, hi : float
        The map parameter's start and bounds.
    k_extra : int
        Parameters counted in the BIC beyond the current model's.
    values : dict, optional
        Where the balancer's parameters start (the current fit's by default).
    max_nfev : int
        Function evaluations.
    chains : list of list of int, optional
        The session's chains (:func:`~balancer_id.diagnostics.arena.session_chains`)
        for a map with a memory: it is then given each chain's joined output, indexed by
        the chain's first trial.

    Returns
    -------
    MappedFit
    """
    model = inp.match.model
    fixed = arena.held(inp.match)
    names = [n for n in model.param_names if n not in fixed]

    def post(i: int, y: np.ndarray) -> np.ndarray:
        return output_map(i, y, post.param)  # type: ignore[attr-defined]

    if chains is not None:
        post.chains = chains  # type: ignore[attr-defined]

    solution: list[object] = []
    parts, base, _, param = arena.fit_varying(
        model,
        arena.Trials(inp.trials),
        values or inp.match.values(),
        fixed,
        names[0],
        np.zeros((len(inp.trials), 0)),
        post=post,
        extra=(float(np.clip(start, lo, hi)), lo, hi),
        max_nfev=max_nfev,
        solution=solution,
    )
    d, rmse = arena.score(inp, parts, k_extra)
    return MappedFit(parts, base, float(param or 0.0), _stderr(solution, inp), d, rmse)


def _stderr(solution: list[object], inp: ArenaInput) -> float | None:
    """The last parameter's standard error from the optimizer's Jacobian."""
    if not solution:
        return None
    sol = solution[0]
    jac = np.asarray(sol.jac)  # type: ignore[attr-defined]
    res = np.asarray(sol.fun)  # type: ignore[attr-defined]
    n, p = jac.shape
    if n <= p:
        return None
    s2 = float(res @ res) / (n - p)
    cov = np.linalg.pinv(jac.T @ jac) * s2
    var = float(cov[-1, -1])
    if not np.isfinite(var) or var < 0:
        return None
    # a correlated residual has fewer independent samples than it has samples
    return float(np.sqrt(var / max(inp.independence, 0.05)))


def rest_samples(inp: ArenaInput, before: float = 0.02) -> list[np.ndarray]:
    """The measured acceleration at rest before each onset (trials that start at rest).

    Parameters
    ----------
    inp : ArenaInput
    before : float
        Samples this close to the onset (s) are left out.

    Returns
    -------
    list of numpy.ndarray
    """
    out = []
    for td in inp.trials:
        if td.continues:
            continue
        t = td.time - td.t_step
        out.append(np.asarray(td.accel, dtype=float)[t < -before])
    return [x[np.isfinite(x)] for x in out if x.size]


def corrected(e: Explanation, fit: FitResult) -> str:
    """``corrected, T_a 0.30 (now 0.26), m_a 15.1 (now 14.4)``: the balancer's parameters
    once the sensor is corrected.

    Parameters
    ----------
    e : Explanation
        A sensor's explanation (its ``detail["values"]``).
    fit : FitResult
        The fit diagnosed.

    Returns
    -------
    str
    """
    values: dict[str, float] = e.detail.get("values") or {}  # type: ignore[assignment]
    now = fit.match.values()
    moved = [
        f"{k} {float(values[k]):.4g} (now {now[k]:.4g})"  # type: ignore[index]
        for k in ("T_a", "m_a")
        if k in values and k in now
    ]
    return "corrected, " + ", ".join(moved) if moved else "corrected"
