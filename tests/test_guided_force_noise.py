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
