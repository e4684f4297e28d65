"""Synthetic step-trial recordings for the segmentation tests (and checks of the generator).

A run is rest, then groups of thrust steps: each group starts from rest with one or
more steps (later ones "chained" while moving), the load follows the analytic response
of the first-order drive lag and the virtual mass with viscosity, saturating at the
winding speed, until a person catches it (a half-sine deceleration that stops it, a
sideways push, and a hand-force transient). The acceleration is the specific force
[0, 0, g + a] (or [0, 0, a] without g) rotated into a tilted sensor frame, with seeded
noise, quantization, bias drift, timing jitter and dropped samples.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from balancer_id.read.recording import Gap, Log, Recording

G = 9.8


@dataclass
class Truth:
    """What the generator put into a run."""

    onsets: list[float] = field(default_factory=list)
    thrusts: list[float] = field(default_factory=list)
    catches: list[float] = field(default_factory=list)
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))


def step_accel(tau: np.ndarray, m_a: float, T_a: float, D: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit-thrust acceleration and velocity, ``tau`` s after a step (0 before).

    ``a = (exp(-D tau/m) - exp(-tau/T)) / (m T (1/T - D/m))``, which is
    ``(1 - exp(-tau/T)) / m`` when ``D = 0``.
    """
    t = np.clip(tau, 0.0, None)
    if D == 0:
        a = -np.expm1(-t / T_a) / m_a
        v = (t - T_a * -np.expm1(-t / T_a)) / m_a
    else:
        k = 1.0 / (m_a * T_a * (1.0 / T_a - D / m_a))
        a = k * (np.exp(-D * t / m_a) - np.exp(-t / T_a))
        v = k * ((m_a / D) * -np.expm1(-D * t / m_a) - T_a * -np.expm1(-t / T_a))
    return np.where(tau >= 0, a, 0.0), np.where(tau >= 0, v, 0.0)


def random_rotation(rng: np.random.Generator, tilt_deg: float) -> Rotation:
    """Sensor-to-world rotation whose sensor z axis is ``tilt_deg`` from vertical."""
    yaw = Rotation.from_euler("z", rng.uniform(0, 360), degrees=True)
    phi = rng.uniform(0, 2 * np.pi)
    axis = np.array([np.cos(phi), np.sin(phi), 0.0])
    tilt = Rotation.from_rotvec(np.radians(tilt_deg) * axis)
    return tilt * yaw


def synth_run(
    seed: int,
    groups: list[list[float]],
    *,
    m_a: float = 15.1,
    T_a: float = 0.33,
    D: float = 0.0,
    v_max: float = 0.5,
    rate: float = 200.0,
    tilt_deg: float = 20.0,
    noise: bool = True,
    quantize: bool = True,
    mount: int = 1,
    with_g: bool = True,
    first_rest: float = 3.0,
    rest: tuple[float, float] = (2.0, 6.0),
    motion: tuple[float, float] = (2.5, 4.0),
    chain_after: float = 1.5,
    drift: bool = True,
    n_gaps: int = 0,
    has_force: bool = True,
    has_accel: bool = True,
    name: str = "Run 1",
) -> tuple[Recording, Truth]:
    """Build one synthetic run.

    Parameters
    ----------
    seed : int
        Seed of the run's random generator.
    groups : list of list of float
        Each group: signed thrusts (N, up positive); the first starts from rest, the
        others follow ``chain_after`` s apart while moving; a catch ends the group.
        The winding-speed limit ``v_max`` applies to single-step groups only.
    mount : {+1, -1}
        Sensor force = ``mount * thrust`` (+ offset): ``force_sign = mount``.
    n_gaps : int
        Number of stretches of dropped samples placed in rests.

    Returns
    -------
    Recording, Truth
    """
    rng = np.random.default_rng(seed)
    truth = Truth()
    plan: list[tuple[float, list[float], float]] = []  # (t_first, thrusts, t_catch)
    t = first_rest
    for grp in groups:
        t0 = t + rng.uniform(0, 1 / rate)
        t_catch = t0 + chain_after * (len(grp) - 1) + rng.uniform(*motion)
        plan.append((t0, grp, t_catch))
        t = t_catch + 0.4 + rng.uniform(*rest)
    duration = t + (rng.uniform(*rest) if groups else 0.0)
    time = np.arange(0.0, duration, 1.0 / rate)
    time = time + rng.uniform(-0.1, 0.1, time.size) / rate * 2 if noise else time
    n = time.size
    a_up = np.zeros(n)
    side = np.zeros((n, 2))
    thrust = np.zeros(n)
    hand = np.zeros(n)
    catch_len = 0.4
    for t0, grp, t_catch in plan:
        in_grp = (time >= t0) & (time < t_catch)
        a_g = np.zeros(n)
        v_g = np.zeros(n)
        for j, F in enumerate(grp):
            tj = t0 + j * chain_after
            truth.onsets.append(tj)
            truth.thrusts.append(F)
            a1, v1 = step_accel(time - tj, m_a, T_a, D)
            a_g += F * a1
            v_g += F * v1
            thrust += np.where((time >= tj) & (time < t_catch), F, 0.0)
        over = np.abs(v_g) >= v_max
        if len(grp) == 1 and over.any():  # saturate single steps only (chains stay linear)
            first = np.flatnonzero(over & in_grp)
            if first.size:
                a_g[first[0] :] = 0.0
                v_g[first[0] :] = np.sign(v_g[first[0]]) * v_max
        a_up += np.where(in_grp, a_g, 0.0)
        k_c = int(np.searchsorted(time, t_catch))
        v_c = v_g[k_c - 1]
        truth.catches.append(t_catch)
        tau = time - t_catch
        in_c = (tau >= 0) & (tau < catch_len)
        bump = np.sin(np.pi * tau[in_c] / catch_len)
        a_up[in_c] += -v_c * np.pi / (2 * catch_len) * bump
        side[in_c] += rng.normal(0, 1.0, 2) * bump[:, None]
        hand[in_c] = rng.choice([-1, 1]) * rng.uniform(4, 10) * bump
        thrust[in_c] = thrust[k_c - 1] * (1 - tau[in_c] / catch_len)
    rot = random_rotation(rng, tilt_deg)
    world = np.column_stack([side, a_up + (G if with_g else 0.0)])
    acc = rot.inv().apply(world)
    truth.up = rot.inv().apply([0.0, 0.0, 1.0])
    force = mount * (thrust + hand) - 20.0
    if drift:
        acc += rng.normal(0, 0.02, 3) + np.outer(time, rng.normal(0, 2e-4, 3))
        force += rng.normal(0, 0.002) * time + 0.1 * np.sin(2 * np.pi * time / 97.0)
    if noise:
        acc += rng.normal(0, 0.05, acc.shape)
        force += rng.normal(0, 0.05, n)
    if quantize:
        acc = np.round(acc / 0.2) * 0.2
        force = np.round(force / 0.03) * 0.03
    keep = np.ones(n, dtype=bool)
    rests = _rest_spans(first_rest, plan, duration, catch_len)
    for _ in range(n_gaps):
        lo, hi = rests[rng.integers(len(rests))]
        if hi - lo > 1.5:
            start = rng.uniform(lo + 0.3, hi - 1.0)
            keep &= ~((time >= start) & (time < start + rng.uniform(0.05, 0.6)))
    rec = make_recording(
        time[keep],
        force[keep] if has_force else None,
        acc[keep] if has_accel else None,
        rate,
        with_g=with_g,
        name=name,
    )
    return rec, truth


def _rest_spans(
    first_rest: float, plan: list[tuple[float, list[float], float]], end: float, catch_len: float
) -> list[tuple[float, float]]:
    spans = []
    t = 0.0
    for t0, _, t_catch in plan:
        spans.append((t + 0.2, t0 - 0.8))
        t = t_catch + catch_len + 0.5
    spans.append((t, end))
    return [s for s in spans if s[1] > s[0]] or [(0.0, first_rest)]


def make_recording(
    time: np.ndarray,
    force: np.ndarray | None,
    accel: np.ndarray | None,
    rate: float,
    *,
    with_g: bool = True,
    name: str = "Run 1",
) -> Recording:
    """Wrap arrays as a reader would (gaps: time steps longer than 1.5 nominal steps)."""
    dt = np.diff(time)
    nominal = 1.0 / rate
    gaps = [
        Gap(float(time[i]), float(time[i + 1]), round(dt[i] / nominal) - 1)
        for i in np.flatnonzero(dt > 1.5 * nominal)
    ]
    axes = ("x", "y", "z") if accel is None or accel.shape[1] == 3 else ("z",)
    return Recording(
        name=name,
        time=time,
        force=force,
        accel=accel,
        accel_includes_gravity=with_g,
        accel_axes=axes,
        sample_rate_hz=float(1.0 / np.median(dt)),
        gaps=gaps,
    )


def make_log(*recs: Recording, path: str = "synthetic.csv") -> Log:
    """A log holding the given runs."""
    return Log(path=Path(path), format="generic", recordings=list(recs))


# --- checks of the generator itself -------------------------------------------------


def test_step_response_is_first_order_rise_without_viscosity():
    tau = np.array([-0.1, 0.0, 0.33, 3 * 0.33, 10.0])
    a, _ = step_accel(tau, 15.1, 0.33, 0.0)
    a_zc = 2.45 / 15.1
    np.testing.assert_allclose(
        2.45 * a, a_zc * np.array([0, 0, 1 - np.exp(-1), 0.9502, 1]), rtol=1e-3, atol=1e-9
    )


def test_viscous_response_matches_its_velocity():
    tau = np.linspace(0, 8, 8001)
    a, v = step_accel(tau, 15.1, 0.33, 6.0)
    v_num = np.concatenate([[0.0], np.cumsum((a[1:] + a[:-1]) / 2 * np.diff(tau))])
    np.testing.assert_allclose(v, v_num, atol=1e-6)
    assert a[-1] < 0.5 * a.max()


def test_sensor_reads_g_along_the_tilted_up_vector():
    rec, truth = synth_run(3, [], tilt_deg=25.0, noise=False, quantize=False, drift=False)
    np.testing.assert_allclose(rec.accel, np.tile(G * truth.up, (rec.n_samples, 1)), atol=1e-12)
    assert abs(np.degrees(np.arccos(truth.up[2])) - 25.0) < 1e-9
