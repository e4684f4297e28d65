"""A robot whose servo acts late (issue 31, item 9): the delayed loop, its poles and delay
margin, the delay named (or not) with its interval, and advice that holds on the loop
with the delay. Moves are simulated here (no file, no segmentation) to stay fast."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from balancer_id.identify import resolve_model
from balancer_id.identify.advice import advise, mode_from_response
from balancer_id.identify.coupling import coupling, delay_margin, delayed_coupling
from balancer_id.identify.servo_delay import examine_servo_delay
from balancer_id.simulation.delayed_servo import LANE_PARAMS, simulate_delayed_servo
from balancer_id.simulation.engine import TrialInput, simulate_many
from balancer_id.simulation.inputs import Thrust, Trapezoid

PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
ROBOT = {"k_r": 150.0, "c_r": 100.0}
MODEL = "variable_viscosity+servo"
#: The paper's sensors: 0.03 m/s^2 and 0.03 N of white noise.
NOISE = 0.03


def _move(rate_hz=100.0, duration_s=10.0):
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    z_ref, v_ref = Trapezoid(0.2, 0.1, 0.5, start=1.0).evaluate(t)
    return t, z_ref, v_ref


def _lane(values, tau_r):
    return np.array([float({**values, "tau_r": tau_r}.get(n, 0.0)) for n in LANE_PARAMS])


def _recorded(tau_r, seed, values=None):
    """A move of the robot whose servo is ``tau_r`` late, with the sensors' noise."""
    values = values or {**PAPER, **ROBOT}
    t, zr, vr = _move()
    a, h, _ = simulate_delayed_servo(t, zr, vr, _lane(values, tau_r))
    rng = np.random.default_rng(seed)
    trial = SimpleNamespace(
        index=0,
        input=TrialInput(t, Thrust.step(t[0], 0.0), zr, vr),
        accel=a[0] + rng.normal(0, NOISE, t.size),
    )
    return trial, h[0] + rng.normal(0, NOISE, t.size)


def test_without_delay_the_delayed_loop_is_the_kernels_loop():
    t, zr, vr = _move(rate_hz=200.0)
    values = {**PAPER, **ROBOT}
    model = resolve_model(MODEL)
    sim = simulate_many(model, values, [TrialInput(t, Thrust.step(t[0], 0.0), zr, vr)])[0]
    a, h, v = simulate_delayed_servo(t, zr, vr, _lane(values, 0.0))
    scale = np.max(np.abs(sim.accel))
    assert np.max(np.abs(a[0] - sim.accel)) < 1e-4 * scale
    assert np.max(np.abs(h[0] - sim.operating_force)) < 1e-3
    assert np.max(np.abs(v[0] - sim.velocity)) < 1e-5


def test_the_delayed_poles_are_the_mode_a_delayed_simulation_rings_with():
    # a constant viscosity keeps the loop linear: the simulated settling is the mode
    values = {"m_a": 15.1, "T_a": 0.33, "D0": 1.0, "A": 0.0, **ROBOT}
    t, zr, vr = _move(rate_hz=200.0, duration_s=14.0)
    a, _, _ = simulate_delayed_servo(t, zr, vr, _lane(values, 0.03))
    after = t > 4.0  # the move ends at 3.2 s
    sim = mode_from_response(t[after], a[0][after], expected_hz=0.7)
    pred = delayed_coupling(15.1, 0.33, 1.0, 150.0, 100.0, 0.03)
    plain = coupling(15.1, 0.33, 1.0, 150.0, 100.0)
    assert sim is not None
    assert abs(sim.damping_ratio - pred.damping_ratio) < 0.01
    assert abs(sim.oscillation_hz / pred.oscillation_hz - 1) < 0.02
    # the delay costs damping: the undelayed prediction misses it
    assert plain.damping_ratio - sim.damping_ratio > 0.05


def test_the_delay_margin_is_where_the_loop_turns_unstable():
    margin = delay_margin(15.1, 0.33, 1.0, 150.0, 100.0)
    assert 0.02 < margin < 0.5
    assert delayed_coupling(15.1, 0.33, 1.0, 150.0, 100.0, 0.97 * margin).stable
    assert not delayed_coupling(15.1, 0.33, 1.0, 150.0, 100.0, 1.03 * margin).stable


def test_a_late_servo_is_named_with_an_interval_holding_the_truth():
    trial, force = _recorded(0.03, seed=5)
    # the fit without a delay takes it for a stiffer servo: start there
    start = {**PAPER, "k_r": 205.0, "c_r": 97.0}
    found = examine_servo_delay(resolve_model(MODEL), start, ["k_r", "c_r"], [trial], [force])
    assert found.verdict == "servo_delay", found.text()
    lo, hi = found.interval
    assert lo <= 0.03 <= hi, found.text()
    assert hi - lo < 0.01
    late = found.delayed_values
    assert abs(late["k_r"] / 150.0 - 1) < 0.05
    assert "acts late" in found.text() and "stiffer servo" in found.text()


def test_a_servo_acting_at_once_is_not_called_late():
    trial, force = _recorded(0.0, seed=6)
    found = examine_servo_delay(
        resolve_model(MODEL), {**PAPER, **ROBOT}, ["k_r", "c_r"], [trial], [force]
    )
    assert found.verdict == "none", found.text()
    assert found.interval[1] < 0.01
    assert not found.use_delay


def test_advice_for_a_late_servo_holds_over_the_delays_interval():
    values = {**PAPER, **ROBOT}
    delays = (0.03, 0.025, 0.035)
    got = advise(values, viscosity_factor=0.15, delays=delays)
    assert got.delays == delays
    reached = [s for s in got.settings if s.advised is not None]
    assert reached
    for s in reached:
        assert s.over_delay["damping_ratio_min"] >= 0.3 - 1e-6
        at = {**values, s.parameter: s.advised}
        for tau in delays:
            c = delayed_coupling(at["m_a"], at["T_a"], 0.15 * at["D0"], at["k_r"], at["c_r"], tau)
            assert c.stable and c.damping_ratio >= 0.3 - 1e-6
    # the undelayed advice for k_r promises 0.3; on the late loop it falls short
    plain = advise(values, viscosity_factor=0.15)
    k_r = next(s for s in plain.settings if s.parameter == "k_r").advised
    assert k_r is not None
    assert delayed_coupling(15.1, 0.33, 0.9, k_r, 100.0, 0.03).damping_ratio < 0.27


def test_advice_for_an_ambiguous_delay_holds_on_the_stiffer_servo_too():
    # the data allow a late servo (150 N/m, 30 ms) or a stiffer one acting at once
    late = {**PAPER, **ROBOT}
    stiffer = {**PAPER, "k_r": 205.0, "c_r": 97.0}
    got = advise(late, viscosity_factor=0.15, delays=(0.03, 0.025, 0.035), also=[stiffer])
    for s in got.settings:
        if s.advised is None:
            continue
        alt = s.over_delay["also_damping_ratio"]
        assert alt and alt[0] is not None and alt[0] >= 0.3 - 1e-6
        factor = s.advised / s.current
        v = {**stiffer, s.parameter: stiffer[s.parameter] * factor}
        c = coupling(v["m_a"], v["T_a"], 0.15 * v["D0"], v["k_r"], v["c_r"])
        assert c.stable and c.damping_ratio >= 0.3 - 1e-6


def test_diagnose_names_a_late_servo_from_the_fits_examination():
    from balancer_id.diagnostics.explanations import kind_of
    from balancer_id.identify.servo_delay import Explanation, ServoDelay

    late = ServoDelay(
        True, "servo_delay", 0.031, (0.029, 0.033),
        [
            Explanation("servo_delay", {**PAPER, "k_r": 148.0, "c_r": 100.0, "tau_r": 0.031},
                        0.0, -2000.0, "late", 0.0302, 0.03),
            Explanation("no_delay", {**PAPER, "k_r": 206.0, "c_r": 97.0}, 0.0, -1200.0,
                        "at once", 0.0303, 0.07),
        ],
        has_force=True,
    )  # fmt: skip
    kind = kind_of("servo_delay")
    got = kind.propose(SimpleNamespace(fit=SimpleNamespace(servo_delay=late)))
    assert len(got) == 1 and got[0].label == "robot servo 31 ms late"
    assert got[0].delta_bic == 800.0
    assert got[0].detail["ci95_s"] == [0.029, 0.033]
    # the acceleration's excess error is nil: it stands on its BIC fall
    got[0].excess_drop = 0.0
    assert kind.valid(got[0], False, 10.0, 0.05)
    # not named: not proposed
    late.verdict = "none"
    assert kind.propose(SimpleNamespace(fit=SimpleNamespace(servo_delay=late))) == []
