"""Small steps on a light balancer are trials; a run without one says why (issue 17.6).

Seeded simulated logs: a 0.3 kg balancer stepped by 0.05-0.15 N, force noise 0.003 N and
0.01 N (the smallest step is then 5 times the noise), acceleration noise 0.03 m/s^2.
"""

from __future__ import annotations

import pytest
from simlib.sessions import write_recordings

from balancer_id.model.spec import parse_model
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings
from balancer_id.trials import load_log

LIGHT = {"m_a": 0.3, "T_a": 0.05, "D0": 0.3, "A": 2.0}
SMALL = [0.05, -0.05, 0.1, -0.1, 0.15, -0.15]


@pytest.mark.parametrize("force_noise", [0.003, 0.01])
def test_steps_of_five_times_the_force_noise_are_trials(tmp_path, force_noise):
    sensor = SensorSettings(force_noise=force_noise, accel_noise=0.03)
    model = parse_model("variable_viscosity")
    recs = synthetic_recordings(model, LIGHT, SMALL, sensor=sensor, seed=2)
    path = tmp_path / "light.csv"
    write_recordings(path, recs)
    loaded = load_log(path)
    thrusts = [t.thrust_N for t in loaded.trials]
    assert len(thrusts) == len(SMALL)
    for found, truth in zip(thrusts, SMALL, strict=True):
        assert found == pytest.approx(truth, abs=4 * force_noise)


def test_a_run_without_a_trial_says_why(tmp_path):
    from balancer_id.trials import describe_log, read, segment

    sensor = SensorSettings(force_noise=0.003, accel_noise=0.03)
    model = parse_model("variable_viscosity")
    recs = synthetic_recordings(model, LIGHT, [0.1, -0.1], sensor=sensor, seed=3)
    quiet = synthetic_recordings(model, LIGHT, [0.0], sensor=sensor, seed=4)[0]
    quiet.name = "Run #3"
    path = tmp_path / "with_quiet_run.csv"
    write_recordings(path, [*recs, quiet])
    loaded = load_log(path)
    assert len(loaded.trials) == 2
    data = read(path)  # as inspect does: the log read, segmented, described
    record = describe_log(data, segment(data))
    run = next(r for r in record["runs"] if r["name"] == "Run #3")
    assert "no step trial found" in run["no_trial_reason"]
    assert any(w.startswith("Run #3: no step trial found") for w in record["warnings"])
    assert any(
        n["code"] == "segment.run_without_trial" and n["subject"] == "Run #3"
        for n in record["notes"]
    )


def test_a_log_without_acceleration_is_warned_in_inspect(tmp_path, cli):
    import json

    import numpy as np

    t = np.arange(0, 10, 0.005)
    force = np.where(t > 3, 2.45, 0.0) + np.random.default_rng(1).normal(0, 0.02, t.size)
    path = tmp_path / "force_only.csv"
    rows = "\n".join(f"{a:.3f},{b:.4f}" for a, b in zip(t, force, strict=True))
    path.write_text("Time (s),Force (N)\n" + rows + "\n", encoding="utf-8")
    _, out, _ = cli("inspect", path, "--json")
    record = json.loads(out)
    assert any(w.startswith("no acceleration channel") for w in record["warnings"])
