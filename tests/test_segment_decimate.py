"""Decimation of high-rate trials for fitting (anti-aliased, zero phase, integer factor)."""

from __future__ import annotations

import numpy as np
import pytest

from balancer_id.segment.decimate import decimate_trial, decimation_factor
from balancer_id.segment.trial import Trial


def _trial(rate: float, seconds: float = 4.0, alias_amp: float = 0.0, seed: int = 0) -> Trial:
    """A first-order rise of 0.3 m/s^2 (T = 0.3 s) at 1 s, with noise and a fast tone."""
    rng = np.random.default_rng(seed)
    t = 10.0 + np.arange(round(seconds * rate)) / rate
    rise = 0.3 * -np.expm1(-np.clip(t - 11.0, 0.0, None) / 0.3)
    tone = alias_amp * np.sin(2 * np.pi * 0.299 * rate * t)  # aliases to a low frequency
    accel = rise + tone + rng.normal(0.0, 0.03, t.size)
    force = 4.9 * (t >= 11.0) + rng.normal(0.0, 0.03, t.size)
    return Trial(0, "Run 1", 11.0, t[0], t[-1], 4.9, "up", t, accel, force)


@pytest.mark.parametrize(
    ("rate", "factor"), [(20.0, 1), (200.0, 1), (399.0, 1), (400.0, 2), (700.0, 3), (10000.0, 50)]
)
def test_factor_brings_the_rate_to_200_400_hz(rate, factor):
    assert decimation_factor(rate) == factor
    assert 200.0 <= rate / factor < 400.0 or factor == 1


def test_factor_of_a_rate_that_is_not_finite_is_one():
    assert decimation_factor(float("nan")) == 1


def test_10khz_trial_is_decimated_without_alias_or_delay():
    trial = _trial(10000.0, alias_amp=0.5)
    before = trial.accel.copy()
    out, info = decimate_trial(trial)
    assert (info.factor, info.rate_in_hz, info.rate_out_hz) == (
        50,
        pytest.approx(1e4),
        pytest.approx(200.0),
    )
    assert "200 Hz" in info.reason and out.notes[-1] == info.reason
    np.testing.assert_array_equal(out.time, trial.time[::50])  # the log's own sample times
    np.testing.assert_array_equal(trial.accel, before)  # the input is left alone
    clean = 0.3 * -np.expm1(-np.clip(out.time - 11.0, 0.0, None) / 0.3)
    # Plain subsampling keeps the 0.5 m/s^2 tone (aliased); the filter removes it, and
    # the noise averages down (0.03 / sqrt(50 / 2)); a delay would show at the onset.
    assert np.max(np.abs(trial.accel[::50] - clean)) > 0.3
    assert np.max(np.abs(out.accel - clean)) < 0.03
    assert out.force is not None and out.force.shape == out.time.shape
    onset = out.time[np.argmax(out.force > 2.45)]
    assert abs(onset - 11.0) <= 1.0 / 200.0


def test_low_rate_trial_is_returned_as_is():
    trial = _trial(200.0)
    out, info = decimate_trial(trial)
    assert out is trial and info.factor == 1 and "no decimation" in info.reason


def test_trial_with_nan_is_not_decimated():
    trial = _trial(2000.0)
    trial.accel[5] = np.nan
    out, info = decimate_trial(trial)
    assert out is trial and info.factor == 1 and "non-finite" in info.reason


def test_fit_says_at_which_rate_it_fitted_a_decimated_log(cli, tmp_path):
    import json

    from balancer_id.model import parse_model
    from balancer_id.simulation.synth import SensorSettings, write_synthetic_log

    path = tmp_path / "fast.csv"
    write_synthetic_log(
        path, parse_model("variable_viscosity"), {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4},
        [2.45, -4.9, 7.35], sensor=SensorSettings(rate_hz=1000.0), seed=3, duration_s=3,
    )  # fmt: skip
    code, out, err = cli("fit", path, "--json")
    assert code == 0, err
    data = json.loads(out)
    for trial in data["trials"]:
        assert trial["fit_rate_hz"] == pytest.approx(200.0, rel=1e-3)
        assert trial["decimated_from_hz"] == pytest.approx(1000.0, rel=1e-3)
    assert [n["text"] for n in data["notes"] if n["code"] == "fit.decimated"] == [
        f"{len(data['trials'])} trials fitted at 200 Hz, decimated from 1000 Hz "
        "(factor 5, anti-aliased)"
    ]
    code, out, err = cli("fit", path)
    assert code == 0, err
    assert "fitted at 200 Hz, decimated from 1000 Hz" in " ".join(out.split())
