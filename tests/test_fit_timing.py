"""The drive's timing at the optimum (issue 31): a late force channel is measured and
takes the trust of the values it moves; an on-time log keeps every value trusted."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from balancer_id.identify.api import fit
from balancer_id.model.spec import resolve_model
from balancer_id.read.writers import write_log
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings

TRUTH = {"m_a": 15.0, "T_a": 0.3, "D0": 60.0, "A": 0.05}


def _log(tmp_path, delay_s: float, truth: dict[str, float] = TRUTH) -> str:
    recs = synthetic_recordings(
        resolve_model("variable_viscosity"),
        truth,
        [8.0, -8.0, 16.0, -16.0],
        sensor=SensorSettings(rate_hz=200.0),
        duration_s=4.0,
        seed=3,
    )
    if delay_s:
        late = []
        for rec in recs:
            t = np.asarray(rec.time, dtype=float)
            f = np.interp(t - delay_s, t, np.asarray(rec.force, dtype=float))
            late.append(dataclasses.replace(rec, force=f))
        recs = late
    path = tmp_path / f"late_{delay_s * 1e3:.0f}ms_{truth['T_a'] * 1e3:.0f}.csv"
    write_log(path, recs, "pasco-capstone")
    return str(path)


def test_late_force_channel_is_measured_and_untrusts_what_it_moves(tmp_path) -> None:
    out = fit(_log(tmp_path, 0.040)).to_dict()
    lead, se = out["metrics"]["timing_lead_s"], out["metrics"]["timing_lead_stderr_s"]
    # the force 40 ms late: the acceleration leads it by about that (first order)
    assert lead == pytest.approx(0.040, abs=max(3 * se, 0.01))
    codes = [n["code"] for n in out["notes"] if n["severity"] == "error"]
    assert "fit.timing" in codes
    assert out["trusted"] is False
    # T_a absorbs the shift: it is not trusted, and says why
    t_a = out["parameters"]["T_a"]
    assert t_a["trusted"] is False
    assert any("timing" in why for why in t_a["untrusted_because"])


def test_late_force_channel_with_lag_on_its_floor_is_not_read_as_no_lag(tmp_path) -> None:
    # issue 31: a force channel 30 ms late on a balancer whose own lag is 30 ms: the fit
    # put T_a on the samples' floor ("T_a < 5 ms, no drive lag seen"), m_a 6 standard
    # errors high, all trusted; the first-order timing column (one spike per step) read
    # the lateness as 3 +- 1.5 ms. Measured whole (the output moved by whole leads) the
    # acceleration clearly leads the force, and no value bends unseen.
    out = fit(_log(tmp_path, 0.030, {**TRUTH, "T_a": 0.03})).to_dict()
    lead, se = out["metrics"]["timing_lead_s"], out["metrics"]["timing_lead_stderr_s"]
    assert lead > 3 * se and lead > 0.005
    assert out["trusted"] is False
    assert any(n["code"] == "fit.timing" and n["severity"] == "error" for n in out["notes"])
    assert not any(n["code"] == "fit.below_resolution" for n in out["notes"])
    for name in ("m_a", "T_a"):
        assert out["parameters"][name]["trusted"] is False, name


def test_lag_below_the_samples_on_time_stays_a_bound(tmp_path) -> None:
    # the same balancer with a lag of 1 ms and the force on time: T_a on its floor is a
    # bound (below resolution), the whole-shift search finds no lead, every value trusted
    out = fit(_log(tmp_path, 0.0, {**TRUTH, "T_a": 0.001})).to_dict()
    assert out["trusted"] is True
    assert any(n["code"] == "fit.below_resolution" for n in out["notes"])
    assert not any(n["code"] == "fit.timing" for n in out["notes"])


def test_on_time_log_keeps_every_value_trusted(tmp_path) -> None:
    out = fit(_log(tmp_path, 0.0)).to_dict()
    assert abs(out["metrics"]["timing_lead_s"]) < 3 * out["metrics"]["timing_lead_stderr_s"]
    assert out["trusted"] is True
    for name in ("m_a", "T_a", "D0", "A"):
        p = out["parameters"][name]
        assert p["trusted"] is True and p["untrusted_because"] == []
        lo, hi = p["ci95"]
        assert lo - 0.5 * (hi - lo) <= TRUTH[name] <= hi + 0.5 * (hi - lo)


def _session_log(tmp_path, rate_hz: float) -> str:
    """A clean session (rests between levels), its steps at random instants between
    samples, a precise accelerometer: the sampling alone must not read as a late channel."""
    from balancer_id.read.recording import Recording
    from balancer_id.simulation.engine import TrialInput, simulate_many
    from balancer_id.simulation.inputs import Thrust

    rng = np.random.default_rng(5)
    times, levels = [1.0 + rng.uniform(0, 0.02)], []
    for u in (20.0, 0.0, -20.0, 0.0, 35.0, 0.0, -35.0, 0.0):
        levels.append(u)
        times.append(times[-1] + 2.5 + rng.uniform(0, 0.02))
    t = np.arange(round(times[-1] * rate_hz) + 1) / rate_hz
    model = resolve_model("variable_viscosity")
    drive = Thrust(np.array(times[:-1]), np.array(levels))
    truth = {"m_a": 10.0, "T_a": 0.3, "D0": 40.0, "A": 0.02}
    sim = simulate_many(model, truth, [TrialInput(t, drive)], substeps=32)[0]
    accel = np.zeros((t.size, 3))
    accel[:, 2] = sim.accel + 9.80665
    accel += rng.normal(0.0, 0.003, accel.shape)
    force = np.asarray(sim.operating_force) + rng.normal(0.0, 0.02, t.size)
    rec = Recording(
        name="Run #1",
        time=t,
        force=force,
        accel=accel,
        accel_includes_gravity=True,
        accel_axes=("x", "y", "z"),
        sample_rate_hz=rate_hz,
    )
    path = tmp_path / f"session_{rate_hz:.0f}.csv"
    write_log(path, [rec], "generic")
    return str(path)


@pytest.mark.parametrize("rate_hz", [500.0])
def test_sampling_of_the_force_is_no_late_channel(tmp_path, rate_hz) -> None:
    # issue 31: holding each force sample until the next put every step half a sample
    # late, and a precise clean log was called late (here by 17 standard errors); the step now
    # changes halfway between its samples (found at the log's own rate when decimated)
    out = fit(_session_log(tmp_path, rate_hz)).to_dict()
    lead, se = out["metrics"]["timing_lead_s"], out["metrics"]["timing_lead_stderr_s"]
    assert abs(lead) < 3 * se
    assert not any(n["code"] == "fit.timing" for n in out["notes"])


def test_steps_sharing_their_place_between_samples_widen_the_values(tmp_path) -> None:
    # issue 31: a programmed session steps every 6.00 s at 50 Hz, each step right at a
    # sample (bench_universe seed 723): where between its samples each step lies is
    # unknown by up to 20 ms, the same for every step, and T_a came out 5.5 standard
    # errors off, trusted, or the timing test called it late. The spread (dt^2 / 12)
    # now enters the lead's and every value's standard error (through its sensitivity
    # to the drive's timing).
    from balancer_id.read.recording import Recording
    from balancer_id.simulation.engine import TrialInput, simulate_many
    from balancer_id.simulation.inputs import Thrust

    rate = 50.0
    truth = {"m_a": 2.25, "T_a": 0.68, "D0": 0.94, "A": 0.105}
    levels = [1.27, 0.0, 1.38, 0.0, -1.26, 0.0, -1.34, 0.0]
    onsets = 1.54 + 6.0 * np.arange(len(levels))
    t = np.arange(round((onsets[-1] + 6.0) * rate) + 1) / rate
    sim = simulate_many(
        resolve_model("variable_viscosity"),
        truth,
        [TrialInput(t, Thrust(onsets, np.array(levels)))],
        substeps=32,
    )[0]
    rng = np.random.default_rng(2)
    accel = np.zeros((t.size, 3))
    accel[:, 2] = sim.accel + 9.80665
    accel += rng.normal(0.0, 0.0055, accel.shape)
    force = np.asarray(sim.operating_force) + rng.normal(0.0, 0.027, t.size)
    rec = Recording(
        name="Run #1",
        time=t,
        force=force,
        accel=accel,
        accel_includes_gravity=True,
        accel_axes=("x", "y", "z"),
        sample_rate_hz=rate,
    )
    path = tmp_path / "programmed.csv"
    write_log(path, [rec], "pasco-sparkvue")
    out = fit(str(path)).to_dict()
    # the 20 ms place is the sampling's, no late channel: trusted, and each interval holds
    # the truth (without the spread: "11 +- 1 ms late", every value untrusted)
    assert out["trusted"] is True
    for name, value in truth.items():
        lo, hi = out["parameters"][name]["ci95"]
        assert lo <= value <= hi, name


def _updown_log(tmp_path, delay_s: float) -> str:
    """Up-then-down moves without rest at 50 Hz, the paper's viscosity falling with the
    thrust (A |u| about 1.2): the acceleration jumps where the thrust returns to zero
    while the balancer moves (bench_universe seed 13350865005, scaled to 1 kg)."""
    from balancer_id.read.recording import Recording
    from balancer_id.simulation.engine import TrialInput, simulate_many
    from balancer_id.simulation.inputs import Thrust

    rate, hold = 50.0, 4.33
    times, levels = [1.4], []
    for u in (0.97, 1.10, 1.16):
        for level, span in ((u, hold / 2), (-u, hold / 2), (0.0, hold)):
            levels.append(level)
            times.append(times[-1] + span)
    t = np.arange(round(times[-1] * rate) + 1) / rate
    drive = Thrust(np.array(times[:-1]), np.array(levels))
    sim = simulate_many(
        resolve_model("variable_viscosity"), UPDOWN_TRUTH, [TrialInput(t, drive)], substeps=32
    )[0]
    rng = np.random.default_rng(1)
    accel = np.zeros((t.size, 3))
    accel[:, 2] = sim.accel + 9.80665
    accel += rng.normal(0.0, 0.0084, accel.shape)
    force = np.asarray(sim.operating_force, dtype=float)
    if delay_s:
        force = np.interp(t - delay_s, t, force, left=force[0])
    force = force + rng.normal(0.0, 0.019, t.size)
    rec = Recording(
        name="Run #1",
        time=t,
        force=force,
        accel=accel,
        accel_includes_gravity=True,
        accel_axes=("x", "y", "z"),
        sample_rate_hz=rate,
    )
    path = tmp_path / f"updown_{delay_s * 1e3:.0f}ms.csv"
    write_log(path, [rec], "pasco-capstone")
    return str(path)


UPDOWN_TRUTH = {"m_a": 1.0, "T_a": 1.05, "D0": 5.6, "A": 1.14}


def test_late_force_on_a_jumping_response_is_measured_whole(tmp_path) -> None:
    # issue 31: a force channel 25 ms late, 50 Hz, the response jumping at each return to
    # zero thrust: the first-order test read 12 +- 7 ms (not clear) and A came out 4.5
    # standard errors low, trusted. The whole-shift profile (the output moved by each
    # lead, the values refitted to first order) calls it, and A is no longer trusted.
    out = fit(_updown_log(tmp_path, 0.025)).to_dict()
    lead, se = out["metrics"]["timing_lead_s"], out["metrics"]["timing_lead_stderr_s"]
    assert lead > 3 * se and lead > 0.01
    assert out["trusted"] is False
    assert any(n["code"] == "fit.timing" and n["severity"] == "error" for n in out["notes"])
    assert out["parameters"]["A"]["trusted"] is False


def test_on_time_jumping_response_keeps_its_trust(tmp_path) -> None:
    # the same log on time: no lead called, every interval holds the truth (within the
    # 95 % interval at this seed; the noise is the only error left)
    out = fit(_updown_log(tmp_path, 0.0)).to_dict()
    assert not any(n["code"] == "fit.timing" for n in out["notes"])
    assert out["trusted"] is True
    for name, value in UPDOWN_TRUTH.items():
        lo, hi = out["parameters"][name]["ci95"]
        assert lo <= value <= hi, name


def test_a_late_force_the_fit_found_is_the_diagnosis(tmp_path) -> None:
    # issue 31: the arena's refit with the force 38 ms late gained 24 BIC, under the
    # threshold of 30 for the best of many explanations, and the verdict was "effect
    # missing" naming a bias. The fit's own timing test had called it (one test, fixed in
    # advance, at 3 standard errors) and no balancer answers before it is pushed: the
    # diagnosis names the late channel.
    from balancer_id.diagnostics.api import diagnose

    d = diagnose(fit(_updown_log(tmp_path, 0.025))).to_dict()
    assert d["verdict"] == "sensor effect"
    best = d["explanations"][0]
    assert best["detail"]["sensor"] == "channel timing"
    assert best["detail"]["late_channel"] == "force"


def _moving_steps_log(tmp_path, delay_s: float, seed: int = 28) -> str:
    """Up, down, then zero thrust without rest at 200 Hz, a slow drive lag and the paper's
    viscosity (A |u| about 1.3): each step inside the session begins the next trial while
    the balancer moves, so the acceleration jumps on the trials' border (bench_universe
    world 3412600028, scaled to 1 kg)."""
    from balancer_id.read.recording import Recording
    from balancer_id.simulation.engine import TrialInput, simulate_many
    from balancer_id.simulation.inputs import Thrust

    rate, u = 200.0, 0.8
    truth = MOVING_TRUTH
    times = np.array([1.64, 2.83, 4.02])
    t = np.arange(round(6.37 * rate) + 1) / rate
    drive = Thrust(times, np.array([u, -u, 0.0]))
    model = resolve_model("variable_viscosity")
    sim = simulate_many(model, truth, [TrialInput(t, drive)], substeps=32)[0]
    rng = np.random.default_rng(seed)
    accel = np.zeros((t.size, 3))
    accel[:, 2] = sim.accel + 9.80665
    accel += rng.normal(0.0, 0.03, accel.shape)
    force = np.asarray(sim.operating_force, dtype=float)
    if delay_s:
        force = np.interp(t - delay_s, t, force, left=force[0])
    force = force + rng.normal(0.0, 0.008, t.size)
    rec = Recording(
        name="Run #1",
        time=t,
        force=force,
        accel=accel,
        accel_includes_gravity=True,
        accel_axes=("x", "y", "z"),
        sample_rate_hz=rate,
    )
    path = tmp_path / f"moving_{delay_s * 1e3:.0f}ms.csv"
    write_log(path, [rec], "pasco-capstone")
    return str(path)


MOVING_TRUTH = {"m_a": 1.0, "T_a": 0.48, "D0": 5.25, "A": 1.65}


def test_late_force_at_steps_between_trials_is_seen(tmp_path) -> None:
    # issue 31: a force 23 ms late, its steps taken while the balancer moves: each step
    # begins a trial, and the acceleration's jump, 23 ms before the recorded step, lay at
    # the end of the trial before. Shifted trial by trial the model never moved its jump
    # across the border: "1 +- 3 ms", A 26 % low, trusted. Shifted through the session,
    # the lead is measured and the values it bends lose their trust.
    out = fit(_moving_steps_log(tmp_path, 0.023)).to_dict()
    lead, se = out["metrics"]["timing_lead_s"], out["metrics"]["timing_lead_stderr_s"]
    assert lead == pytest.approx(0.023, abs=max(3 * se, 0.006))
    assert any(n["code"] == "fit.timing" and n["severity"] == "error" for n in out["notes"])
    assert out["trusted"] is False


def test_on_time_steps_between_trials_keep_their_trust(tmp_path) -> None:
    out = fit(_moving_steps_log(tmp_path, 0.0)).to_dict()
    assert not any(n["code"] == "fit.timing" for n in out["notes"])
    assert out["trusted"] is True
    for name, value in MOVING_TRUTH.items():
        lo, hi = out["parameters"][name]["ci95"]
        assert lo <= value <= hi, name


def test_a_lead_that_moves_one_value_far_takes_every_values_trust(tmp_path) -> None:
    # issue 31 (bench_universe world 12757897009): a guided move at 50 Hz, the force 59 ms
    # late; modelling the lead moved m_a 5.3 standard errors to first order, T_a 1.0 and
    # A 0.4, so T_a and A kept their trust, and ended 3.6 and 2.9 standard errors off.
    # That far from the optimum the first order bounds no value: none is trusted.
    from simlib.sessions import guided_move_thrust

    from balancer_id.read.recording import Recording
    from balancer_id.simulation.engine import TrialInput, simulate_many

    truth = {"m_a": 228.3, "T_a": 0.952, "D0": 2753.0, "A": 0.000528}
    rate = 50.0
    t = np.arange(round(12.8 * rate) + 1) / rate
    thrust = guided_move_thrust(924.7, 9.71, 1.0964, rate)
    (sim,) = simulate_many(
        resolve_model("variable_viscosity"), truth, [TrialInput(t, thrust)], substeps=8
    )
    rng = np.random.default_rng(9)
    force = np.asarray(sim.operating_force, dtype=float)
    force = np.interp(t - 0.059, t, force, left=force[0]) + rng.normal(0.0, 3.4, t.size)
    accel = np.zeros((t.size, 3))
    accel[:, 2] = sim.accel + 9.80665
    accel += rng.normal(0.0, 0.0071, accel.shape)
    rec = Recording(
        name="Run #1", time=t, force=force, accel=accel, accel_includes_gravity=True,
        accel_axes=("x", "y", "z"), sample_rate_hz=rate,
    )  # fmt: skip
    path = tmp_path / "guided_late.csv"
    write_log(path, [rec], "generic")
    out = fit(str(path)).to_dict()
    assert any(n["code"] == "fit.timing" and n["severity"] == "error" for n in out["notes"])
    for name, value in truth.items():
        p = out["parameters"][name]
        lo, hi = p["ci95"]
        if not lo <= value <= hi:
            assert p["trusted"] is False, name
