"""A guided move's force noise is smoothed out before it drives the model (issue 31,
errors in variables).

The measured force drives the simulation; on a step its held level is averaged, but a
guided move's force changes all the time, and its noise went into the model as it was.
On a heavily damped load (the acceleration follows the force's changes) a load cell's
noise at 1.2 % of the thrust came out as the acceleration 35 ms late ("a dead time, a
sensor's low-pass": untrusted, a sensor blamed) and m_a 2.6 standard errors high
(``bench_universe``-style guided world 9106). A smoothing spline chosen by
cross-validation (zero phase) now drives it.
"""

from __future__ import annotations

import numpy as np
from simlib.sessions import guided_move_thrust

from balancer_id.identify.api import fit
from balancer_id.model.spec import resolve_model
from balancer_id.read.recording import Recording
from balancer_id.read.writers import write_log
from balancer_id.simulation.engine import TrialInput, simulate_many
from balancer_id.simulation.synth import up_vector

TRUTH = {"m_a": 18.6, "T_a": 0.93, "D0": 341.0, "A": 0.0183}
RATE = 200.0


def test_a_noisy_guided_force_is_no_late_sensor(tmp_path):
    rng = np.random.default_rng(9106)
    t = np.arange(0.0, 12.7, 1.0 / RATE)
    thrust = guided_move_thrust(1.5 * 40.6, 9.58, 1.13, RATE)
    (sim,) = simulate_many(
        resolve_model("variable_viscosity"), TRUTH, [TrialInput(t, thrust)], substeps=1
    )
    u = np.asarray(sim.operating_force, float)
    up = up_vector(25.0, 37.6)
    rec = Recording(
        name="Run #1", time=t, force=u + rng.normal(0.0, 0.0124 * 40.6, u.size),
        accel=(sim.accel + 9.80665)[:, None] * up[None, :] + rng.normal(0.0, 0.028, (t.size, 3)),
        accel_includes_gravity=True, accel_axes=("x", "y", "z"), sample_rate_hz=RATE,
    )  # fmt: skip
    path = tmp_path / "guided.csv"
    write_log(path, [rec], "generic")
    result = fit(str(path))
    codes = {n.code for n in result.all_notes if n.severity == "error"}
    assert "fit.timing" not in codes, codes
    for name, value in TRUTH.items():
        p = result.match.parameters[name]
        assert abs(p.value - value) < 3 * p.stderr, (name, p.value, p.stderr)


def test_a_held_force_at_50_hz_puts_its_sample_into_the_values(tmp_path):
    # issue 31 (bench_universe world 14420044007, without its faults): a clean guided
    # move at 50 Hz; the force changes between the samples (16.5 ms before each, here),
    # the model holds each sample's value to the next, and T_a came out 24 ms (13
    # standard errors) short, trusted. The hold's sample now enters each value's error.
    truth = {"m_a": 1.195, "T_a": 0.181, "D0": 1.564, "A": 1.32}
    rate = 50.0
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 9.0, 1.0 / rate)
    thrust = guided_move_thrust(1.6, 5.09, 1.7635, rate)
    (sim,) = simulate_many(
        resolve_model("variable_viscosity"), truth, [TrialInput(t, thrust)], substeps=8
    )
    up = up_vector(8.6, 40.0)
    rec = Recording(
        name="Run #1", time=t, force=np.asarray(sim.operating_force, float),
        accel=(sim.accel + 9.80665)[:, None] * up[None, :] + rng.normal(0.0, 0.0075, (t.size, 3)),
        accel_includes_gravity=True, accel_axes=("x", "y", "z"), sample_rate_hz=rate,
    )  # fmt: skip
    path = tmp_path / "guided_50hz.csv"
    write_log(path, [rec], "pasco-capstone")
    out = fit(str(path)).to_dict()
    for name, value in truth.items():
        lo, hi = out["parameters"][name]["ci95"]
        assert lo <= value <= hi, (name, lo, hi)
