"""A robot move with a late servo: the servo law acts ``tau_r`` seconds late.

The servo of MODEL.md, ``h = k_r (z_ref - z) + c_r (v_ref - v)``, computed from what the
robot saw ``tau_r`` ago (its controller's cycle, bus and amplifier latency)::

    h(t) = k_r (z_ref(t - tau_r) - z(t - tau_r)) + c_r (v_ref(t - tau_r) - v(t - tau_r))
    df/dt = (h - f) / T_a,   a = (f - D0 exp(-A |h|) v) / m_a,   dz/dt = v

A delay-differential equation, which the generated kernels (ordinary differential
equations with forward sensitivities) do not integrate: this module does, for the
balancer models the robot advice covers (the base with ``viscous`` or
``variable_viscosity``; ``A = 0`` is ``viscous``). Fixed RK4 steps of at most
:data:`MAX_STEP_S`; the delayed state is interpolated in the stored history by cubic
Hermite polynomials (position with the velocity, velocity with the acceleration;
linearly inside the current step between its start and the stage, so ``tau_r = 0`` is the
undelayed loop), and the reference is evaluated where the servo reads it, so the
response moves smoothly with ``tau_r``. Before the first sample the load rests where it
starts and the reference holds its first value. Several parameter sets ("lanes") are
simulated in one call.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from balancer_id.simulation.jit import jit

#: Largest internal step (s): RK4 on the ~1 Hz coupled mode and a lag of tens of ms.
MAX_STEP_S = 0.0025

#: The model's effects the delayed loop covers: the servo on the base with a viscosity.
SUPPORTED_EFFECTS = frozenset({"servo", "viscous", "variable_viscosity"})

#: The lane parameters, in the order of the rows of ``lanes``.
LANE_PARAMS = ("m_a", "T_a", "D0", "A", "k_r", "c_r", "tau_r")


@jit(cache=True)
def _hermite(x0: float, d0: float, x1: float, d1: float, h: float, w: float) -> float:
    """Cubic Hermite interpolation on ``[0, h]`` at ``w h`` from values and slopes."""
    w2 = w * w
    w3 = w2 * w
    return (
        (2 * w3 - 3 * w2 + 1) * x0
        + (w3 - 2 * w2 + w) * h * d0
        + (-2 * w3 + 3 * w2) * x1
        + (w3 - w2) * h * d1
    )


@jit(cache=True)
def _past(zh, vh, ah, n_done, h, tq, t0):
    """Position and velocity at ``tq`` from the history (every ``h`` from ``t0``, points
    ``0 .. n_done``; accelerations known at ``0 .. n_done - 1``): cubic Hermite in both,
    the last interval's velocity linear (its end's acceleration is not known yet)."""
    x = (tq - t0) / h
    if x <= 0.0:
        return zh[0], vh[0]
    i = int(x)  # x > 0: truncation is the floor
    if i >= n_done:
        return zh[n_done], vh[n_done]
    w = x - i
    z = _hermite(zh[i], vh[i], zh[i + 1], vh[i + 1], h, w)
    if i + 1 < n_done:
        v = _hermite(vh[i], ah[i], vh[i + 1], ah[i + 1], h, w)
    else:
        v = (1.0 - w) * vh[i] + w * vh[i + 1]
    return z, v


@jit(cache=True)
def _lane(t_s, zr, vr, m_a, T_a, D0, A, k_r, c_r, tau, f0, v0, z0, n_sub, acc, force, vel):
    """Integrate one lane; fill ``acc``, ``force`` (the servo's force h) and ``vel``.

    ``zr``, ``vr``: the reference the servo acts on (already ``tau`` late) at every half
    internal step: index ``k`` is the time ``t_s[0] + k h / 2``.
    """
    n = t_s.shape[0]
    h = (t_s[n - 1] - t_s[0]) / (n - 1) / n_sub
    n_steps = (n - 1) * n_sub
    zh = np.empty(n_steps + 1)
    vh = np.empty(n_steps + 1)
    ah = np.empty(n_steps + 1)
    zh[0] = z0
    vh[0] = v0
    t0 = t_s[0]
    f = f0
    v = v0
    z = z0
    k_out = 0
    kf = np.zeros(4)
    kv = np.zeros(4)
    kz = np.zeros(4)
    for j in range(n_steps + 1):
        t = t0 + j * h
        for s in range(4):
            c = 0.0 if s == 0 else (0.5 if s < 3 else 1.0)
            ts = t + c * h
            fs = f + c * h * (kf[s - 1] if s > 0 else 0.0)
            vs = v + c * h * (kv[s - 1] if s > 0 else 0.0)
            zs = z + c * h * (kz[s - 1] if s > 0 else 0.0)
            td = ts - tau
            if td >= t:  # inside the current step: between its start and this stage
                w = (td - t) / (c * h) if c > 0.0 else 0.0
                zd = (1.0 - w) * z + w * zs
                vd = (1.0 - w) * v + w * vs
            else:
                zd, vd = _past(zh, vh, ah, j, h, td, t0)
            kk = 2 * j + (0 if s == 0 else (1 if s < 3 else 2))
            hh = k_r * (zr[kk] - zd) + c_r * (vr[kk] - vd)
            kf[s] = (hh - fs) / T_a
            kv[s] = (fs - D0 * math.exp(-A * abs(hh)) * vs) / m_a
            kz[s] = vs
            if s == 0:
                ah[j] = kv[0]
                if j % n_sub == 0:  # a sample time: the output
                    acc[k_out] = kv[0]
                    force[k_out] = hh
                    vel[k_out] = v
                    k_out += 1
                if j == n_steps:
                    break
        if j == n_steps:
            break
        f += h / 6.0 * (kf[0] + 2.0 * kf[1] + 2.0 * kf[2] + kf[3])
        v += h / 6.0 * (kv[0] + 2.0 * kv[1] + 2.0 * kv[2] + kv[3])
        z += h / 6.0 * (kz[0] + 2.0 * kz[1] + 2.0 * kz[2] + kz[3])
        zh[j + 1] = z
        vh[j + 1] = v


def simulate_delayed_servo(
    time: np.ndarray,
    z_ref: np.ndarray,
    v_ref: np.ndarray,
    lanes: np.ndarray,
    x0: tuple[float, float, float] | None = None,
    reference: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulate a robot move with a late servo for one or more parameter sets.

    Parameters
    ----------
    time : numpy.ndarray
        Equally spaced sample times (s).
    z_ref, v_ref : numpy.ndarray
        The robot's reference position (m) and velocity (m/s) at ``time``.
    lanes : numpy.ndarray
        Shape ``(7,)`` or ``(L, 7)``: per lane ``m_a, T_a, D0, A, k_r, c_r, tau_r``
        (:data:`LANE_PARAMS`; ``A = 0`` for a constant viscosity, ``tau_r`` in s).
    x0 : tuple of float, optional
        Drive force, velocity and position at ``time[0]`` (rest when None).
    reference : callable, optional
        ``t -> (z_ref, v_ref)`` at any times: the move itself, evaluated where the servo
        needs it (a delay of a fraction of a sample moves it smoothly); None interpolates
        ``z_ref`` and ``v_ref`` linearly between the samples.

    Returns
    -------
    accel, force, velocity : numpy.ndarray
        Shape ``(L, len(time))``: the load's acceleration (m/s^2), the servo's force
        ``h`` (N) and the load's velocity (m/s) at the sample times.

    Raises
    ------
    ValueError
        When the times are fewer than two or not increasing, or a lane has a
        non-positive ``m_a`` or ``T_a`` or a negative ``tau_r``.
    """
    t = np.asarray(time, dtype=float)
    if t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError("the move needs two or more increasing sample times")
    p = np.atleast_2d(np.asarray(lanes, dtype=float))
    if p.shape[1] != len(LANE_PARAMS):
        raise ValueError(f"each lane holds {', '.join(LANE_PARAMS)}")
    if np.any(p[:, 0] <= 0) or np.any(p[:, 1] <= 0) or np.any(p[:, 6] < 0):
        raise ValueError("m_a and T_a must be positive and tau_r not negative")
    dt = (t[-1] - t[0]) / (t.size - 1)
    n_sub = max(math.ceil(dt / MAX_STEP_S - 1e-9), 1)
    f0, v0, z0 = x0 if x0 is not None else (0.0, 0.0, 0.0)
    zs = np.asarray(z_ref, dtype=float)
    vs = np.asarray(v_ref, dtype=float)
    half = t[0] + np.arange(2 * (t.size - 1) * n_sub + 1) * (dt / n_sub / 2)
    acc = np.empty((p.shape[0], t.size))
    force = np.empty((p.shape[0], t.size))
    vel = np.empty((p.shape[0], t.size))
    for i, row in enumerate(p):
        td = half - row[6]
        if reference is not None:
            zr, vr = (np.ascontiguousarray(x, dtype=float) for x in reference(td))
        else:
            zr, vr = np.interp(td, t, zs), np.interp(td, t, vs)
        _lane(t, zr, vr, *(float(x) for x in row), float(f0), float(v0), float(z0), n_sub,
              acc[i], force[i], vel[i])  # fmt: skip
    return acc, force, vel
