"""The command line end to end: contract JSON, exit codes, one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from conftest import EXAMPLES, SAMPLE_LOGS

from balancer_id.model.effects import BUILTIN_EFFECTS

THRUSTS = "2.45,-4.9,7.35"


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """A small simulated Capstone log written by the simulate command."""
    from typer.testing import CliRunner

    from balancer_id.cli import app

    path = tmp_path_factory.mktemp("sim") / "sim.csv"
    res = CliRunner().invoke(
        app,
        [
            "simulate",
            "--thrust",
            THRUSTS,
            "--out",
            str(path),
            "--duration",
            "5",
            "--seed",
            "4",
            "--tilt",
            "20",
            "--drop",
            "0.002",
            "--json",
        ],
    )
    assert res.exit_code == 0, res.stderr
    return path


def test_effects_lists_every_effect_with_units(cli):
    code, out, _ = cli(
        "effects", "--json", "--effects-file", EXAMPLES / "effects" / "hose_spring.py"
    )
    assert code == 0
    effects = {e["name"]: e for e in json.loads(out)["effects"]}
    assert set(BUILTIN_EFFECTS) | {"base", "hose_spring"} <= set(effects)
    for e in effects.values():
        assert all(p["unit"] and p["min"] <= p["value"] <= p["max"] for p in e["parameters"])
    assert "hose_spring.py" in effects["hose_spring"]["origin"]


def test_simulate_then_inspect_finds_the_trials(cli, simulated):
    code, out, err = cli("inspect", simulated, "--json")
    assert code == 0, err
    info = json.loads(out)
    assert info["format"] == "pasco-capstone"
    assert info["sample_rate_hz"] == pytest.approx(200.0, rel=0.01)
    trials = info["trials"]
    assert [round(t["thrust_N"], 1) for t in trials] == [2.5, -4.9, 7.3] or [
        round(t["thrust_N"], 2) for t in trials
    ] == pytest.approx([2.45, -4.9, 7.35], abs=0.05)
    for t in trials:
        assert t["direction"] == ("up" if t["thrust_N"] > 0 else "down")
        assert t["t_step"] == pytest.approx(2.0, abs=0.011)  # onset within 2 samples
        assert t["t_start"] < t["t_step"] < t["t_end"]


def test_inspect_plot_is_written(cli, simulated, tmp_path):
    png = tmp_path / "inspect.png"
    code, _, err = cli("inspect", simulated, "--plot", png)
    assert code == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_fit_json_follows_the_contract(cli, simulated):
    code, out, err = cli("fit", simulated, "--json")
    assert code == 0, err
    res = json.loads(out)
    assert res["model"] == "variable_viscosity"
    assert set(res["parameters"]) == {"m_a", "T_a", "D0", "A"}
    assert all({"value", "stderr"} <= set(p) for p in res["parameters"].values())
    assert set(res["classic"]) >= {"m_a", "T_a"}
    assert len(res["trials"]) == 3
    assert {"index", "thrust_N", "direction", "rmse"} <= set(res["trials"][0])
    assert res["parameters"]["m_a"]["value"] == pytest.approx(15.0, rel=0.03)


def test_fit_with_fix_and_table_output(cli, simulated):
    # the simulated balancer's own model (viscous alone lacks its A, and a model that
    # misses what the trials show is not trusted: exit 5, test_trusted.py)
    code, out, err = cli("fit", simulated, "--fix", "m_a=15.1", "--model", "variable_viscosity")
    assert code == 0, err
    assert "m_a" in out and "held" in out


def test_thrusts_that_do_not_match_the_trials_are_a_usage_error(cli, simulated):
    code, _, err = cli("fit", simulated, "--thrust", "2.45,4.9")
    assert code == 2  # the option's value is wrong (CONTRACT.md), not the log
    assert err.count("\n") == 1 and "sim.csv" in err


def test_unknown_effect_is_a_usage_error(cli, simulated):
    code, _, err = cli("fit", simulated, "--model", "variable_viscosity+warp_drive")
    assert code == 2
    assert "unknown effect 'warp_drive'" in err and "karnopp" in err


def test_bad_fix_is_a_usage_error(cli, simulated):
    code, _, err = cli("fit", simulated, "--fix", "m_a")
    assert code == 2 and "NAME=VALUE" in err


def test_unreadable_log_exits_3_with_one_line(cli, tmp_path):
    bad = tmp_path / "garbage.csv"
    bad.write_text("time,force\n0.0,abc\n0.005,1.0\n")
    code, _out, err = cli("fit", bad)
    assert code == 3
    assert "garbage.csv" in err and err.count("\n") == 1 and "Traceback" not in err


def test_real_log_without_steps_exits_4(cli):
    from conftest import REAL_LOGS

    log = REAL_LOGS / "phyphox_accel_with_g_comma_100Hz_andrefcmoraes_phys.i_Raw_Data.csv"
    if not log.exists():
        pytest.skip("shared/real_logs not present")
    code, out, err = cli("inspect", log, "--json")
    assert code in (0, 4)
    if code == 4:
        assert "no step trial found" in err
        assert json.loads(out)["trials"] == []


def test_simulate_refuses_to_overwrite(cli, simulated):
    code, _, err = cli("simulate", "--out", simulated, "--thrust", "2.45")
    assert code == 2 and "exists" in err


def test_help_is_quick():
    res = subprocess.run(
        [sys.executable, "-c", "import sys, balancer_id.cli; print(sorted(sys.modules))"],
        capture_output=True,
        text=True,
        check=True,
    )
    heavy = {"numba", "scipy", "pandas", "lmfit", "matplotlib"}
    loaded = {m.split(".")[0] for m in eval(res.stdout)}
    assert not heavy & loaded


def test_sample_logs_are_fitted_by_the_readme_command(cli):
    code, out, err = cli("fit", SAMPLE_LOGS / "paper_balancer.csv", "--json")
    assert code == 0, err
    assert json.loads(out)["metrics"]["nrmse_fit_percent"] > 50


def test_a_second_identical_fit_comes_from_the_cache(cli, simulated, results_cache):
    from balancer_id import cache

    tmp_path = results_cache
    first = cli("fit", simulated, "--json")
    assert first[0] == 0
    entries = list((tmp_path / "results").glob("*.json"))
    assert len(entries) == 1
    # a cached entry is what the second run prints: prove it by planting a marker in it
    # (a whole entry, with its checksum: the cache serves only unaltered entries)
    key = entries[0].stem
    planted = json.loads(entries[0].read_text())["result"]
    planted["model"] = "from-the-cache"
    entries[0].unlink()
    cache.store(key, planted)
    assert json.loads(cli("fit", simulated, "--json")[1])["model"] == "from-the-cache"
    # an entry altered behind the cache's back is not served: it is recomputed
    tampered = json.loads(entries[0].read_text())
    tampered["result"]["model"] = "tampered"
    entries[0].write_text(json.dumps(tampered))
    assert json.loads(cli("fit", simulated, "--json")[1])["model"] == "variable_viscosity"
    entries[0].write_text('{"schema": 2, "key": "cut in the mid')
    assert json.loads(cli("fit", simulated, "--json")[1])["model"] == "variable_viscosity"
    # other options, or --no-cache, compute anew
    assert json.loads(cli("fit", simulated, "--json", "--no-cache")[1])["model"] == (
        "variable_viscosity"
    )
    assert json.loads(cli("fit", simulated, "--json", "--fix", "m_a=15")[1])["model"] == (
        "variable_viscosity"
    )
    assert cache.result_key("fit", [tmp_path / "missing.csv"], {}) is None


def test_a_force_only_log_cannot_be_identified(cli, tmp_path):
    rows = ["Time (s),Force (N)"]
    for k in range(1600):
        t = k * 0.005
        rows.append(f"{t:.3f},{(-2.45 if t > 2 else 0.0) + 0.01 * ((k * 7) % 5 - 2):.3f}")
    log = tmp_path / "force_only.csv"
    log.write_text("\n".join(rows) + "\n")
    code, out, _ = cli("inspect", log, "--json")
    assert code == 0 and len(json.loads(out)["trials"]) == 1
    code, _, err = cli("fit", log)
    assert code == 4
    assert "force_only.csv" in err and "acceleration" in err and err.count("\n") == 1
