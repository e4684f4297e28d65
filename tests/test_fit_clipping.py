"""A clipped accelerometer is the sensor's, and its fit is not trusted (issue 31.4); a
quantized sensor's outer levels are no clipping."""

from __future__ import annotations

import dataclasses

import numpy as np

from balancer_id.identify.api import fit
from balancer_id.model.spec import resolve_model
from balancer_id.read.validate import clipped_mask
from balancer_id.read.writers import write_log
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings


def test_clipped_motion_makes_the_fit_untrusted_and_says_why(tmp_path) -> None:
    recs = synthetic_recordings(
        resolve_model("variable_viscosity"),
        {"m_a": 15.0, "T_a": 0.3, "D0": 60.0, "A": 0.05},
        [8.0, -8.0, 16.0, -16.0],
        sensor=SensorSettings(rate_hz=200.0, tilt_deg=5.0),
        duration_s=4.0,
        seed=5,
    )
    # the range 0.15 m/s^2 above g: the upward steps' first 0.2-0.5 m/s^2 are clipped
    top = 9.8 + 0.15
    clipped = [dataclasses.replace(r, accel=np.clip(r.accel, -top, top)) for r in recs]
    path = tmp_path / "clipped.csv"
    write_log(path, clipped, "pasco-capstone")
    out = fit(str(path)).to_dict()
    assert out["trusted"] is False
    errors = [n for n in out["notes"] if n["severity"] == "error"]
    assert any(n["code"] == "read.sensor_limit" and "clipped" in n["text"] for n in errors)


def test_quantized_levels_are_not_a_range() -> None:
    rng = np.random.default_rng(0)
    # a 0.2 m/s^2 quantized sensor at rest: its outer levels repeat, they are no clip
    x = np.round((9.3 + rng.normal(0, 0.1, 4000)) / 0.2) * 0.2
    assert not clipped_mask(x).any()
    # clipped at 9.6 m/s^2 while the signal goes well past it: found
    y = 9.3 + rng.normal(0, 0.02, 4000) + np.where(np.arange(4000) % 800 < 100, 1.0, 0.0)
    assert clipped_mask(np.minimum(y, 9.6)).sum() >= 400
