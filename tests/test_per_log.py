"""Fits that share across logs (issue 33, ``fit LOG... --per-log m_a``, ``batch --per-log``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from balancer_id.errors import UsageError
from balancer_id.identify.api import fit
from balancer_id.model import parse_model
from balancer_id.simulation.synth import SensorSettings, write_synthetic_log

MODEL = parse_model("variable_viscosity")
COMMON = {"T_a": 0.33, "D0": 6.0, "A": 0.4}
THRUSTS = [2.45, -2.45, 4.9, -7.35]


def _plant(folder, masses, seed):
    paths = []
    for k, m in enumerate(masses):
        path = folder / f"log{k}.csv"
        write_synthetic_log(
            path, MODEL, {"m_a": m, **COMMON}, THRUSTS, duration_s=6.0,
            sensor=SensorSettings(tilt_deg=7.0), seed=seed + k,
        )
        paths.append(str(path))
    return paths


@pytest.fixture(scope="module")
def payloads(tmp_path_factory):
    """Three logs of one balancer type with payloads differing (m_a 12, 15, 19 kg)."""
    masses = [12.0, 15.0, 19.0]
    return masses, _plant(tmp_path_factory.mktemp("payloads"), masses, 11)


def test_each_log_gets_its_own_mass_and_the_shared_ones_are_pinned_by_all(payloads):
    masses, paths = payloads
    result = fit(paths, per_log=["m_a"])
    for own, m in zip(result.own, masses, strict=True):
        # noise 0.03 m/s^2 over ~4 trials: m_a to well under 1 % (its stderr ~0.2 %)
        assert abs(own["m_a"].value / m - 1) < 0.01
        assert abs(own["m_a"].value - m) < 4 * own["m_a"].stderr
    for name, truth in COMMON.items():
        shared = result.shared[name]
        assert abs(shared.value - truth) < 4 * shared.stderr
        alone = np.median([s[name].stderr for s in result.separate])
        assert shared.stderr < alone  # three logs pin a shared value better than one
    assert result.supported == "partly shared"
    doc = result.to_dict()
    assert doc["supported"] == "partly shared" and len(doc["logs"]) == 3
    assert doc["comparison"]["all shared"]["bic"] > doc["comparison"]["partly shared"]["bic"]
    held = {k: v["held_out_rmse"] for k, v in doc["comparison"].items()}
    assert held["partly shared"] < held["all shared"]  # one mass cannot predict three
    assert "&lt;- supported" in result._repr_html_() and "verdict:" in result.summary()


def test_equal_payloads_are_shared(tmp_path):
    paths = _plant(tmp_path, [15.0, 15.0, 15.0], 21)
    result = fit(paths, per_log=["m_a"], held_out=False)
    assert result.supported == "all shared"
    assert "do not differ in m_a" in result.verdict()


def test_per_log_needs_two_logs_and_a_parameter_of_the_model(payloads, cli):
    _, paths = payloads
    with pytest.raises(UsageError, match="two or more logs"):
        fit(paths[:1], per_log=["m_a"])
    code, _, err = cli("fit", *paths[:2], "--per-log", "X")
    assert code == 2 and "--per-log X: not a parameter" in err
    code, out, err = cli("fit", *paths, "--per-log", "m_a")
    assert code == 0, err
    assert "each log's own" in out and "<- supported" in out and "verdict:" in out


def test_batch_per_log_writes_the_shared_fit_and_the_fleet_section(payloads, tmp_path, cli):
    _, paths = payloads
    out = tmp_path / "out"
    report = tmp_path / "fleet.html"
    code, _, err = cli(
        "batch", *paths, "--out", out, "--per-log", "m_a", "--jobs", "1", "--report", report
    )
    assert code == 0, err
    doc = json.loads((out / "shared_fit.json").read_text())
    assert doc["supported"] == "partly shared" and doc["left_out"] == []
    html = report.read_text()
    assert "Shared over the fleet" in html and "width alone" in html
