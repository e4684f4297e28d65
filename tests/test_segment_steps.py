"""Thrust steps from the force channel: onsets, thrusts, directions, windows, errors.

Tolerances. The force noise (0.05 N) is 30 times smaller than the smallest step (1.5 N),
so the least-squares change point lands on the first sample after the true onset, or
the one before when noise tips it: within 2 samples (1 sample plus the 0.2-sample time
jitter). The thrust is a difference of two trimmed means of >= 50 samples with 0.05 N
noise, 0.03 N quantization and drift of a few mN/s: within 0.05 N + 1 %.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from test_segment_synth import make_log, make_recording, synth_run

from balancer_id.errors import NoTrialError, UsageError
from balancer_id.segment import find_trials

ONSET_SAMPLES = 2.0


def _config(seed: int, n: int = 3, chain: bool = False) -> tuple[list[list[float]], dict]:
    """Random thrusts (+-1.5..10 N), m_a 8-30 kg, T_a 0.15-0.6 s, tilt, rate, mounting."""
    r = np.random.default_rng(1000 + seed)

    def thrust() -> float:
        return float(r.choice([-1, 1]) * r.uniform(1.5, 10.0))

    groups = []
    for _ in range(n):
        first = thrust()
        # a chained step adds weight while moving, or takes part of it off
        groups.append(
            [first, first * r.uniform(-0.5, 1.0)] if chain and r.random() < 0.5 else [first]
        )
    groups = [[g for g in grp if abs(g) >= 1.5] for grp in groups]
    kw = dict(
        m_a=r.uniform(8, 30),
        T_a=r.uniform(0.15, 0.6),
        D=float(r.choice([0.0, r.uniform(0, 10)])),
        tilt_deg=r.uniform(0, 30),
        rate=float(r.choice([100.0, 200.0])),
        mount=int(r.choice([-1, 1])),
    )
    return groups, kw


def _check(trials, truth, rate, *, onset_samples=ONSET_SAMPLES):
    assert len(trials) == len(truth.onsets), [t.t_step for t in trials]
    for tr, t0, f in zip(trials, truth.onsets, truth.thrusts, strict=True):
        assert abs(tr.t_step - t0) * rate <= onset_samples
        assert tr.change_N == pytest.approx(f, abs=0.05 + 0.01 * abs(f))
        if not tr.continues:  # a step from rest: its level is its change
            assert tr.thrust_N == tr.change_N
        assert tr.direction == ("up" if tr.thrust_N > 0 else "down")
        assert tr.t_start < tr.t_step < tr.t_end
        assert tr.time.size == tr.accel.size == tr.force.size


@pytest.mark.parametrize("seed", range(4))
def test_clean_steps_are_found_within_two_samples(seed):
    groups, kw = _config(seed)
    rec, truth = synth_run(seed, groups, noise=False, quantize=False, drift=False, **kw)
    trials = find_trials(make_log(rec))
    _check(trials, truth, kw["rate"])
    assert [t.index for t in trials] == [0, 1, 2]


@pytest.mark.parametrize("seed", range(12))
def test_noisy_quantized_tilted_steps_over_many_settings(seed):
    groups, kw = _config(seed)
    rec, truth = synth_run(seed, groups, **kw)
    trials = find_trials(make_log(rec))
    _check(trials, truth, kw["rate"])
    # each window ends where the person catches the load (not later, not long before)
    for tr, catch in zip(trials, truth.catches, strict=True):
        assert tr.end_reason == "catch"
        assert -0.5 < tr.t_end - catch < 0.05


@pytest.mark.parametrize("seed", range(6))
def test_steps_taken_while_moving_end_the_trial_before(seed):
    groups, kw = _config(seed, chain=True)
    rec, truth = synth_run(seed, groups, **kw)
    trials = find_trials(make_log(rec))
    _check(trials, truth, kw["rate"])
    k = 0
    for grp in groups:
        for j in range(len(grp) - 1):
            assert trials[k + j].end_reason == "next step"
            assert trials[k + j].t_end < trials[k + j + 1].t_step
        k += len(grp)


def test_trial_signals_are_aligned_so_that_up_is_positive():
    rec, truth = synth_run(21, [[4.9], [-7.35]], mount=-1, tilt_deg=20.0)
    trials = find_trials(make_log(rec, path="logs/run.csv"))
    for tr, f in zip(trials, truth.thrusts, strict=True):
        after = tr.time > tr.t_step + 0.3
        assert np.median(tr.force[after]) == pytest.approx(f, abs=0.1)
        assert np.sign(np.mean(tr.accel[after])) == np.sign(f)
        assert abs(np.median(tr.force[tr.time < tr.t_step])) < 0.05
        assert tr.source == "logs/run.csv"
        assert tr.recording == "Run 1"


def test_long_rests_gaps_and_several_runs():
    # minutes of rest, dropped samples (gaps) in the rests, two runs: indices run on
    runs = [
        synth_run(31, [[2.45], [-4.9]], first_rest=120.0, rest=(40.0, 60.0), n_gaps=3),
        synth_run(32, [[7.35]], rate=100.0, n_gaps=2, name="Run 2"),
    ]
    assert all(rec.gaps for rec, _ in runs)
    trials = find_trials(make_log(*(rec for rec, _ in runs)))
    assert [t.index for t in trials] == [0, 1, 2]
    assert [t.recording for t in trials] == ["Run 1", "Run 1", "Run 2"]
    _check(trials[:2], runs[0][1], 200.0)
    _check(trials[2:], runs[1][1], 100.0)


def test_a_gap_ends_the_window():
    rec, truth = synth_run(33, [[4.9]], motion=(4.0, 4.0), noise=False, quantize=False)
    cut = (rec.time > truth.onsets[0] + 2.0) & (rec.time < truth.onsets[0] + 2.5)
    holed = make_recording(rec.time[~cut], rec.force[~cut], rec.accel[~cut], 200.0)
    (trial,) = find_trials(make_log(holed))
    assert trial.end_reason == "gap"
    assert trial.t_end == pytest.approx(truth.onsets[0] + 2.0, abs=0.01)


def test_a_few_dropped_samples_are_bridged_with_a_note():
    rec, truth = synth_run(34, [[4.9]], motion=(4.0, 4.0), noise=False, quantize=False)
    cut = np.zeros(rec.n_samples, dtype=bool)
    cut[np.searchsorted(rec.time, truth.onsets[0] + 1.0) + np.arange(3)] = True
    holed = make_recording(rec.time[~cut], rec.force[~cut], rec.accel[~cut], 200.0)
    (trial,) = find_trials(make_log(holed))
    assert trial.end_reason == "catch"
    assert "1 short gap(s) inside (3 samples missing)" in trial.notes


def test_force_sign_fixes_the_direction_and_given_thrusts_replace_the_magnitudes():
    rec, _ = synth_run(41, [[4.9], [-2.45]], mount=-1)
    trials = find_trials(make_log(rec), force_sign=-1, thrusts=[5.0, 2.5])
    assert [t.thrust_N for t in trials] == [5.0, -2.5]
    assert [t.direction for t in trials] == ["up", "down"]
    # the wrong force sign is believed: it is the user's statement
    flipped = find_trials(make_log(rec), force_sign=1)
    assert [t.direction for t in flipped] == ["down", "up"]
    # a given negative thrust that disagrees with the motion is kept, with a warning
    noted = find_trials(make_log(rec), thrusts=[-5.0, -2.5])
    assert noted[0].thrust_N == -5.0 and noted[0].direction == "down"
    assert any(n.startswith("warning:") and "motion" in n for n in noted[0].notes)


def test_thrust_count_mismatch_is_a_usage_error():
    rec, _ = synth_run(42, [[4.9], [-2.45]])
    with pytest.raises(UsageError, match=r"3 thrust\(s\) given but .* holds 2 step") as err:
        find_trials(make_log(rec), thrusts=[1.0, 2.0, 3.0])
    assert err.value.exit_code == 2  # the option's value is wrong, not the log


def test_bad_arguments_are_usage_errors():
    rec, _ = synth_run(43, [[4.9]])
    for kwargs in ({"force_sign": 2}, {"thrusts": [0.0]}, {"min_step_N": -1.0}, {"vertical": "q"}):
        with pytest.raises(UsageError):
            find_trials(make_log(rec), **kwargs)


def test_rest_only_log_raises_no_trial_error_saying_why():
    rec, _ = synth_run(44, [], first_rest=60.0)
    with pytest.raises(NoTrialError, match="no step trial found") as err:
        find_trials(make_log(rec, path="rest.csv"))
    assert "rest.csv" in str(err.value) and "largest force change" in str(err.value)
    assert err.value.exit_code == 4


@pytest.mark.parametrize("seed", range(10))
def test_no_false_trial_on_rest_noise_and_drift(seed):
    r = np.random.default_rng(seed)
    rec, _ = synth_run(
        seed, [], first_rest=r.uniform(60, 180), tilt_deg=r.uniform(0, 60), rate=200.0
    )
    with pytest.raises(NoTrialError):
        find_trials(make_log(rec))


def test_steps_below_min_step_are_ignored_and_a_step_without_motion_is_no_trial():
    rec, _ = synth_run(45, [[4.9], [2.45]])
    assert len(find_trials(make_log(rec), min_step_N=3.0)) == 1
    # a force step while the load is held (no motion follows) is not a trial
    held = make_recording(rec.time, rec.force, np.tile(rec.accel[:1], (rec.n_samples, 1)), 200.0)
    with pytest.raises(NoTrialError, match="no motion followed"):
        find_trials(make_log(held))


@pytest.mark.parametrize("seed", range(3))
def test_force_only_log_takes_the_direction_from_the_force_sign(seed):
    groups, kw = _config(seed)
    rec, truth = synth_run(seed, groups, has_accel=False, **kw)
    trials = find_trials(make_log(rec), force_sign=kw["mount"])
    assert len(trials) == len(truth.onsets)
    for tr, t0, f in zip(trials, truth.onsets, truth.thrusts, strict=True):
        assert abs(tr.t_step - t0) * kw["rate"] <= ONSET_SAMPLES
        assert tr.change_N == pytest.approx(f, abs=0.05 + 0.01 * abs(f))
        assert np.isnan(tr.accel).all() and "no acceleration channel" in tr.notes
    assert all("assumed" not in n for t in trials for n in t.notes)
    unsigned = find_trials(make_log(rec))
    assert all(any("force sign +1 assumed" in n for n in t.notes) for t in unsigned)


def test_linear_acceleration_sign_is_fixed_by_the_force_sign():
    rec, truth = synth_run(46, [[4.9], [-6.0], [3.0]], with_g=False, tilt_deg=15.0, mount=-1)
    trials = find_trials(make_log(rec), force_sign=-1)
    _check(trials, truth, 200.0)
    assert all(
        np.sign(np.mean(t.accel[t.time > t.t_step + 0.5])) == np.sign(t.thrust_N) for t in trials
    )


@pytest.mark.parametrize("rate", [50.0, 200.0])
def test_a_log_starting_just_before_its_step_says_the_rest_is_too_short(rate):
    """A log that starts 50 ms before its only step has no rest to read the zeros from:
    the refusal says so, with how long the rest is and how long it needs to be."""
    rec, _ = synth_run(46, [[4.9]], first_rest=0.05, rate=rate)
    with pytest.raises(NoTrialError, match="starts too soon before its steps") as err:
        find_trials(make_log(rec, path="late_start.csv"))
    text = str(err.value)
    assert "late_start.csv" in text and err.value.exit_code == 4
    # the onset lands on a sample 0.05-0.08 s in (the synthetic clock jitters)
    assert re.search(r"rest before the step 0\.0[5-8]\d* s long \(from the run's start\)", text)
    assert "under the 0.12 s a step needs" in text
    # with that much rest the same step is a trial
    rec, _ = synth_run(46, [[4.9]], first_rest=0.2, rate=rate)
    assert len(find_trials(make_log(rec))) == 1
