"""Logs without a force channel: onsets from the acceleration, thrusts given by the user.

Tolerance. Without the force step the onset is where a first-order rise starts, which
noise hides: with 0.05 m/s^2 noise and 0.2 m/s^2 quantization, over 25 seeds, the
error reached 0.19 s for a_zc = 0.2 m/s^2 and 0.09 s for 0.8 m/s^2 (0.12 s without
quantization at 0.2 m/s^2). Tests use a_zc >= 0.25 m/s^2 and allow 0.25 s; a clean
log is placed within 2 samples.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_segment_synth import make_log, synth_run

from balancer_id.errors import NoTrialError, UsageError
from balancer_id.segment import find_trials


def _config(seed: int) -> tuple[list[list[float]], dict]:
    r = np.random.default_rng(2000 + seed)
    m_a = r.uniform(8, 30)
    groups = [[float(r.choice([-1, 1]) * m_a * r.uniform(0.25, 0.8))] for _ in range(3)]
    kw = dict(
        m_a=m_a,
        T_a=r.uniform(0.15, 0.6),
        D=r.uniform(0, 3),
        tilt_deg=r.uniform(0, 30),
        rate=float(r.choice([100.0, 200.0])),
        has_force=False,
    )
    return groups, kw


@pytest.mark.parametrize("seed", range(8))
def test_onsets_from_the_acceleration_with_given_thrusts(seed):
    groups, kw = _config(seed)
    rec, truth = synth_run(seed, groups, **kw)
    given = [abs(g[0]) for g in groups]
    trials = find_trials(make_log(rec), thrusts=given)
    assert len(trials) == 3
    for tr, t0, f in zip(trials, truth.onsets, truth.thrusts, strict=True):
        assert abs(tr.t_step - t0) < 0.25
        assert tr.thrust_N == pytest.approx(f)  # magnitude given, sign from the motion
        assert tr.force is None
    for tr, catch in zip(trials, truth.catches, strict=True):
        assert tr.end_reason == "catch"
        assert -0.5 < tr.t_end - catch < 0.05


def test_clean_acceleration_onsets_within_two_samples():
    groups, kw = _config(20)
    rec, truth = synth_run(20, groups, noise=False, quantize=False, drift=False, **kw)
    trials = find_trials(make_log(rec), thrusts=[abs(g[0]) for g in groups])
    errors = [abs(t.t_step - t0) * kw["rate"] for t, t0 in zip(trials, truth.onsets, strict=True)]
    assert max(errors) <= 2.0


def test_without_thrusts_the_onsets_are_reported():
    groups, kw = _config(1)
    rec, _ = synth_run(1, groups, **kw)
    with pytest.raises(NoTrialError, match="no force channel and no thrusts given") as err:
        find_trials(make_log(rec))
    assert "no step trial found" in str(err.value) and "3 onset(s)" in str(err.value)
    with pytest.raises(UsageError, match=r"2 thrust\(s\) given but .* holds 3 step"):
        find_trials(make_log(rec), thrusts=[1.0, 2.0])


@pytest.mark.parametrize("seed", range(4))
def test_no_false_trial_on_long_rest(seed):
    rec, _ = synth_run(seed, [], first_rest=240.0, tilt_deg=20.0 * seed, has_force=False)
    with pytest.raises(NoTrialError, match="largest acceleration departure"):
        find_trials(make_log(rec))


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_high_rate_log_gives_the_onsets_of_the_200hz_log(seed):
    """The same motion at 5 kHz and at 200 Hz: onsets agree within one 200 Hz sample.

    The generator draws the onsets with a sub-sample jitter that depends on the rate, so
    each onset is compared relative to its own truth. Sensor noise is left out (its
    realisation differs between the rates, and so would the onsets, by noise, not by
    rate); quantization and drift are kept.
    """
    groups, kw = _config(seed)
    found = {}
    for rate in (200.0, 5000.0):
        rec, truth = synth_run(seed, groups, noise=False, **{**kw, "rate": rate})
        trials = find_trials(make_log(rec), thrusts=[abs(g[0]) for g in groups])
        assert len(trials) == len(groups)
        found[rate] = np.array([t.t_step for t in trials]) - np.array(truth.onsets)
    assert np.max(np.abs(found[5000.0] - found[200.0])) <= 1.0 / 200.0


def _session_without_force(truth, levels, holds, seed, tilt):
    import dataclasses

    from simlib.sessions import record, session_thrust

    from balancer_id.model import parse_model
    from balancer_id.simulation.synth import SensorSettings

    holds = np.broadcast_to(np.asarray(holds, float), (len(levels),))
    rec = record(
        parse_model("variable_viscosity"), truth, session_thrust(levels, holds),
        2.0 + float(holds.sum()) + 1.0, sensor=SensorSettings(tilt_deg=tilt), seed=seed,
    )  # fmt: skip
    onsets = 2.0 + np.concatenate([[0.0], np.cumsum(holds)[:-1]])
    return make_log(dataclasses.replace(rec, force=None)), onsets


@pytest.mark.parametrize(
    ("truth", "levels", "holds", "seed"),
    [
        # the 70 s session of benchmarks/bench_sessions.py: six changes while moving
        ({"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4},
         [2.45, 4.9, -2.45, -4.9, 7.35, -7.35], 68.0 / 6, 1),
        # another balancer, levels and holds: nothing of the detector is tuned to the first
        ({"m_a": 26.4, "T_a": 0.48, "D0": 4.3, "A": 0.12},
         [9.46, -12.36, 10.31, 13.01, -6.58], [7.78, 7.48, 7.6, 7.21, 6.0], 0),
    ],
)  # fmt: skip
def test_thrust_changes_while_moving_are_found_from_the_acceleration(truth, levels, holds, seed):
    log, onsets = _session_without_force(truth, levels, holds, seed, tilt=14.0)
    trials = find_trials(log, thrusts=levels)
    assert len(trials) == len(levels)
    np.testing.assert_allclose([t.t_step for t in trials], onsets, atol=0.25)
    assert [t.direction for t in trials] == ["up" if x > 0 else "down" for x in levels]


@pytest.mark.parametrize("rate", [20.0, 50.0])
def test_caught_steps_at_low_rates_are_all_found(tmp_path, rate):
    """Two steps from rest, each caught by hand, tilted sensor, 0.05 m/s^2 noise, written
    as a generic CSV at 20 and 50 Hz (the lowest rates read): both steps are found, within
    two samples plus the noise tolerance of this file."""
    from balancer_id.trials import ReadOptions, read, segment

    rng = np.random.default_rng(7)
    t = np.arange(round(14.0 * rate)) / rate
    a_up = np.zeros(t.size)
    for t0, f in ((2.0, 4.9), (9.0, -4.9)):
        on = (t >= t0) & (t < t0 + 4.0)
        a_up[on] += f / 15.1 * -np.expm1(-(t[on] - t0) / 0.33)
        a_up[(t >= t0 + 4.0) & (t < t0 + 4.4)] -= 2.0 * np.sign(f)
    up = np.array([np.sin(np.radians(10.0)), 0.0, np.cos(np.radians(10.0))])
    accel = (9.8 + a_up)[:, None] * up[None, :] + rng.normal(0.0, 0.05, (t.size, 3))
    path = tmp_path / "low_rate.csv"
    np.savetxt(path, np.column_stack([t, accel]), delimiter=",", fmt="%.6g",
               header="time,ax,ay,az", comments="")  # fmt: skip
    options = ReadOptions(thrusts=[4.9, 4.9])
    trials = segment(read(path, options), options)
    assert [round(tr.thrust_N, 2) for tr in trials] == [4.9, -4.9]
    for tr, t0 in zip(trials, (2.0, 9.0), strict=True):
        assert abs(tr.t_step - t0) < 0.25 + 2 / rate
