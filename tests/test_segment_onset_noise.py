"""An onset must stand out of the noise measured on the log; none in steady travel (issue
19.4); a drop-out inside a motion starts no phantom onset (issue 17.6).

Elevator rides (accelerate, cruise, decelerate) are simulated at several rates, noise
levels, travel vibrations (sway of 20-150 ms correlation time, up to 3x the resting
noise) and accelerations (0.5-1.2 m/s^2), with and without gravity in the data: the two
thrust changes are the start and the braking; the end of the acceleration (the cruise
speed reached) and anything in the cruise are no onset. The real rides of
``../shared/real_logs`` are held to the same rule. Over 40 seeds of this generator the
detector finds the two onsets in all 40 (before issue 19.4: in 20; 3 to 6 in the others).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_real_logs_public import REAL_LOGS
from test_segment_synth import make_log, make_recording, synth_run

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import LogReadError
from balancer_id.read.recording import Recording
from balancer_id.segment import find_trials
from balancer_id.segment.find import find_onsets


def _ramp(t: np.ndarray, t0: float, rise: float, hold: float, amp: float) -> np.ndarray:
    """A jerk-limited acceleration pulse: up over ``rise``, held, down over ``rise``."""
    up = np.clip((t - t0) / rise, 0.0, 1.0)
    down = np.clip((t - t0 - rise - hold) / rise, 0.0, 1.0)
    return amp * (0.5 - 0.5 * np.cos(np.pi * up)) * (1.0 - (0.5 - 0.5 * np.cos(np.pi * down)))


def elevator(seed: int) -> tuple[Recording, list[float]]:
    """A seeded elevator ride and its two thrust changes (start, braking)."""
    rng = np.random.default_rng(seed)
    rate = float(rng.choice([100.0, 200.0, 400.0]))
    t = np.arange(0.0, rng.uniform(30.0, 40.0), 1.0 / rate)
    amp = rng.uniform(0.5, 1.2) * rng.choice([-1.0, 1.0])
    rise, hold = rng.uniform(0.3, 0.8), rng.uniform(1.0, 2.5)
    start = rng.uniform(3.0, 6.0)
    brake = start + 2 * rise + hold + rng.uniform(6.0, 14.0)
    a = _ramp(t, start, rise, hold, amp) - _ramp(t, brake, rise, hold, amp)
    rest_noise = rng.uniform(0.02, 0.06)
    # travel sways and rattles: low-pass noise, stronger than at rest, while moving
    sway = np.zeros(t.size)
    e = rng.normal(0.0, 1.0, t.size)
    phi = np.exp(-1.0 / (rate * rng.uniform(0.02, 0.15)))
    for i in range(1, t.size):
        sway[i] = phi * sway[i - 1] + e[i]
    sway *= rng.uniform(1.0, 3.0) * rest_noise / np.std(sway)
    moving = (t > start) & (t < brake + 2 * rise + hold)
    vertical = a + np.where(moving, sway, 0.0) + rng.normal(0.0, rest_noise, t.size)
    with_g = bool(rng.uniform() < 0.5)
    tilt = np.radians(rng.uniform(0.0, 20.0))
    up = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    side = rng.normal(0.0, rest_noise, (t.size, 3))
    accel = (vertical + (G_DEFAULT if with_g else 0.0))[:, None] * up + side
    rec = Recording(
        name="Run 1",
        time=t,
        accel=accel,
        accel_includes_gravity=with_g,
        sample_rate_hz=rate,
    )
    return rec, [start, brake]


@pytest.mark.parametrize("seed", range(12))
def test_an_elevator_ride_has_two_onsets_none_in_steady_travel(seed):
    rec, truth = elevator(seed)
    try:
        trials = find_trials(make_log(rec), thrusts=[1.0, 1.0])
    except LogReadError as exc:  # another count: the message lists the onsets
        pytest.fail(f"seed {seed}: {exc}")
    for trial, t0 in zip(trials, truth, strict=True):
        assert abs(trial.t_step - t0) < 0.5, (trial.t_step, truth)


#: The real rides: (file, the onsets a right reading finds, in s).
REAL_RIDES = [
    ("public/phyphox_withg_elevator_400Hz_Polegatoo_Elevador.csv", [17.6, 31.2]),
    ("public/phyphox_withg_elevator_SuaTia_G_elev_predio_45.csv", [16.4, 29.9]),
    ("public/phyphox_linear_elevator_KN1GHTR1DER_Elevador.csv", [2.0, 15.9]),
]


@pytest.mark.needs_real_logs
@pytest.mark.parametrize(("name", "onsets"), REAL_RIDES)
def test_real_elevator_rides_have_no_onset_in_travel(name, onsets):
    from balancer_id.read import read_log

    path = Path(REAL_LOGS) / name
    if not path.is_file():
        pytest.skip("real_logs folder not present")
    trials = find_trials(read_log(path), thrusts=[1.0] * len(onsets))
    assert [t.t_step for t in trials] == pytest.approx(onsets, abs=0.3)


@pytest.mark.parametrize("seed", range(6))
def test_a_dropout_inside_a_motion_starts_no_phantom_onset(seed):
    """50-300 ms of missing samples anywhere inside a motion (after the onset, midway,
    just before or just after the catch), force and acceleration or acceleration alone:
    no onset is found that neither the log without the drop-out nor the truth has (issue
    17.6). Over 24 seeds x 240 drop-outs: 1 phantom in 1440 (before: 106 in 720 of 12
    seeds)."""
    rng = np.random.default_rng(700 + seed)
    groups = [[4.9], [-3.0], [2.45, 4.9], [-4.9]]
    with_force, with_g = bool(seed % 2), bool(seed % 3)
    rate = float(rng.choice([100.0, 200.0]))
    rec0, truth = synth_run(
        seed, groups, has_force=with_force, with_g=with_g, D=rng.uniform(0, 3), rate=rate
    )
    (reference,) = find_onsets(make_log(rec0)).values()
    for t_on in truth.onsets:
        catch = min(c for c in truth.catches if c > t_on)
        for gap in (0.05, 0.3):
            for lo in (t_on + 0.2, 0.5 * (t_on + catch), catch - gap - 0.1, catch + 0.1):
                keep = ~((rec0.time > lo) & (rec0.time < lo + gap))
                rec = make_recording(
                    rec0.time[keep],
                    None if rec0.force is None else rec0.force[keep],
                    rec0.accel[keep],
                    rate,
                    with_g=with_g,
                )
                (found,) = find_onsets(make_log(rec)).values()
                known = [*reference, *truth.onsets]  # a true change the gap revealed counts
                phantom = [t for t in found if not any(abs(t - r) < 0.3 for r in known)]
                assert not phantom, (
                    f"drop-out {gap} s at {lo:.2f} s (onset {t_on:.2f}, catch {catch:.2f}): "
                    f"onsets {np.round(found, 2)}, without it {np.round(reference, 2)}"
                )
