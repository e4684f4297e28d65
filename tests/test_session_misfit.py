"""A session's trials that go on while the load moves are held to the noise at rest too.

The misfit test compared the residual after each step with the rest before it, trial by
trial and pooled, and a trial with no rest of its own (it continues the session) was left
out; most of a session is such trials, so a misfit there went unseen and the fit stayed
trusted (a 500 Hz session's blended jumps: RMSE 2.8x the noise, m_a and T_a 3.5-4 standard
errors off, trusted)."""

from __future__ import annotations

import copy

import numpy as np
from simlib.sessions import record, session_thrust, write_recordings

from balancer_id.identify.api import fit
from balancer_id.identify.structure import structured_residual
from balancer_id.model import parse_model
from balancer_id.simulation.synth import SensorSettings

NOISE = 0.02


def test_a_misfit_in_a_sessions_continuing_trials_is_seen(tmp_path):
    thrust = session_thrust([8.0, -8.0, 4.0, 0.0], hold_s=2.5, rest_s=1.0)
    sensor = SensorSettings(rate_hz=200.0, accel_noise=NOISE, force_noise=0.05, tilt_deg=5.0)
    truth = {"m_a": 12.0, "T_a": 0.25, "D0": 6.0, "A": 0.03}
    rec = record(parse_model("variable_viscosity"), truth, thrust, 12.0, sensor=sensor, seed=5)
    path = tmp_path / "session.csv"
    write_recordings(path, [rec])
    match = copy.copy(fit(str(path)).match)
    assert structured_residual(match) is None  # clean: nothing to say
    continuing = [td.continues for td in match.data.trials]
    assert sum(continuing) >= 2 and not continuing[0]
    y = np.array(match.y, dtype=float)
    for td, sl in zip(match.data.trials, match.data.slices(), strict=True):
        if td.continues:  # a slow misfit, 2x the noise in RMS, where only these trials are
            y[sl] += 2 * np.sqrt(2) * NOISE * np.sin(2 * np.pi * 0.8 * np.asarray(td.time))
    object.__setattr__(match, "y", y)
    note = structured_residual(match)
    assert note is not None and note.code == "fit.structured_residual", note
    assert note.severity == "error"
