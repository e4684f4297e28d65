"""A parameter the data do not reach is a bound, not a value (issue 31, item 3).

A speed limit above every speed the trials reach, a friction below the noise, a delay
shorter than anything the samples see: the cost does not change when the parameter
moves on to the end of its range, so the fitted value (``v_max = 3.460 ± 0.0043 m/s``)
is wherever the optimizer stopped, and its standard error describes nothing. Here each
such parameter (a limit, friction or delay: not the smooth base laws) is held at the end
of its range and the others refitted; where the cost stays within the 95 % profile
threshold of the optimum, the parameter is reported as the one-sided bound its profile
gives (``v_max >= 3.4 m/s (not reached)``), and the others take the refit's values and
standard errors (the singular direction gone).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from balancer_id.errors import BalancerIdError
from balancer_id.identify.basins import SMOOTH_PARAMETERS
from balancer_id.identify.intervals import PROFILE_FACTOR, chi2_quantile_1dof, profile_interval
from balancer_id.identify.matching import MatchResult, ParameterEstimate, match_trials
from balancer_id.notes import Note


def _threshold(match: MatchResult, level: float = 0.95) -> float:
    """The profile threshold of ``match``'s cost (see :mod:`~balancer_id.identify.intervals`)."""
    n = match.y.size
    k = sum(1 for p in match.parameters.values() if p.vary)
    s_min = float(np.sum(match.residual**2))
    tau = max(float(match.metrics.get("residual_tau", 1.0)), 1.0)
    return s_min + s_min / max(n - k, 1) * tau * chi2_quantile_1dof(level)


def _ends(match: MatchResult, name: str) -> list[tuple[str, float]]:
    """The ends of ``name``'s range a profile is followed to (``"below"``/``"above"``)."""
    spec = match.model.param(name)
    value = match.parameters[name].value
    lo, hi = spec.min, spec.max
    if spec.min >= 0 and value > 0:
        if spec.min > 0:
            lo = max(spec.min, value / PROFILE_FACTOR)
        hi = min(spec.max, value * PROFILE_FACTOR)
    return [("below", lo), ("above", hi)]


def _held_fit(match: MatchResult, name: str, value: float) -> MatchResult | None:
    """``match``'s model refitted with ``name`` held at ``value`` (None: failed)."""
    held = {p.name: p.value for p in match.parameters.values() if not p.vary}
    try:
        with np.errstate(all="ignore"):
            return match_trials(
                match.model,
                match.data.trials,
                start={**match.values(), name: value},
                fixed={**held, name: value},
                max_nfev=300,
            )
    except BalancerIdError:
        return None


def settle_unreached(
    match: MatchResult, user_bounds: Mapping[str, object] | None = None
) -> tuple[MatchResult, list[Note]]:
    """Report each limit, friction or delay the data do not reach as a bound.

    Parameters
    ----------
    match : MatchResult
        The fit.
    user_bounds : mapping or collection of str
        Parameters bounded by the user (``--bounds``): their ends are the user's, not
        tested here.

    Returns
    -------
    match : MatchResult
        ``match`` itself when every such parameter is reached; else the refit with the
        unreached ones held at their ends, each given back as a varied estimate with
        ``not_reached`` set and its one-sided profile interval.
    notes : list of Note
        One ``fit.not_reached`` note per parameter.
    """
    free = [
        p.name
        for p in match.parameters.values()
        if p.vary and p.name not in SMOOTH_PARAMETERS and p.name not in (user_bounds or {})
    ]
    free = [n for n in free if n not in match.model.drive_lag_names]
    if not free:
        return match, []
    threshold = _threshold(match)
    unreached: dict[str, tuple[str, float]] = {}
    for name in free:
        for side, end in _ends(match, name):
            refit = _held_fit(match, name, end)
            if refit is not None and float(np.sum(refit.residual**2)) <= threshold:
                unreached[name] = (side, end)
                break
    if not unreached:
        return match, []
    intervals = {}
    for name in unreached:
        iv = profile_interval(match, name)
        intervals[name] = (iv.low, iv.high)
    held = {p.name: p.value for p in match.parameters.values() if not p.vary}
    ends = {name: end for name, (_, end) in unreached.items()}
    try:
        with np.errstate(all="ignore"):
            settled = match_trials(
                match.model,
                match.data.trials,
                start={**match.values(), **ends},
                fixed={**held, **ends},
            )
    except BalancerIdError:
        return match, []
    notes = []
    for name, (side, end) in unreached.items():
        spec = match.model.param(name)
        low, high = intervals[name]
        bound = low if side == "above" else high
        settled.parameters[name] = ParameterEstimate(
            name, end, None, spec.unit, True, None, (low, high), side
        )
        relation = ">=" if side == "above" else "<="
        what = "not reached" if side == "above" else "not resolved"
        notes.append(
            Note(
                "fit.not_reached",
                f"{name} {relation} {bound:.3g} {spec.unit} ({what}): the trials fit as well "
                f"with any {name} {'above' if side == 'above' else 'below'} that, so it is a "
                f"bound, not a value ({spec.description}); the other parameters are fitted "
                f"with {name} = {end:g}",
                subject=name,
                severity="info",
            )
        )
    settled.warnings = [
        *(w for w in settled.warnings if not _about_held(w, unreached)),
        *notes,
    ]
    settled.nfev += match.nfev
    return settled, notes


def _about_held(note: object, names: Mapping[str, object]) -> bool:
    """Whether ``note`` is about a parameter now reported as a bound."""
    return isinstance(note, Note) and note.subject in names
