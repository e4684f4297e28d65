"""A session with a drop-out longer than the bridging limit (issue 8): the model is not
carried across it; the trial after it starts in motion from the state estimated from the
data (velocity integrated from the acceleration since the last rest, drive force at the
thrust's steady state). Known truth, seeded; the fit benchmark's tolerances."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from simlib.sessions import record, session_thrust

from balancer_id.identify.data import LONG_GAP_S, from_trials
from balancer_id.identify.matching import match_trials
from balancer_id.model import parse_model
from balancer_id.read.recording import Log
from balancer_id.segment import find_trials
from balancer_id.simulation.engine import simulate
from balancer_id.simulation.synth import SensorSettings

TRUTH = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
#: The fit benchmark's tolerances (benchmarks/bench_fit.py).
TOL = {"m_a": 0.02, "T_a": 0.05, "D0": 0.08, "A": 0.15}
SESSION = (2.45, 4.9, -2.45, -4.9, 7.35, -7.35)


@pytest.fixture(scope="module")
def model():
    return parse_model("variable_viscosity")


def _session_with_dropout(model, lo, hi, seed):
    thrust = session_thrust(SESSION, 68.0 / 6)
    rec = record(model, TRUTH, thrust, 70.0, sensor=SensorSettings(tilt_deg=12.0), seed=seed)
    cut = (rec.time > lo) & (rec.time < hi)
    rec = dataclasses.replace(rec, time=rec.time[~cut], force=rec.force[~cut],
                              accel=rec.accel[~cut])  # fmt: skip
    truth = simulate(model, TRUTH, np.arange(0.0, 70.0, 0.005), thrust)
    return Log(path="session.csv", format="generic", recordings=[rec]), truth


@pytest.mark.parametrize(
    ("lo", "hi", "seed"),
    [(26.0, 33.0, 1), (34.0, 40.0, 2)],  # 7 s inside a hold; 6 s hiding the change at 36 s
)
def test_a_trial_after_a_long_dropout_starts_from_the_state_in_the_data(model, lo, hi, seed):
    log, truth = _session_with_dropout(model, lo, hi, seed)
    data = from_trials(find_trials(log))
    after = [td for td in data if td.input.x0 is not None]
    assert len(after) == 1 and after[0].time[0] >= hi and not after[0].continues
    f0, v0, _ = after[0].input.x0
    t0 = after[0].time[0]
    true_v = np.interp(t0, truth.time, truth.velocity)
    # the acceleration inside the drop-out is unknown (taken as linear): the velocity is
    # known to within half the gap times the change of the acceleration across it
    a_lo, a_hi = np.interp([lo, hi], truth.time, truth.accel)
    assert abs(v0 - true_v) <= 0.5 * (hi - lo) * abs(a_hi - a_lo) + 0.05
    assert abs(v0 - true_v) < abs(true_v)  # better than starting from rest
    assert f0 == pytest.approx(np.interp(t0, truth.time, truth.drive_force), rel=0.05)
    assert all(np.diff(td.time).max() <= LONG_GAP_S for td in data)  # never across a gap
    res = match_trials(model, data, start={"m_a": 15.0, "T_a": 0.3})
    for name, p in res.parameters.items():
        assert abs(p.value / TRUTH[name] - 1) <= TOL[name], (name, p.value)
