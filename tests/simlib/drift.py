"""A session whose parameters move while it is recorded (issue 33: oil warming, a payload).

The kernel simulates constant parameters; a drifting balancer is simulated in short
chunks, each with the parameters at its middle, the state carried from one chunk to the
next (drive force, velocity, position), then recorded as the sensor would (as
:func:`simlib.sessions.record`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from balancer_id.constants import ACCEL_RESOLUTION, FORCE_RESOLUTION_N
from balancer_id.model.spec import Model
from balancer_id.read.recording import Recording
from balancer_id.simulation.engine import simulate
from balancer_id.simulation.inputs import Thrust
from balancer_id.simulation.synth import SensorSettings, ar1_noise, keep_mask, up_vector

#: Length of a chunk of constant parameters (s): short against any drift simulated.
CHUNK_S = 0.5


def alternating_levels(
    n: int, rng: np.random.Generator, magnitudes: tuple[float, ...] = (2.45, 4.9, 7.35)
) -> list[float]:
    """``n`` thrust levels: up and down in turn, each a random one of ``magnitudes`` other
    than the one before (the weight changed at every step).

    Parameters
    ----------
    n : int
        Number of levels.
    rng : numpy.random.Generator
        The random source.
    magnitudes : sequence of float
        The sizes to draw from (N).

    Returns
    -------
    list of float
    """
    out: list[float] = []
    for k in range(n):
        choices = [m for m in magnitudes if not out or m != abs(out[-1])] or list(magnitudes)
        out.append(float(rng.choice(choices)) * (1 if k % 2 == 0 else -1))
    return out


def record_drifting(
    model: Model,
    values_at: Callable[[float], Mapping[str, float]],
    thrust: Thrust,
    duration_s: float,
    *,
    sensor: SensorSettings | None = None,
    name: str = "Run #1",
    seed: int = 0,
) -> Recording:
    """Simulate ``thrust`` with parameters ``values_at(t)`` and record it.

    Parameters
    ----------
    model : Model
        The true model.
    values_at : callable
        Time (s) -> parameter values (defaults for the rest).
    thrust : Thrust
        The operating thrust ``u(t)``.
    duration_s : float
        Length of the recording (s).
    sensor : SensorSettings, optional
        Noise, quantization, tilt, drop-outs.
    name : str
        Name of the run.
    seed : int
        Seed of every random choice.

    Returns
    -------
    Recording
    """
    sensor = sensor or SensorSettings()
    rng = np.random.default_rng(seed)
    dt = 1.0 / sensor.rate_hz
    n = round(duration_s / dt) + 1
    time = np.arange(n) * dt
    per = max(1, round(CHUNK_S / dt))
    accel = np.empty(n)
    h = np.empty(n)
    x0 = None
    for i in range(0, n - 1, per):
        j = min(i + per, n - 1)
        t = time[i : j + 1]
        sim = simulate(model, values_at(0.5 * (t[0] + t[-1])), t, thrust, x0=x0)
        accel[i : j + 1] = sim.accel
        h[i : j + 1] = sim.operating_force
        x0 = (float(sim.drive_force[-1]), float(sim.velocity[-1]), float(sim.position[-1]))
    azimuth = (
        float(rng.uniform(0, 360)) if sensor.tilt_azimuth_deg is None else sensor.tilt_azimuth_deg
    )
    up = up_vector(sensor.tilt_deg, azimuth)
    specific = (accel + sensor.g)[:, None] * up[None, :]
    acc = specific + ar1_noise(rng, sensor.accel_noise, sensor.noise_correlation, specific.shape)
    force = sensor.force_offset + sensor.force_sign * h
    force = force + rng.normal(0.0, sensor.force_noise, force.shape)
    if sensor.quantize:
        acc = np.round(acc / ACCEL_RESOLUTION) * ACCEL_RESOLUTION
        force = np.round(force / FORCE_RESOLUTION_N) * FORCE_RESOLUTION_N
    keep = keep_mask(n, sensor.drop_fraction, rng)
    return Recording(
        name=name,
        time=time[keep],
        force=force[keep],
        accel=acc[keep],
        accel_includes_gravity=True,
        accel_axes=("x", "y", "z"),
        sample_rate_hz=sensor.rate_hz,
    )
