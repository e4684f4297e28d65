"""Synthetic logs recorded the way people record them: whole sessions and guided moves.

:mod:`balancer_id.simulation.synth` writes one run per thrust step from rest. Here one run
holds any thrust history ``u(t)``: a session in which the thrust changes while the load
is still moving (push up, pull down, push harder, ...), or a person guiding the load
through a smooth move. The sensor records it as in ``synth`` (tilt, noise, drop-outs).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from balancer_id.constants import ACCEL_RESOLUTION, FORCE_RESOLUTION_N
from balancer_id.model.spec import Model
from balancer_id.read.recording import Recording
from balancer_id.simulation.engine import simulate
from balancer_id.simulation.inputs import Thrust
from balancer_id.simulation.synth import SensorSettings, ar1_noise, keep_mask, up_vector


def session_thrust(
    levels: Sequence[float], hold_s: float | Sequence[float], rest_s: float = 2.0
) -> Thrust:
    """A session's thrust: rest, then each level held in turn (changes while moving).

    Parameters
    ----------
    levels : sequence of float
        The signed thrust levels (N, up positive), in order; 0 is a release.
    hold_s : float or sequence of float
        How long each level is held (s): one value for all or one per level.
    rest_s : float
        Rest before the first change (s).

    Returns
    -------
    Thrust
        Piecewise constant, 0 before ``rest_s``.
    """
    holds = np.broadcast_to(np.asarray(hold_s, dtype=float), (len(levels),))
    starts = rest_s + np.concatenate([[0.0], np.cumsum(holds)[:-1]])
    return Thrust(starts, np.asarray(levels, dtype=float))


def guided_move_thrust(
    peak_N: float = 4.0, move_s: float = 6.0, rest_s: float = 2.0, rate_hz: float = 200.0
) -> Thrust:
    """A person guiding the load: a smooth push, then a smooth pull back to a stop.

    ``u(t) = peak * sin(2 pi s) * sin(pi s)`` for ``s = (t - rest_s) / move_s`` in [0, 1]:
    no step anywhere, the force rises and falls continuously (the paper's human assist).

    Parameters
    ----------
    peak_N : float
        Scale of the force (N); the push is up for a positive value.
    move_s : float
        Duration of the move (s).
    rest_s : float
        Rest before the move (s).
    rate_hz : float
        Resolution of the series (Hz).

    Returns
    -------
    Thrust
        A series sampled at ``rate_hz``, 0 outside the move.
    """
    t = rest_s + np.arange(round(move_s * rate_hz) + 1) / rate_hz
    s = (t - rest_s) / move_s
    u = peak_N * np.sin(2 * np.pi * s) * np.sin(np.pi * s)
    u[-1] = 0.0
    return Thrust.series(t, u)


def record(
    model: Model,
    params: Mapping[str, float],
    thrust: Thrust,
    duration_s: float,
    *,
    sensor: SensorSettings | None = None,
    name: str = "Run #1",
    seed: int = 0,
) -> Recording:
    """Simulate ``thrust`` from rest and record it as the sensor would.

    Parameters
    ----------
    model : Model
        The true model.
    params : mapping of str to float
        True parameter values (defaults for the rest).
    thrust : Thrust
        The operating thrust ``u(t)`` (N, up positive).
    duration_s : float
        Length of the recording from t = 0 (s).
    sensor : SensorSettings, optional
        Noise, quantization, tilt, drop-outs, force mounting.
    name : str
        Name of the run.
    seed : int
        Seed of every random choice.

    Returns
    -------
    Recording
        Force (``force_offset + force_sign * u`` plus noise) and 3-axis specific force.
    """
    sensor = sensor or SensorSettings()
    rng = np.random.default_rng(seed)
    dt = 1.0 / sensor.rate_hz
    n = round(duration_s / dt) + 1
    time = np.arange(n) * dt
    azimuth = (
        float(rng.uniform(0, 360)) if sensor.tilt_azimuth_deg is None else sensor.tilt_azimuth_deg
    )
    up = up_vector(sensor.tilt_deg, azimuth)
    sim = simulate(model, params, time, thrust)
    specific = (sim.accel + sensor.g)[:, None] * up[None, :]
    accel = specific + ar1_noise(rng, sensor.accel_noise, sensor.noise_correlation, specific.shape)
    force = sensor.force_offset + sensor.force_sign * sim.operating_force
    force = force + rng.normal(0.0, sensor.force_noise, force.shape)
    if sensor.quantize:
        accel = np.round(accel / ACCEL_RESOLUTION) * ACCEL_RESOLUTION
        force = np.round(force / FORCE_RESOLUTION_N) * FORCE_RESOLUTION_N
    keep = keep_mask(n, sensor.drop_fraction, rng)
    return Recording(
        name=name,
        time=time[keep],
        force=force[keep],
        accel=accel[keep],
        accel_includes_gravity=True,
        accel_axes=("x", "y", "z"),
        sample_rate_hz=sensor.rate_hz,
    )


def write_recordings(path: str | Path, recordings: Sequence[Recording]) -> None:
    """Write recordings as a PASCO Capstone CSV (whole or not at all; never overwrites).

    Parameters
    ----------
    path : str or Path
        The CSV file to write.
    recordings : sequence of Recording
        The runs, in order.
    """
    from balancer_id.read.writers import write_log

    write_log(Path(path), list(recordings), "pasco-capstone", overwrite=False)
