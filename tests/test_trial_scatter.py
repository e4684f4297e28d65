"""Standard errors from the scatter between trials (issue 31): a thrust level read from a
noisy force pulls a whole trial, which the noise within it does not show."""

from __future__ import annotations

from balancer_id.identify.api import fit
from balancer_id.identify.trial_scatter import trial_scatter_stderr
from balancer_id.model.spec import resolve_model
from balancer_id.read.writers import write_log
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings

TRUTH = {"m_a": 10.0, "T_a": 0.5, "D0": 40.0, "A": 0.05}


def _fit(tmp_path, force_noise: float, seed: int):
    recs = synthetic_recordings(
        resolve_model("variable_viscosity"),
        TRUTH,
        [5.0, -5.0, 10.0, -10.0, 15.0, -15.0],
        sensor=SensorSettings(rate_hz=100.0, accel_noise=0.004, force_noise=force_noise),
        duration_s=4.0,
        seed=seed,
    )
    path = tmp_path / f"noisy_force_{seed}.csv"
    write_log(path, recs, "pasco-capstone")
    return fit(str(path))


def test_scatter_widens_where_force_noise_pulls_whole_trials(tmp_path) -> None:
    # a precise accelerometer (0.004 m/s^2) and a force 0.3 N noisy on 5-15 N steps:
    # each hold's level is off by its mean noise, a pull the whole trial shares
    result = _fit(tmp_path, 0.3, seed=1)
    scatter = trial_scatter_stderr(result.match)
    assert scatter is not None and set(scatter) == {"m_a", "T_a", "D0", "A"}
    # wider than the noise within the trials says: the levels' errors, carried in from
    # the force's noise (level_errors), take most of it; the scatter widens the rest
    ratio = result.metrics["level_error_ratio"] * max(result.metrics["trial_scatter_ratio"], 1)
    assert ratio > 1.2
    for name, se in scatter.items():  # every standard error at least the scatter's
        assert result.match.parameters[name].stderr >= se * (1 - 1e-12)
    assert any("noisy force" in str(n) for n in result.all_notes)


def test_scatter_needs_three_trials(tmp_path) -> None:
    from balancer_id.identify.matching import match_trials

    result = _fit(tmp_path, 0.01, seed=2)
    two = match_trials(
        result.match.model, result.match.data.trials[:2], start=result.values, n_starts=1
    )
    assert trial_scatter_stderr(two) is None  # two trials' scatter says too little
    assert trial_scatter_stderr(result.match) is not None
