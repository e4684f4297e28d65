"""The simulator against analytic solutions, the paper's Fig. 11 and a solve_ivp reference."""

from __future__ import annotations

import numpy as np
import pytest
from simlib.reference import simulate_reference

from balancer_id.model import parse_model
from balancer_id.model.effects import BUILTIN_EFFECTS
from balancer_id.simulation import Thrust, Trapezoid, TrialInput, simulate

M, T = 15.1, 0.33
DT = 0.005
#: The paper's viscosity held off: its force ``-D0 exp(-A|h|) v`` is exactly zero, so a
#: model with it simulates as the model without it, in a kernel the suite compiles anyway
#: (the diagnosis candidates ``variable_viscosity+EFFECT``) instead of one more of its own.
NO_VISCOSITY = {"D0": 0.0, "A": 0.0}


def without_viscosity(name: str = "base"):
    """The model of effect ``name`` alone (``base``: none), as the paper's model with its
    viscosity held off by :data:`NO_VISCOSITY`."""
    if name in ("base", "variable_viscosity"):
        return parse_model("variable_viscosity")
    if name == "viscous":
        return parse_model("viscous")
    return parse_model(f"variable_viscosity+{name}")


def grid(seconds: float) -> np.ndarray:
    return np.arange(0.0, seconds, DT)


def test_first_order_step_without_viscosity():
    t = grid(5.0)
    t0, f_in = 0.5023, 2.45  # onset between two samples
    params = {"m_a": M, "T_a": T, **NO_VISCOSITY}
    sim = simulate(without_viscosity(), params, t, Thrust.step(t0, f_in))
    a_zc = f_in / M
    exact = np.where(t >= t0, a_zc * (1.0 - np.exp(-(t - t0) / T)), 0.0)
    assert np.max(np.abs(sim.accel - exact)) < 1e-4 * a_zc
    # the paper's settling rule: ~95 % at 3 T_a
    k = np.searchsorted(t, t0 + 3 * T)
    assert sim.accel[k] / a_zc == pytest.approx(1 - np.exp(-3 * T / T), abs=2e-3)


def test_exponential_decay_with_constant_viscosity():
    t = grid(12.0)
    D, f_in = 6.0, 4.9
    sim = simulate(parse_model("viscous"), {"m_a": M, "T_a": T, "D0": D}, t, Thrust.step(0.0, f_in))
    # A(s) = f_in / ((T s + 1)(M s + D)): a(t) = f_in/(T M) (e^{-D t/M} - e^{-t/T}) / (1/T - D/M)
    exact = f_in / (T * M) * (np.exp(-D * t / M) - np.exp(-t / T)) / (1 / T - D / M)
    assert np.max(np.abs(sim.accel - exact)) < 1e-4 * np.max(exact)
    late = t > 3.0
    rate = -np.polyfit(t[late], np.log(sim.accel[late]), 1)[0]
    assert rate == pytest.approx(D / M, rel=1e-4)


@pytest.mark.parametrize(("A", "peak", "half_time"), [(0.0, 0.12, 2.9), (0.4, 0.139, 6.0)])
def test_paper_fig11(A, peak, half_time):
    t = grid(15.0)
    sim = simulate(
        parse_model("variable_viscosity"),
        {"m_a": M, "T_a": T, "D0": 6.0, "A": A},
        t,
        Thrust.step(0.0, 2.45),
    )
    i = int(np.argmax(sim.accel))
    j = i + int(np.argmax(sim.accel[i:] < sim.accel[i] / 2))
    assert sim.accel[i] == pytest.approx(peak, abs=0.002)
    assert t[j] == pytest.approx(half_time, abs=0.1)


def test_stuck_below_the_friction_threshold():
    t = grid(5.0)
    params = {"m_a": M, "T_a": T, "f_s": 0.98, **NO_VISCOSITY}
    sim = simulate(without_viscosity("karnopp"), params, t, Thrust.step(0.5, 0.9))
    assert np.all(sim.velocity == 0.0)
    assert np.all(sim.accel == 0.0)


def test_sticks_again_without_chattering_after_the_thrust_is_removed():
    t = grid(8.0)
    thrust = Thrust(np.array([0.5, 2.0]), np.array([4.9, 0.0]))
    sim = simulate(
        parse_model("viscous+karnopp"), {"m_a": M, "T_a": T, "D0": 3.0, "f_s": 0.98}, t, thrust
    )
    assert sim.velocity.max() > 0.05
    stopped = np.flatnonzero(sim.velocity == 0.0)
    last_motion = np.flatnonzero(sim.velocity != 0.0)[-1]
    assert last_motion < t.size - 100  # it stops, and stays stopped
    assert np.all(sim.velocity[last_motion + 1 :] == 0.0)
    assert np.all(sim.velocity[: last_motion + 1] >= 0.0)  # never reverses: no chattering
    assert stopped.size > 100


def test_speed_plateau_at_v_max():
    from balancer_id.simulation.kernel import SPEED_LIMIT_TAU

    t = grid(6.0)
    params = {"m_a": M, "T_a": T, "v_max": 0.5, **NO_VISCOSITY}
    sim = simulate(without_viscosity("speed_limit"), params, t, Thrust.step(0.0, 7.35))
    assert np.all(sim.velocity <= 0.5 + 1e-12)
    t_hit = t[np.argmax(sim.velocity >= 0.99 * 0.5)]
    assert t_hit == pytest.approx(1.4, abs=0.1)  # MODEL.md: about 1.4 s at 7.35 N
    # the drive closes on the limit exponentially with SPEED_LIMIT_TAU (20 ms)
    settled = t > t_hit + 10 * SPEED_LIMIT_TAU
    assert np.allclose(sim.velocity[settled], 0.5, atol=1e-4 * 0.5)
    assert np.max(np.abs(sim.accel[settled])) < 1e-3 * 7.35 / M
    # and the acceleration falls to zero within a few samples of reaching the limit
    k = int(np.argmax(sim.velocity >= 0.99 * 0.5))
    assert abs(sim.accel[k + 10]) < 0.1 * abs(sim.accel[k - 40])


def test_dead_time_is_exact_to_the_sample():
    t = grid(4.0)
    tau = 0.0173  # not a multiple of the sample interval
    params = {"m_a": M, "T_a": T, **NO_VISCOSITY}
    delayed = simulate(
        without_viscosity("dead_time"), {**params, "tau_d": tau}, t, Thrust.step(0.5, 4.9)
    )
    shifted = simulate(without_viscosity(), params, t, Thrust.step(0.5 + tau, 4.9))
    assert np.max(np.abs(delayed.accel - shifted.accel)) < 1e-12


def _scenario(name: str) -> tuple[dict[str, float], TrialInput]:
    cls = BUILTIN_EFFECTS[name]
    params = {"m_a": M, "T_a": T, **NO_VISCOSITY, **cls.example}
    t = grid(6.0)
    if name == "servo":
        z_ref, v_ref = Trapezoid(0.2, 0.1, 0.5, start=1.0).evaluate(t)
        return params, TrialInput(t, Thrust.step(0.5, 0.0), z_ref, v_ref)
    return params, TrialInput(t, Thrust.step(0.5023, -4.9 if name == "asymmetric_lag" else 4.9))


@pytest.mark.parametrize("name", sorted(BUILTIN_EFFECTS))
def test_agrees_with_solve_ivp(name):
    model = without_viscosity(name)
    params, trial = _scenario(name)
    params = {k: v for k, v in params.items() if k in model.param_names}
    fast = simulate(model, params, trial.time, trial.thrust, z_ref=trial.z_ref, v_ref=trial.v_ref)
    ref = simulate_reference(model, params, trial, max_step=0.01)
    for got, want in ((fast.accel, ref.accel), (fast.velocity, ref.velocity)):
        assert np.max(np.abs(got - want)) <= 1e-3 * np.max(np.abs(want))


@pytest.mark.parametrize(
    "spec",
    [
        # each kink apart, on the kernels a first run compiles anyway (a kernel of karnopp
        # and speed_limit together would cost the suite a compile of its own, ~14 s cold)
        "variable_viscosity+karnopp+dead_time",
        "variable_viscosity+speed_limit+dead_time",
        "variable_viscosity+servo",
    ],
)
def test_halving_the_internal_step_changes_little(spec):
    model = parse_model(spec)
    t = grid(8.0)
    params = {"m_a": M, "T_a": T, "D0": 6.0, "A": 0.4, "f_s": 0.98, "tau_d": 0.05}
    params.update({"k_r": 400.0, "c_r": 180.0})
    params = {k: v for k, v in params.items() if k in model.param_names}
    z_ref, v_ref = Trapezoid(0.2, 0.1, 0.5, start=1.0).evaluate(t)
    kw = {"z_ref": z_ref, "v_ref": v_ref}
    one = simulate(model, params, t, Thrust.step(0.5, 7.35), substeps=1, **kw)
    two = simulate(model, params, t, Thrust.step(0.5, 7.35), substeps=2, **kw)
    assert np.max(np.abs(one.accel - two.accel)) < 1e-4 * np.max(np.abs(two.accel))
    assert np.max(np.abs(one.position - two.position)) < 1e-4 * np.max(np.abs(two.position))


def test_starts_from_a_given_state():
    """From v0 with no thrust and constant viscosity: the drive force decays with T_a and
    the velocity obeys m v' = f - D v, solved in closed form."""
    m, T, D, f0, v0 = 15.1, 0.33, 6.0, 3.0, 0.2
    t = np.arange(0.0, 4.0, 0.005)
    sim = simulate(
        parse_model("viscous"),
        {"m_a": m, "T_a": T, "D0": D},
        t,
        Thrust.step(0.0, 0.0),
        x0=(f0, v0, 0.1),
    )
    # v(t) = v0 e^{-k t} + f0 / (m (k - 1/T)) (e^{-t/T} - e^{-k t}), k = D / m
    k = D / m
    v = v0 * np.exp(-k * t) + f0 / (m * (k - 1 / T)) * (np.exp(-t / T) - np.exp(-k * t))
    np.testing.assert_allclose(sim.velocity, v, atol=1e-6)
    np.testing.assert_allclose(sim.drive_force, f0 * np.exp(-t / T), atol=1e-6)
    assert sim.position[0] == pytest.approx(0.1)


def _sens_scenario(name: str) -> tuple[object, dict[str, float], TrialInput]:
    """A trial of ``name`` (with viscosity) that moves, and for friction stops and sticks."""
    model = parse_model(name if name in ("viscous", "variable_viscosity") else f"viscous+{name}")
    params = {"m_a": M, "T_a": T, "D0": 6.0, **BUILTIN_EFFECTS[name].example}
    params = {k: v for k, v in params.items() if k in model.param_names}
    t = grid(5.0)
    if name == "servo":
        z_ref, v_ref = Trapezoid(0.2, 0.1, 0.5, start=1.0).evaluate(t)
        return model, params, TrialInput(t, Thrust.step(0.5, 0.0), z_ref, v_ref, (0.1, 0.0, 0.0))
    if name == "speed_limit":
        params["D0"] = 0.5
        return model, params, TrialInput(t, Thrust.step(0.5023, 7.35), x0=(0.1, 0.0, 0.0))
    # up, then the thrust is removed: the load decelerates and (with friction) sticks
    thrust = Thrust(
        np.array([0.5023, 2.5017]), np.array([-4.9 if name == "asymmetric_lag" else 4.9, 0.0])
    )
    return model, params, TrialInput(t, thrust, x0=(0.1, 0.02, 0.0))


@pytest.mark.parametrize("name", sorted(BUILTIN_EFFECTS))
def test_kernel_jacobian_matches_central_differences(name):
    """The forward sensitivities (one simulation) against central differences of the
    simulated output, for every parameter and the initial state, events included."""
    from balancer_id.simulation.engine import PackedTrials

    model, params, trial = _sens_scenario(name)
    other = (0.05, -0.01, 0.0)  # a second trial, off the kinks of the rest state
    packed = PackedTrials.pack(
        [trial, TrialInput(trial.time, trial.thrust, trial.z_ref, trial.v_ref, other)]
    )
    p = np.asarray(model.vector(params))
    cols = list(range(p.size + 3))
    out, sens = packed.run_sens(model, p, cols)
    assert np.allclose(out, packed.run(model, p), rtol=1e-9, atol=1e-12)
    for c in cols:
        if c < p.size:
            h = 1e-5 * max(abs(p[c]), 1e-2)
            up, dn = p.copy(), p.copy()
            up[c] += h
            dn[c] -= h
            fd = (packed.run(model, up)[:, 0] - packed.run(model, dn)[:, 0]) / (2 * h)
        else:
            h = 1e-6
            fd = np.empty(out.shape[0])
            for sign in (1.0, -1.0):
                x0 = np.array([0.1, 0.02, 0.0]) if trial.x0 is None else np.array(trial.x0)
                x0[c - p.size] += sign * h
                x1 = np.array(other)
                x1[c - p.size] += sign * h
                pk = PackedTrials.pack(
                    [
                        TrialInput(trial.time, trial.thrust, trial.z_ref, trial.v_ref, tuple(x0)),
                        TrialInput(trial.time, trial.thrust, trial.z_ref, trial.v_ref, tuple(x1)),
                    ]
                )
                y = pk.run(model, p)[:, 0]
                fd = y if sign > 0 else (fd - y) / (2 * h)
        scale = max(np.max(np.abs(fd)), 1e-3 * np.max(np.abs(out[:, 0])))
        err = np.abs(sens[:, c] - fd)
        # away from events: the samples next to a friction stop or a thrust step may
        # straddle the event in one of the two differences
        assert np.quantile(err, 0.99) <= 1e-4 * scale, (name, c)
        assert np.median(err) <= 1e-5 * scale, (name, c)


@pytest.mark.parametrize("name", sorted(BUILTIN_EFFECTS))
@pytest.mark.parametrize("rows", [2, 7, 250])
def test_streamed_blocks_are_the_one_pass_exactly(name, rows):
    """Simulated a block of rows at a time (a long log), every trial cut across blocks,
    the output and the sensitivities are those of one pass (the state, the sensitivities
    and the thrust acting carried over each cut), for every effect's events."""
    from balancer_id.simulation.engine import PackedTrials

    model, params, trial = _sens_scenario(name)
    other = (0.05, -0.01, 0.0)
    packed = PackedTrials.pack(
        [trial, TrialInput(trial.time, trial.thrust, trial.z_ref, trial.v_ref, other)]
    )
    p = np.asarray(model.vector(params))
    cols = list(range(p.size + 3))
    out, sens = packed.run_sens(model, p, cols)
    seen = np.zeros(out.shape[0], dtype=int)
    for first, o, s in packed.stream_sens(model, p, cols, rows):
        np.testing.assert_array_equal(o, out[first : first + len(o)])
        np.testing.assert_array_equal(s, sens[first : first + len(o)])
        seen[first : first + len(o)] += 1
    assert np.all(seen == 1)
    plain = packed.run(model, p)
    for first, o in packed.stream(model, p, rows):
        np.testing.assert_array_equal(o, plain[first : first + len(o)])
