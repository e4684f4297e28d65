"""A robot move with a late servo: the servo law acts ``tau_r`` seconds late.

The servo of MODEL.md, ``h = k_r (z_ref - z) + c_r (v_ref - v)``, computed from what the
robot saw ``tau_r`` ago (its controller's cycle, bus and amplifier latency)::

    h(t) = k_r (z_ref(t - tau_r) - z(t - tau_r)) + c_r (v_ref(t - tau_r) - v(t - tau_r))
    df/dt = (h - f) / T_a,   a = (f - D0 exp(-A |h|) v) / m_a,   dz/dt = v

A delay-differential equation, which the generated kernels (ordinary differential
equations with forward sensitivities) do not integrate: this module does, for the
balancer models the robot advice covers (the base with ``viscous`` or
``variable_viscosity``; ``A = 0`` is ``viscous``). Fixed RK4 steps of at most
:data:`MAX_STEP_S`; the delayed state is interpolated linearly in the stored history (and
inside the current step between its start and the stage, so ``tau_r = 0`` is the
undelayed loop). Before the first sample the load rests where it starts and the reference
holds its first value. Several parameter sets ("lanes") are simulated in one call.
"""

from __future__ import annotations

import math

import numpy as np

from balancer_id.simulation.jit import jit

#: Largest internal step (s): RK4 on the ~1 Hz coupled mode and a lag of tens of ms.
MAX_STEP_S = 0.0025

#: The model's effects the delayed loop covers: the servo on the base with a viscosity.
SUPPORTED_EFFECTS = frozenset({"servo", "viscous", "variable_viscosity"})

#: The lane parameters, in the order of the rows of ``lanes``.
LANE_PARAMS = ("m_a", "T_a", "D0", "A", "k_r", "c_r", "tau_r")


@jit(cache=True)
def _at(hist: np.ndarray, n_done: int, h: float, tq: float, t0: float) -> float:
    """History ``hist`` (sampled every ``h`` from ``t0``, ``n_done + 1`` points) at ``tq``."""
    x = (tq - t0) / h
    if x <= 0.0:
        return hist[0]
    i = int(x)  # x > 0: truncation is the floor
    if i >= n_done:
        return hist[n_done]
    w = x - i
    return (1.0 - w) * hist[i] + w * hist[i + 1]


@jit(cache=True)
def _ref(t_s: np.ndarray, r: np.ndarray, tq: float) -> float:
    """The reference ``r`` (given at the sample times ``t_s``) at ``tq``, held at the ends."""
    n = t_s.shape[0]
    if tq <= t_s[0]:
        return r[0]
    if tq >= t_s[n - 1]:
        return r[n - 1]
    dt = (t_s[n - 1] - t_s[0]) / (n - 1)
    i = int((tq - t_s[0]) / dt)
    if i > n - 2:
        i = n - 2
    while i > 0 and t_s[i] > tq:
        i -= 1
    while i < n - 2 and t_s[i + 1] < tq:
        i += 1
    w = (tq - t_s[i]) / (t_s[i + 1] - t_s[i])
    return (1.0 - w) * r[i] + w * r[i + 1]


@jit(cache=True)
def _lane(t_s, zr, vr, m_a, T_a, D0, A, k_r, c_r, tau, f0, v0, z0, n_sub, acc, force, vel):
    """Integrate one lane; fill ``acc``, ``force`` (the servo's force h) and ``vel``."""
    n = t_s.shape[0]
    h = (t_s[n - 1] - t_s[0]) / (n - 1) / n_sub
    n_steps = (n - 1) * n_sub
    zh = np.empty(n_steps + 1)
    vh = np.empty(n_steps + 1)
    zh[0] = z0
    vh[0] = v0
    t0 = t_s[0]
    f = f0
    v = v0
    z = z0
    k_out = 0
    for j in range(n_steps + 1):
        t = t0 + j * h
        # the output at a sample time: the servo force and the acceleration now
        if j % n_sub == 0:
            td = t - tau
            zd = _at(zh, j, h, td, t0)
            vd = _at(vh, j, h, td, t0)
            hh = k_r * (_ref(t_s, zr, td) - zd) + c_r * (_ref(t_s, vr, td) - vd)
            acc[k_out] = (f - D0 * math.exp(-A * abs(hh)) * v) / m_a
            force[k_out] = hh
            vel[k_out] = v
            k_out += 1
        if j == n_steps:
            break
        kf = np.zeros(4)
        kv = np.zeros(4)
        kz = np.zeros(4)
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
                zd = _at(zh, j, h, td, t0)
                vd = _at(vh, j, h, td, t0)
            hh = k_r * (_ref(t_s, zr, td) - zd) + c_r * (_ref(t_s, vr, td) - vd)
            kf[s] = (hh - fs) / T_a
            kv[s] = (fs - D0 * math.exp(-A * abs(hh)) * vs) / m_a
            kz[s] = vs
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
    zr = np.ascontiguousarray(z_ref, dtype=float)
    vr = np.ascontiguousarray(v_ref, dtype=float)
    acc = np.empty((p.shape[0], t.size))
    force = np.empty((p.shape[0], t.size))
    vel = np.empty((p.shape[0], t.size))
    for i, row in enumerate(p):
        _lane(t, zr, vr, *(float(x) for x in row), float(f0), float(v0), float(z0), n_sub,
              acc[i], force[i], vel[i])  # fmt: skip
    return acc, force, vel
