"""Synthetic logs: what a PASCO sensor on the load would have recorded.

One run per thrust: rest, a thrust step, the motion. The accelerometer reads specific
force (``+g`` up at rest) in a tilted sensor frame; force and acceleration get seeded
noise and optional quantization; wireless drop-outs remove samples (never filled in).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from balancer_id.constants import ACCEL_RESOLUTION, FORCE_RESOLUTION_N, G_DEFAULT
from balancer_id.model.spec import Model
from balancer_id.read.recording import Recording
from balancer_id.simulation.engine import TrialInput, simulate_many
from balancer_id.simulation.inputs import Thrust, Trapezoid


@dataclass(frozen=True)
class SensorSettings:
    """How the simulated sensor records.

    Attributes
    ----------
    rate_hz : float
        Sample rate.
    accel_noise, force_noise : float
        Standard deviation of the noise (m/s^2, N).
    noise_correlation : float
        Lag-one correlation of the acceleration noise (0 = white; a sensor's internal
        low-pass filter makes it positive): AR(1) noise with the same standard deviation.
    quantize : bool
        Round to the sensor's resolution (0.2 m/s^2, 0.03 N).
    tilt_deg : float
        Angle between the sensor's z axis and the vertical (degrees).
    tilt_azimuth_deg : float or None
        Direction of the tilt; None draws it from the seed.
    drop_fraction : float
        Fraction of samples lost in wireless drop-outs (bursts of 1-5 samples).
    force_sign : int
        +1 when the force channel's change equals the thrust (sensor in tension under the
        load), -1 for the opposite mounting.
    force_offset : float
        Reading of the force channel before the step (N).
    g : float
        Gravity (m/s^2).
    """

    rate_hz: float = 200.0
    accel_noise: float = 0.03
    noise_correlation: float = 0.0
    force_noise: float = 0.03
    quantize: bool = False
    tilt_deg: float = 10.0
    tilt_azimuth_deg: float | None = None
    drop_fraction: float = 0.0
    force_sign: int = 1
    force_offset: float = 0.0
    g: float = G_DEFAULT


def up_vector(tilt_deg: float, azimuth_deg: float) -> np.ndarray:
    """The vertical (up) direction in the sensor frame of a sensor tilted by ``tilt_deg``.

    Parameters
    ----------
    tilt_deg : float
        Angle between the sensor's z axis and the vertical (degrees).
    azimuth_deg : float
        Direction of the tilt in the sensor's x-y plane, from the x axis (degrees).

    Returns
    -------
    numpy.ndarray
        Unit vector, shape ``(3,)``.
    """
    th, ph = np.radians(tilt_deg), np.radians(azimuth_deg)
    return np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])


def synthetic_recordings(
    model: Model,
    params: Mapping[str, float],
    thrusts: Sequence[float],
    *,
    sensor: SensorSettings | None = None,
    rest_s: float = 2.0,
    duration_s: float = 8.0,
    trajectory: Trapezoid | None = None,
    seed: int = 0,
    servo_delay_s: float = 0.0,
) -> list[Recording]:
    """Simulate one run per thrust and record it as the sensor would.

    Parameters
    ----------
    model : Model
        The true model.
    params : mapping
        True parameter values (defaults for the rest).
    thrusts : sequence of float
        Signed thrust of each run (N, up positive).
    sensor : SensorSettings, optional
        Noise, quantization, tilt, drop-outs.
    rest_s : float
        Rest before the step (s): the sample at ``rest_s`` is the first to read the step,
        which happens half a sample before it (between two samples, as a real one does).
    duration_s : float
        Recording after the step (s).
    trajectory : Trapezoid, optional
        A robot's reference move (``servo``), relative to each run's start.
    seed : int
        Seed of every random choice.
    servo_delay_s : float
        The robot's servo acts this late (s; ``servo`` with a viscosity only, see
        :mod:`~balancer_id.simulation.delayed_servo`); 0 is the model as it stands.

    Returns
    -------
    list of Recording
        One per thrust, named ``Run #1``, ``Run #2``, ...

    Raises
    ------
    ValueError
        When ``servo_delay_s`` is given for a model or move it does not apply to.
    """
    sensor = sensor or SensorSettings()
    rng = np.random.default_rng(seed)
    dt = 1.0 / sensor.rate_hz
    n = round((rest_s + duration_s) / dt) + 1
    time = np.arange(n) * dt
    azimuth = (
        float(rng.uniform(0, 360)) if sensor.tilt_azimuth_deg is None else sensor.tilt_azimuth_deg
    )
    up = up_vector(sensor.tilt_deg, azimuth)
    inputs = []
    for f_in in thrusts:
        z_ref = v_ref = None
        if trajectory is not None:
            z_ref, v_ref = trajectory.evaluate(time)
        # the step happens between two samples (halfway: where a real one is on average),
        # so the sample at rest_s is the first to read it, as a sensor's would
        onset = rest_s - 0.5 * dt if trajectory is None else rest_s
        inputs.append(TrialInput(time, Thrust.step(onset, float(f_in)), z_ref, v_ref))
    sims = settled_simulation(model, params, inputs, dt)
    if servo_delay_s > 0 and any(float(f) != 0.0 for f in thrusts):
        raise ValueError("a servo delay applies to robot moves, which carry no thrust step")
    delayed = (
        _delayed_runs(model, params, inputs, servo_delay_s, trajectory)
        if servo_delay_s > 0
        else None
    )
    recordings = []
    for k, sim in enumerate(sims):
        sim_accel, sim_force = (
            (sim.accel, sim.operating_force) if delayed is None else delayed[k]
        )
        specific = (sim_accel + sensor.g)[:, None] * up[None, :]
        accel = specific + ar1_noise(
            rng, sensor.accel_noise, sensor.noise_correlation, specific.shape
        )
        force = sensor.force_offset + sensor.force_sign * sim_force
        force = force + rng.normal(0.0, sensor.force_noise, force.shape)
        if sensor.quantize:
            accel = np.round(accel / ACCEL_RESOLUTION) * ACCEL_RESOLUTION
            force = np.round(force / FORCE_RESOLUTION_N) * FORCE_RESOLUTION_N
        keep = keep_mask(n, sensor.drop_fraction, rng)
        recordings.append(
            Recording(
                name=f"Run #{k + 1}",
                time=time[keep],
                force=force[keep],
                accel=accel[keep],
                accel_includes_gravity=True,
                accel_axes=("x", "y", "z"),
                sample_rate_hz=sensor.rate_hz,
            )
        )
    return recordings


def _delayed_runs(
    model: Model,
    params: Mapping[str, float],
    inputs: Sequence[TrialInput],
    tau_r: float,
    move: Trapezoid | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Acceleration and servo force of each robot move with the servo ``tau_r`` late."""
    from balancer_id.simulation.delayed_servo import (
        LANE_PARAMS,
        SUPPORTED_EFFECTS,
        simulate_delayed_servo,
    )

    names = {e.name for e in model.effects}
    if "servo" not in names or not names <= SUPPORTED_EFFECTS:
        raise ValueError(
            "a servo delay applies to the servo with at most a viscosity "
            f"({', '.join(sorted(SUPPORTED_EFFECTS))}), not to {model.spec}"
        )
    values = {**model.resolve(params), "tau_r": float(tau_r)}
    lane = np.array([float(values.get(n, 0.0)) for n in LANE_PARAMS])
    out = []
    for inp in inputs:
        if inp.z_ref is None or inp.v_ref is None:
            raise ValueError("a servo delay needs the robot's reference move (--trajectory)")
        a, h, _ = simulate_delayed_servo(
            inp.time, inp.z_ref, inp.v_ref, lane,
            reference=None if move is None else move.evaluate,
        )  # fmt: skip
        out.append((a[0], h[0]))
    return out


#: RK4 steps are taken this fine against the fastest time constant of the model (RK4
#: is stable below about 2.8 and accurate to 1e-4 of a step response below 0.5).
STEP_OF_FASTEST = 0.25

#: Most RK4 steps per sample interval a simulated log takes before it refuses.
MAX_SUBSTEPS = 4096


def fastest_rate(model: Model, params: Mapping[str, float]) -> float:
    """The model's fastest rate (1/s) at ``params``: its shortest positive lag, its
    viscosity over its mass, a servo's natural frequency.

    Parameters
    ----------
    model : Model
        The model.
    params : mapping of str to float
        Every parameter's value.

    Returns
    -------
    float
        0 when the model has none of these.
    """
    full = model.resolve(dict(params))
    rates = [1.0 / full[n] for n in model.drive_lag_names if full.get(n, 0.0) > 0]
    m_a = float(full.get("m_a", 1.0))
    if m_a > 0:
        for name in ("D0", "c_r"):
            if full.get(name, 0.0) > 0:
                rates.append(float(full[name]) / m_a)
        if full.get("k_r", 0.0) > 0:
            rates.append(float(np.sqrt(full["k_r"] / m_a)))
    return max(rates, default=0.0)


def settled_simulation(
    model: Model, params: Mapping[str, float], inputs: Sequence[TrialInput], dt: float
) -> list:
    """Simulate ``inputs`` with RK4 steps fine enough for the model's fastest rate.

    Parameters
    ----------
    model : Model
        The model.
    params : mapping of str to float
        Its values.
    inputs : sequence of TrialInput
        The runs.
    dt : float
        The sample interval (s).

    Returns
    -------
    list of Simulation

    Raises
    ------
    UsageError
        When even :data:`MAX_SUBSTEPS` steps per sample leave a non-finite or diverging
        acceleration: no diverged log is ever written.
    """
    from balancer_id.errors import UsageError

    rate = fastest_rate(model, params)
    substeps = int(np.clip(np.ceil(dt * rate / STEP_OF_FASTEST), 1, MAX_SUBSTEPS))
    sims = simulate_many(model, params, inputs, substeps=substeps)
    bad = [k for k, sim in enumerate(sims) if not _settled(sim.accel)]
    if bad:
        raise UsageError(
            f"the simulation of '{model.spec}' diverges at these values (run {bad[0] + 1}: "
            f"acceleration not finite or growing without bound, with {substeps} RK4 steps "
            f"per sample of {dt * 1e3:.3g} ms); give gentler values (a longer lag, a "
            "smaller viscosity or stiffness for the mass) or check the effect's terms"
        )
    return sims


def _settled(accel: np.ndarray) -> bool:
    """Whether a simulated acceleration is finite and not growing without bound (its
    last second's peak no more than 1e3 times the whole run's median magnitude plus
    1 m/s^2)."""
    if not np.all(np.isfinite(accel)):
        return False
    mag = np.abs(accel)
    tail = mag[-max(mag.size // 10, 1) :]
    return bool(np.max(tail) <= 1e3 * (np.median(mag) + 1.0) and np.max(mag) < 1e9)


def keep_mask(n: int, drop_fraction: float, rng: np.random.Generator) -> np.ndarray:
    """Samples kept after wireless drop-outs: bursts of 1-5 samples, first and last kept.

    Terminates for any fraction: at most ``4 n`` bursts are drawn, and what the bursts
    leave short of the target is dropped sample by sample.

    Parameters
    ----------
    n : int
        Number of samples.
    drop_fraction : float
        Fraction of them to drop (0 keeps all).
    rng : numpy.random.Generator
        The random source.

    Returns
    -------
    numpy.ndarray
        One bool per sample: True where it is kept.
    """
    keep = np.ones(n, dtype=bool)
    if not drop_fraction > 0 or n < 8:
        return keep
    target = min(int(min(drop_fraction, 1.0) * n), n - 2)
    dropped = 0
    for _ in range(4 * n):
        if dropped >= target:
            break
        start = int(rng.integers(1, n - 6))
        burst = keep[start : start + int(rng.integers(1, 6))]
        dropped += int(burst.sum())
        burst[:] = False
    if dropped < target:
        inner = np.flatnonzero(keep[1:-1]) + 1
        keep[rng.choice(inner, min(target - dropped, inner.size), replace=False)] = False
    return keep


def write_synthetic_log(
    path: str | Path,
    model: Model,
    params: Mapping[str, float],
    thrusts: Sequence[float],
    *,
    sensor: SensorSettings | None = None,
    rest_s: float = 2.0,
    duration_s: float = 8.0,
    trajectory: Trapezoid | None = None,
    seed: int = 0,
    overwrite: bool = False,
    servo_delay_s: float = 0.0,
) -> list[Recording]:
    """Simulate and write a PASCO Capstone CSV (what ``balancer-id simulate`` does).

    The file is written whole or not at all, and an existing file is only replaced with
    ``overwrite=True``.

    Parameters
    ----------
    path : str or Path
        The CSV file to write.
    model : Model
        The true model.
    params : mapping of str to float
        True parameter values (SI units); parameters not given take their defaults.
    thrusts : sequence of float
        Signed thrust of each run (N, up positive).
    sensor : SensorSettings, optional
        Noise, quantization, tilt, drop-outs; None uses the defaults.
    rest_s : float
        Rest before the step (s): the sample at ``rest_s`` is the first to read the step,
        which happens half a sample before it (between two samples, as a real one does).
    duration_s : float
        Recording after the step (s).
    trajectory : Trapezoid, optional
        A robot's reference move (``servo``), relative to each run's start.
    seed : int
        Seed of every random choice.
    overwrite : bool
        Replace an existing file; False refuses to.
    servo_delay_s : float
        The robot's servo acts this late (s); see :func:`synthetic_recordings`.

    Returns
    -------
    list of Recording
        What was written.

    Raises
    ------
    OutputExistsError
        When the file exists and ``overwrite`` is False.
    """
    from balancer_id.read.writers import write_log

    recordings = synthetic_recordings(
        model,
        params,
        thrusts,
        sensor=sensor,
        rest_s=rest_s,
        duration_s=duration_s,
        trajectory=trajectory,
        seed=seed,
        servo_delay_s=servo_delay_s,
    )
    write_log(Path(path), recordings, "pasco-capstone", overwrite=overwrite)
    return recordings


def ar1_noise(
    rng: np.random.Generator, sigma: float, rho: float, shape: tuple[int, ...]
) -> np.ndarray:
    """Noise of standard deviation ``sigma`` and lag-one correlation ``rho`` along axis 0.

    Parameters
    ----------
    rng : numpy.random.Generator
        The random source.
    sigma : float
        Standard deviation.
    rho : float
        Lag-one correlation along axis 0, in [0, 1).
    shape : tuple of int
        Shape of the noise array.

    Returns
    -------
    numpy.ndarray
    """
    white = rng.normal(0.0, sigma, shape)
    if rho == 0.0:
        return white
    from scipy.signal import lfilter

    first = white[:1]
    rest = lfilter(
        [np.sqrt(1.0 - rho**2)], [1.0, -rho], white[1:], axis=0, zi=rho * first[None, 0]
    )[0]
    return np.concatenate([first, rest])
