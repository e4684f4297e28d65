"""A saved model validated on new logs: a verdict with its reasons (issue 20, item 4)."""

from __future__ import annotations

import json

import pytest
from conftest import PAPER, SAMPLE_LOGS

import balancer_id as bid
from balancer_id.errors import UsageError
from balancer_id.identify import resolve_model
from balancer_id.simulation.synth import SensorSettings, write_synthetic_log

THRUSTS = [2.45, -2.45, 4.9, -4.9]


@pytest.fixture(scope="module")
def identified():
    """The paper balancer identified from the bundled log."""
    return bid.fit(SAMPLE_LOGS / "paper_balancer.csv", model="variable_viscosity")


def _new_log(tmp_path, values, seed):
    path = tmp_path / f"new{seed}.csv"
    write_synthetic_log(
        path, resolve_model("variable_viscosity"), values, THRUSTS,
        sensor=SensorSettings(accel_noise=0.03, force_noise=0.03), seed=seed, duration_s=4,
    )  # fmt: skip
    return path


def test_the_model_holds_on_new_logs_of_the_same_balancer(identified, tmp_path):
    verdict = bid.validate(identified, _new_log(tmp_path, PAPER, seed=7))
    assert verdict.holds, verdict.reasons
    assert verdict.verdict == "holds" and not verdict.reasons
    assert {t["name"] for t in verdict.tests} == {"level", "whiteness", "thrust_correlation"}
    assert verdict.fit_percent > 70


def test_a_heavier_payload_is_caught_with_its_reason(identified, tmp_path):
    heavier = {**PAPER, "m_a": PAPER["m_a"] * 1.5}  # the same balancer, 50 % more mass
    verdict = bid.validate(identified, _new_log(tmp_path, heavier, seed=8))
    assert not verdict.holds
    assert any("noise floor" in r for r in verdict.reasons)
    assert "does not hold" in verdict.lines()[0]


def test_compare_params_prints_the_verdict(cli, identified, tmp_path):
    saved = tmp_path / "model.json"
    saved.write_text(json.dumps(identified.to_dict()))
    new = _new_log(tmp_path, {**PAPER, "m_a": PAPER["m_a"] * 1.5}, seed=9)
    code, out, err = cli("compare", new, "--params", saved)
    assert code == 0, err
    assert "model variable_viscosity does not hold on these logs" in out
    assert "FAIL level" in out
    code, out, err = cli("compare", new, "--params", saved, "--json")
    data = json.loads(out)
    assert data["validation"]["verdict"] == "does not hold"
    assert data["validation"]["reasons"]


def test_values_without_a_model_are_refused():
    with pytest.raises(UsageError, match="give the model's spec"):
        bid.validate({"m_a": 15.0}, SAMPLE_LOGS / "paper_balancer.csv")
    with pytest.raises(UsageError, match="no value for T_a"):
        bid.validate({"m_a": 15.0}, SAMPLE_LOGS / "paper_balancer.csv", model="viscous")
