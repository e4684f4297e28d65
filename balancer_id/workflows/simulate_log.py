"""A synthetic log as one library call: the model, its values, the checks, the file.

``balancer-id simulate`` is this function::

    import balancer_id.workflows.simulate_log as sl
    sl.simulate_log("sim.csv", model="viscous", values={"m_a": 0.5}, thrusts=[2.45, -2.45])

Every value is checked before anything is simulated: beyond the physical ranges below a
log would hold inf/NaN samples or not fit in memory (issue 21: nothing silent).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from balancer_id.arguments import at_least, trajectory
from balancer_id.errors import UsageError
from balancer_id.files import check_outputs, inputs_of
from balancer_id.identify.params_file import params_model, read_params_file
from balancer_id.model.spec import resolve_model
from balancer_id.simulation.synth import SensorSettings, write_synthetic_log

__all__ = ["SimulatedLog", "check_ranges", "simulate_log"]

#: Physical ranges of the values: beyond them a log would hold inf/NaN samples.
MAX_THRUST_N = 1e6
MAX_ACCEL_NOISE = 1e3
MAX_RATE_HZ = 1e5
MAX_DURATION_S = 86400.0
#: More samples than this do not fit in memory.
MAX_SIM_SAMPLES = 5e7


@dataclass(frozen=True)
class SimulatedLog:
    """A synthetic log written, and what made it.

    Attributes
    ----------
    out : Path
        The CSV written.
    model : str
        The true model's spec.
    parameters : dict of str to float
        Every parameter's true value.
    thrusts : list of float
        One run per thrust (N).
    seed : int
        The seed of every random choice.
    runs : int
        The runs written.
    servo_delay_s : float
        The robot's servo acted this late (s; 0: at once).
    """

    out: Path
    model: str
    parameters: dict[str, float] = field(default_factory=dict)
    thrusts: list[float] = field(default_factory=list)
    seed: int = 0
    runs: int = 0
    servo_delay_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """The ``simulate --json`` object."""
        out = {
            "out": str(self.out),
            "model": self.model,
            "parameters": self.parameters,
            "thrusts": self.thrusts,
            "seed": self.seed,
        }
        if self.servo_delay_s:
            out["servo_delay_s"] = self.servo_delay_s
        return out


def check_ranges(
    thrusts: Sequence[float], sensor: SensorSettings, rest_s: float, duration_s: float
) -> None:
    """Refuse values out of their physical range, and logs too long to hold.

    Parameters
    ----------
    thrusts : sequence of float
        One run per thrust (N).
    sensor : SensorSettings
        Rate and noise.
    rest_s, duration_s : float
        Rest before each step and motion after it (s).

    Raises
    ------
    UsageError
        The first value out of range, named by its option.
    """
    if not thrusts:
        raise UsageError("--thrust: give at least one thrust")
    for name, low, high, what, value in [
        *(("--thrust", -MAX_THRUST_N, MAX_THRUST_N, "N", f) for f in thrusts),
        ("--noise", 0.0, MAX_ACCEL_NOISE, "m/s^2", sensor.accel_noise),
        ("--force-noise", 0.0, MAX_THRUST_N, "N", sensor.force_noise),
        ("--rate", 1e-9, MAX_RATE_HZ, "Hz", sensor.rate_hz),
        ("--rest", 0.0, MAX_DURATION_S, "s", rest_s),
        ("--duration", 1e-9, MAX_DURATION_S, "s", duration_s),
    ]:
        if not (math.isfinite(value) and low <= value <= high):
            raise UsageError(
                f"{name} {value:g}: give a finite value in {low:g}..{high:g} {what} (a log "
                "outside these would hold overflowing or unreadable samples)"
            )
    if sensor.rate_hz * (rest_s + duration_s) * len(thrusts) > MAX_SIM_SAMPLES:
        raise UsageError(
            f"--rate {sensor.rate_hz:g} x (--rest + --duration) x {len(thrusts)} runs is more "
            f"than {MAX_SIM_SAMPLES:.0e} samples; shorten the runs or lower the rate"
        )


def _check_sensor(sensor: SensorSettings, rest_s: float, duration_s: float) -> None:
    """Refuse a sensor or timing that cannot record (each message names its option)."""
    if sensor.force_sign not in (1, -1):
        raise UsageError("--force-sign must be +1 or -1")
    if not 0.0 <= sensor.noise_correlation < 1.0:
        raise UsageError("--noise-correlation must be in [0, 1)")
    if not (math.isfinite(sensor.rate_hz) and sensor.rate_hz > 0):
        raise UsageError(f"--rate {sensor.rate_hz}: give a sample rate > 0 Hz, e.g. 200")
    for option, value in (
        ("--noise", sensor.accel_noise), ("--force-noise", sensor.force_noise), ("--rest", rest_s)
    ):
        at_least(value, 0.0, option)
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise UsageError(f"--duration {duration_s}: give the motion's length in s (> 0)")
    drop = sensor.drop_fraction
    if not (math.isfinite(drop) and 0.0 <= drop < 1.0):
        raise UsageError(f"--drop {drop}: give the fraction of samples dropped, in [0, 1)")
    if not math.isfinite(sensor.tilt_deg):
        raise UsageError(f"--tilt {sensor.tilt_deg}: give the sensor's tilt in degrees")


#: Longest servo delay ``simulate`` writes (s): beyond it no robot loop is stable.
MAX_SERVO_DELAY_S = 1.0


def _check_servo_delay(delay: float, model: Any, thrusts: Sequence[float]) -> None:
    """Refuse a servo delay the delayed loop does not simulate (exit 2, one line)."""
    if delay == 0:
        return
    from balancer_id.simulation.delayed_servo import SUPPORTED_EFFECTS

    if not 0 < delay <= MAX_SERVO_DELAY_S:
        raise UsageError(
            f"--servo-delay {delay:g}: give a delay in seconds in 0 .. {MAX_SERVO_DELAY_S:g}"
        )
    names = {e.name for e in model.effects}
    if "servo" not in names or not names <= SUPPORTED_EFFECTS:
        raise UsageError(
            f"--servo-delay applies to a robot's servo with at most a viscosity "
            f"(e.g. --model variable_viscosity+servo), not to {model.spec}"
        )
    if any(float(f) != 0.0 for f in thrusts):
        raise UsageError("--servo-delay: a robot move carries no thrust step; give --thrust 0")


def simulate_log(
    out: str | Path,
    *,
    model: str | None = None,
    values: Mapping[str, float] | None = None,
    params: str | Path | None = None,
    thrusts: Sequence[float] = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35),
    sensor: SensorSettings | None = None,
    rest_s: float = 2.0,
    duration_s: float = 8.0,
    trajectory_text: str | None = None,
    seed: int = 0,
    effects_files: Sequence[str | Path] = (),
    overwrite: bool = False,
    servo_delay_s: float = 0.0,
) -> SimulatedLog:
    """Check everything, simulate one run per thrust and write a PASCO Capstone CSV.

    Parameters
    ----------
    out : str or Path
        The CSV to write (whole or not at all; never an input).
    model : str, optional
        The true model (default: the model of ``params``, else ``variable_viscosity``).
    values : mapping of str to float, optional
        True values (``--param``); they win over ``params``'.
    params : str or Path, optional
        The JSON of ``fit --save`` (or ``--json``): its model and values (issue 11).
    thrusts : sequence of float
        One run per thrust (N).
    sensor : SensorSettings, optional
        Rate, noise, tilt, drop-outs, force sign.
    rest_s, duration_s : float
        Rest before each step and motion after it (s).
    trajectory_text : str, optional
        A robot's reference move (``trapezoid:...`` or a CSV of time,position).
    seed : int
        The seed of every random choice (>= 0).
    effects_files : sequence of path
        User effect files the model may name.
    overwrite : bool
        Replace ``out`` when it exists.
    servo_delay_s : float
        The robot's servo acts this late (s, ``--servo-delay``): the servo with a
        viscosity only, robot moves only (thrust 0).

    Returns
    -------
    SimulatedLog

    Raises
    ------
    UsageError
        A value out of range or an output that may not be written (before any work).
    """
    sensor = sensor or SensorSettings()
    known: dict[str, float] = {}
    if params is not None:
        model = params_model(params, model)
        names = resolve_model(model, effects_files).param_names
        known = {k: v for k, v in read_params_file(params).items() if k in names}
    mdl = resolve_model(model, effects_files)
    true_values = mdl.resolve({**known, **(values or {})})
    thrusts = list(thrusts)
    check_ranges(thrusts, sensor, rest_s, duration_s)
    if seed < 0:
        raise UsageError(f"--seed {seed}: give a seed >= 0")
    move = trajectory(trajectory_text)
    mdl.require_reference_move(move)
    _check_servo_delay(servo_delay_s, mdl, thrusts)
    _check_sensor(sensor, rest_s, duration_s)
    inputs = inputs_of([], effects_files, trajectory_text) + ([params] if params else [])
    check_outputs({"--out": out}, inputs, overwrite)
    recs = write_synthetic_log(
        out, mdl, true_values, thrusts, sensor=sensor, rest_s=rest_s, duration_s=duration_s,
        trajectory=move, seed=seed, overwrite=overwrite, servo_delay_s=servo_delay_s,
    )
    return SimulatedLog(
        Path(out), mdl.spec, dict(true_values), thrusts, seed, len(recs), servo_delay_s
    )
