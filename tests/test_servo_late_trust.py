"""A robot servo that acts late moves the servo's values: they lose their trust (issue
31: a servo 30 ms late read as a 36 % stiffer one, k_r 204 +- 0.5 N/m against 150, marked
trusted with exit 0, while the delay was named beside it)."""

from __future__ import annotations

import json

MOVE = "trapezoid:distance=0.2,speed=0.1,accel=0.5"
HELD = ["--fix", "m_a=15.1", "--fix", "T_a=0.33", "--fix", "D0=6", "--fix", "A=0.4"]
TRUTH = ["--param", "m_a=15.1", "--param", "T_a=0.33", "--param", "D0=6", "--param", "A=0.4"]


def _robot(cli, tmp_path, delay: float):
    path = tmp_path / f"robot_{delay:g}.csv"
    code, _, err = cli(
        "simulate", "--model", "variable_viscosity+servo", "--thrust", "0",
        "--trajectory", f"{MOVE},start=2.0", *TRUTH, "--param", "k_r=150",
        "--param", "c_r=100", "--servo-delay", str(delay), "--seed", "1", "--out", path, "-q",
    )  # fmt: skip
    assert code == 0, err
    code, out, err = cli(
        "fit", path, "--model", "variable_viscosity+servo", "--trajectory", MOVE, *HELD,
        "--json", "--no-cache",
    )  # fmt: skip
    return code, json.loads(out)


def test_a_late_servo_takes_the_trust_of_the_values_it_moves(cli, tmp_path):
    code, result = _robot(cli, tmp_path, 0.03)
    assert code == 5 and result["trusted"] is False
    k_r = result["parameters"]["k_r"]
    assert k_r["value"] > 180 and k_r["trusted"] is False  # the stiffer servo it reads
    assert any("servo acts late" in w for w in k_r["untrusted_because"])
    assert abs(result["servo_delay"]["tau_r_s"] - 0.03) < 0.005


def test_a_servo_acting_at_once_keeps_its_trust(cli, tmp_path):
    code, result = _robot(cli, tmp_path, 0.0)
    assert code == 0 and result["trusted"] is True, result.get("untrusted_because")
    assert abs(result["parameters"]["k_r"]["value"] / 150 - 1) < 0.05
