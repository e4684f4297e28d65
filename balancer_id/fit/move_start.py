"""The start of a robot move, refined by the fit itself (``--trajectory`` without ``start=``).

The segmentation aligns the reference on the log (the servo law on the force channel,
or the integrated motion alone, which the closed loop's oscillation pulls by a few
tenths of a second). Here the start is refined by maximum likelihood: one common shift
of every move's reference, chosen by a bounded scalar search on the cost of a fit of
the servo (``k_r``, ``c_r``) with the balancer's parameters held at their start values.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import minimize_scalar

from balancer_id.errors import IdentificationError
from balancer_id.fit.data import TrialData
from balancer_id.fit.matching import match_trials
from balancer_id.model.spec import Model

#: The shifts searched (s) and the tolerance of the search (s).
SHIFT_RANGE_S = (-0.4, 0.4)
SHIFT_TOL_S = 0.002
#: Parameters fitted while the shift is searched.
SERVO_PARAMS = ("k_r", "c_r")


def shifted(trial: TrialData, shift: float) -> TrialData:
    """The trial with its reference move started ``shift`` seconds later.

    Parameters
    ----------
    trial : TrialData
        A move trial (its input holds ``z_ref`` and ``v_ref``).
    shift : float
        Seconds to delay the reference by (negative: earlier).

    Returns
    -------
    TrialData
        A copy; the reference is interpolated (held at its first and last values
        outside the window).
    """
    inp = trial.input
    if inp.z_ref is None or inp.v_ref is None or shift == 0.0:
        return trial
    t = np.asarray(inp.time, dtype=float)
    zr = np.interp(t - shift, t, inp.z_ref)
    vr = np.interp(t - shift, t, inp.v_ref)
    return dataclasses.replace(
        trial,
        t_step=trial.t_step + shift,
        input=dataclasses.replace(inp, z_ref=zr, v_ref=vr),
    )


def refine_move_start(
    model: Model,
    trials: Sequence[TrialData],
    start: Mapping[str, float] | None = None,
    fixed: Mapping[str, float] | None = None,
) -> tuple[list[TrialData], float]:
    """Shift every move's reference by the delay that fits the servo best.

    Parameters
    ----------
    model : Model
        The model (with ``servo``).
    trials : sequence of TrialData
        The move trials, their references aligned by the segmentation.
    start : mapping, optional
        Start values; every parameter other than ``k_r`` and ``c_r`` is held at
        ``fixed``, else ``start``, else its default during the search.
    fixed : mapping, optional
        Parameters held by the user.

    Returns
    -------
    trials : list of TrialData
        The shifted trials.
    shift : float
        The shift applied (s).
    """
    held = {**model.defaults(), **dict(start or {}), **dict(fixed or {})}
    held = {k: v for k, v in held.items() if k not in SERVO_PARAMS}
    servo_start = {k: v for k, v in dict(start or {}).items() if k in SERVO_PARAMS}

    def cost(shift: float) -> float:
        data = [shifted(t, shift) for t in trials]
        try:
            m = match_trials(model, data, start=servo_start, fixed=held, max_nfev=300)
        except IdentificationError:
            return float("inf")
        return float(np.sum(m.residual**2))

    res = minimize_scalar(
        cost, bounds=SHIFT_RANGE_S, method="bounded", options={"xatol": SHIFT_TOL_S}
    )
    shift = float(res.x) if np.isfinite(res.fun) and res.fun <= cost(0.0) else 0.0
    return [shifted(t, shift) for t in trials], shift
