"""The step trial that tells two fitted models apart (issue 31: a rival that fits as well).

Two models that fit the recorded trials alike answer a new trial differently. Each
candidate of the planner's grid (:func:`~balancer_id.identify.design.candidate_grid`:
thrust levels from a quarter to three times the largest recorded, both directions, rests
and durations) is simulated with both fits; the separation of a candidate is the sum of
squared differences of the two responses over the noise variance widened by the
residual's correlation time, ``d2 = sum((y1 - y2)^2) / (sigma^2 tau)``: about the BIC one
such trial would add between them (before either refits). The trial proposed is the
shortest whose separation reaches :data:`ENOUGH` (a decisive difference), else the one
separating most; a trial moving the load farther than
:data:`~balancer_id.identify.design.TRAVEL_FACTOR` times the recorded trials is not
proposed (the hoist's travel is finite).
"""

from __future__ import annotations

import numpy as np

from balancer_id.identify.design import TRAVEL_FACTOR, Candidate, candidate_grid
from balancer_id.identify.matching import MatchResult
from balancer_id.simulation.engine import PackedTrials

__all__ = ["ENOUGH", "separating_trial", "separation"]

#: A separation this large (in noise variances: a BIC difference of 20, odds of e^10) tells
#: the two apart beyond doubt; the shortest trial reaching it is proposed.
ENOUGH = 20.0


def _responses(match: MatchResult, grid: list[Candidate]) -> list[np.ndarray]:
    """Each candidate's simulated output columns (acceleration, speed, position): one
    simulation per level and rest (a shorter duration is a prefix of the longest)."""
    longest: dict[tuple[float, float], Candidate] = {}
    for c in grid:
        key = (c.thrust_N, c.rest_s)
        if key not in longest or c.duration_s > longest[key].duration_s:
            longest[key] = c
    keys = list(longest)
    inputs = [longest[key].trial_input() for key in keys]
    packed = PackedTrials.pack(inputs)
    with np.errstate(all="ignore"):
        out = packed.run(match.model, np.asarray(match.model.vector(match.values()), float))
    edges = np.concatenate([[0], np.cumsum([len(i.time) for i in inputs])])
    runs = {key: (inputs[k].time, out[edges[k] : edges[k + 1]]) for k, key in enumerate(keys)}
    parts = []
    for c in grid:
        t, o = runs[(c.thrust_N, c.rest_s)]
        parts.append(o[np.asarray(t) <= c.rest_s + c.duration_s + 1e-9])
    return parts


def separation(
    a: MatchResult, b: MatchResult, grid: list[Candidate]
) -> tuple[np.ndarray, np.ndarray]:
    """Each candidate's separation of the two fits and its farthest move.

    Parameters
    ----------
    a, b : MatchResult
        Two fits of the same trials (``a`` gives the noise variance).
    grid : list of Candidate
        The candidates.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        ``d2`` (noise variances) and the farthest either model moves the load (m).
    """
    n = max(a.y.size, 1)
    s2 = float(np.sum(a.residual**2)) / n * max(float(a.metrics.get("residual_tau", 1.0)), 1.0)
    ya, yb = _responses(a, grid), _responses(b, grid)
    d2 = np.array(
        [float(np.nansum((p[:, 0] - q[:, 0]) ** 2)) / s2 for p, q in zip(ya, yb, strict=True)]
    )
    moves = np.array(
        [
            max(float(np.nanmax(np.abs(p[:, 2]))), float(np.nanmax(np.abs(q[:, 2]))))
            for p, q in zip(ya, yb, strict=True)
        ]
    )
    return np.nan_to_num(d2, nan=0.0), np.nan_to_num(moves, nan=np.inf)


def separating_trial(a: MatchResult, b: MatchResult) -> str | None:
    """The step trial that tells fit ``a`` from fit ``b``, in words (None: none does).

    Parameters
    ----------
    a, b : MatchResult
        The fit and its rival, of the same trials.

    Returns
    -------
    str or None
        ``"record a step of +0.02 N (up) after 3 s at rest, recorded 8 s after the step
        (the two fits differ there by 6.3 noise standard deviations)"``.
    """
    try:
        grid = candidate_grid(a.data.trials)
        with np.errstate(all="ignore"):
            recorded = a.data.packed.run(a.model, np.asarray(a.model.vector(a.values()), float))
        travel = TRAVEL_FACTOR * float(np.nanmax(np.abs(recorded[:, 2])))
        d2, moves = separation(a, b, grid)
    except Exception:  # a proposal is advice: a simulation that fails proposes nothing
        return None
    d2 = np.where(moves <= travel, d2, 0.0)
    if not np.any(d2 > 0):
        return None
    enough = [k for k in np.flatnonzero(d2 >= ENOUGH)]
    k = (
        min(enough, key=lambda j: (grid[j].rest_s + grid[j].duration_s, -d2[j]))
        if enough
        else int(np.argmax(d2))
    )
    return (
        f"record {grid[k].sentence()} (the two fits differ there by "
        f"{np.sqrt(d2[k]):.1f} noise standard deviations)"
    )
