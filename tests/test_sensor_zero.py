"""An offset of the acceleration is named only beyond the error of the zero it is read
against (issue 31: clean worlds were diagnosed "effect missing: bias" for the local
gravity's own error, about 0.002 m/s^2 over a second of rest)."""

from __future__ import annotations

import dataclasses

import numpy as np

from balancer_id.diagnostics.arena import within_sensor_zero, zero_stderr
from balancer_id.identify.api import fit
from balancer_id.model.spec import resolve_model
from balancer_id.read.writers import write_log
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings

TRUTH = {"m_a": 15.0, "T_a": 0.3, "D0": 60.0, "A": 0.05}


def _refit(tmp_path, offset: float):
    recs = synthetic_recordings(
        resolve_model("variable_viscosity"),
        TRUTH,
        [8.0, -8.0, 16.0, -16.0],
        sensor=SensorSettings(rate_hz=200.0),
        duration_s=4.0,
        seed=4,
    )
    if offset:  # a zero offset along gravity, after the rest the reader reads g from
        moved = []
        for rec in recs:
            acc = np.array(rec.accel, dtype=float)
            g = acc.mean(axis=0) / np.linalg.norm(acc.mean(axis=0))
            t = np.asarray(rec.time, dtype=float)
            acc += offset * np.outer(t > 0.8, g)
            moved.append(dataclasses.replace(rec, accel=acc))
        recs = moved
    path = tmp_path / f"offset_{offset:g}.csv"
    write_log(path, recs, "pasco-capstone")
    return fit(str(path), model="variable_viscosity+bias").match


def test_an_offset_within_the_zeros_error_is_no_finding(tmp_path) -> None:
    refit = _refit(tmp_path, 0.0)
    se0 = zero_stderr(refit)
    assert 0.0 < se0 < 0.01
    assert within_sensor_zero(refit, "bias", se0)


def test_a_real_offset_is_a_finding(tmp_path) -> None:
    refit = _refit(tmp_path, 0.05)
    assert abs(refit.parameters["b"].value) > 0.03
    assert not within_sensor_zero(refit, "bias", zero_stderr(refit))
    assert not within_sensor_zero(refit, "dead_time", 1.0)  # not an offset: never
