"""One mistake, one exit code and one message, wherever it is made (issue 21, item 4).

A bad option value is a usage error (exit 2) whether typer, the command or the library
finds it; ``--json`` prints the error object for every failure; stdout carries only the
JSON; a closed pipe is silent; Ctrl-C in a batch prints no traceback.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import SAMPLE_LOGS

LOG = SAMPLE_LOGS / "paper_balancer.csv"


def _run(*args: object, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """The real entry point (main()), as a user's shell runs it."""
    return subprocess.run(
        [sys.executable, "-m", "balancer_id", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=300,
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--bounds", "m_a=30:20"], "give MIN < MAX"),
        (["--bounds", "m_a=nan:20"], "give MIN < MAX"),
        (["--bounds", "m_a=1:inf"], "give MIN < MAX"),
        (["--model", "+"], "an empty effect name"),
        (["--model", "viscous++karnopp"], "an empty effect name"),
        (["--group-by", "runs:1-3,2-4"], "run 2 is in two groups"),
        (["--group-by", "runs:"], "give run numbers or ranges"),
        (["--group-by", "runs:1,,2"], "give run numbers or ranges"),
        (["--model", "viscous+servo"], "needs the robot's reference move"),
    ],
)
def test_a_bad_option_value_is_a_usage_error(cli, args, message):
    code, out, err = cli("fit", LOG, *args, "--json")
    assert code == 2, err
    assert message in err and "Traceback" not in err
    assert json.loads(out)["error"]["exit_code"] == 2


def test_a_binary_trajectory_is_named_not_an_internal_error(cli, tmp_path):
    traj = tmp_path / "move.csv"
    traj.write_bytes(b"time,position\n\x00\xff\xfe\x01")
    code, _, err = cli("fit", LOG, "--model", "viscous+servo", "--trajectory", traj)
    assert code == 3
    assert "move.csv: the trajectory is not a text file" in err


def test_a_trajectory_with_nan_names_its_row(cli, tmp_path):
    traj = tmp_path / "move.csv"
    traj.write_text("time,position\n0,0\n1,nan\n2,0.5\n")
    code, _, err = cli("fit", LOG, "--model", "viscous+servo", "--trajectory", traj)
    assert code == 3
    assert "row 2 of the data holds a value that is not finite" in err


@pytest.mark.parametrize(
    "args",
    [
        ["fit", LOG, "--nosuch", "--json"],  # unknown option (click)
        ["fit", "--json"],  # missing argument (click)
        ["fit", LOG, "--starts", "abc", "--json"],  # a value typer rejects
    ],
)
def test_json_usage_errors_print_the_error_object(args):
    res = _run(*args)
    assert res.returncode == 2
    error = json.loads(res.stdout)["error"]
    assert error["exit_code"] == 2 and error["kind"] == "UsageError"
    assert error["message"] in res.stderr
    assert "Traceback" not in res.stderr


def test_an_effects_file_that_prints_leaves_stdout_json(tmp_path):
    effects = tmp_path / "loud.py"
    effects.write_text(
        "print('hello from the effects file')\n"
        "from balancer_id import Effect, Param\n\n"
        "class Loud(Effect):\n"
        "    name = 'loud'\n"
        "    summary = 'a spring that talks'\n"
        "    parameters = (Param('k_loud', 1.0, 0.0, 10.0, 'N/m', 'a spring'),)\n\n"
        "    @staticmethod\n"
        "    def force(f, v, z, h, k_loud):\n"
        "        return -k_loud * z\n"
    )
    res = _run("effects", "--effects-file", effects, "--json")
    assert "hello from the effects file" in res.stderr
    assert "hello" not in res.stdout
    json.loads(res.stdout)  # stdout is only the JSON object, whatever the exit code


def test_a_closed_pipe_is_silent():
    """``balancer-id fit LOG | head -1``: no message, the status ``head`` expects."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "balancer_id", "fit", str(LOG)],  # trusted: silent on stderr
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.readline()
    proc.stdout.close()  # the reader goes away after one line
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 141
    assert err == ""


@pytest.mark.skipif(sys.platform == "win32", reason="process groups and SIGINT are POSIX")
def test_ctrl_c_in_a_batch_then_resume_prints_no_traceback(tmp_path):
    folder = tmp_path / "logs"
    folder.mkdir()
    for k in range(12):
        (folder / f"log{k}.csv").write_bytes(LOG.read_bytes())
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "balancer_id", "batch", folder, "--out", out, "--diagnose"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group: Ctrl-C reaches it all, as in a shell
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert proc.stderr is not None
    first = proc.stderr.readline()  # the batch says how many logs it starts: workers start
    os.killpg(proc.pid, signal.SIGINT)
    err = first + proc.stderr.read()
    code = proc.wait(timeout=300)
    assert "Traceback" not in err, err
    assert code in (0, 130), err  # 0: it finished before the signal arrived
    again = _run("batch", folder, "--out", out, "--resume")
    assert again.returncode == 0, again.stderr
    assert "Traceback" not in again.stderr
    assert "12 identified" in again.stderr


# -- terminal conventions (issue 20, item 6) -----------------------------------------------
def test_bare_command_shows_its_usage_once():
    res = _run()
    assert res.returncode == 2
    assert (res.stdout + res.stderr).count("Usage:") == 1


@pytest.mark.parametrize("where", ["before", "after"])
def test_quiet_is_taken_before_or_after_the_command(tmp_path, where):
    folder = tmp_path / "logs"
    folder.mkdir()
    for k in range(2):
        (folder / f"log{k}.csv").write_bytes(LOG.read_bytes())
    args = ["batch", folder, "--out", tmp_path / "out"]
    res = _run("-q", *args) if where == "before" else _run(*args, "--quiet")
    assert res.returncode == 0, res.stderr
    assert "log0.csv" not in res.stderr  # no line per log
    assert "2 identified, 0 failed" in res.stderr  # the outcome is still said


#: A model name rich cuts at 80 columns (test_simulate_physics simulates it: no kernel more).
#: 33 characters: the comparison's table is 128 columns wide with it, so rich would cut it
#: at 80 columns; built-in effects of the shared kernel (no compile, 2 s against 12 s)
LONG_NAME = "variable_viscosity+dead_time+bias"


@pytest.mark.slow
def test_without_a_terminal_no_name_is_cut():
    env = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    res = subprocess.run(
        [sys.executable, "-m", "balancer_id", "compare", str(SAMPLE_LOGS / "paper_balancer.csv"),
         "-m", f"viscous,{LONG_NAME}"],
        capture_output=True, text=True, env=env, timeout=300,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "…" not in res.stdout  # rich cut names to fit 80 columns when stdout is a pipe
    assert LONG_NAME in res.stdout


def test_one_data_row_is_called_one_row_not_blank_cells(cli, tmp_path):
    log = tmp_path / "one.csv"
    log.write_text("Time (s),Force (N),Acceleration (m/s²)\n0,1,9.8\n", encoding="utf-8")
    code, _, err = cli("inspect", log)
    assert code == 3
    assert "only 1 data row(s)" in err and "blank" not in err


@pytest.mark.parametrize(
    ("thrust", "message"),
    [
        ("1,2", "2 thrust(s) given but"),  # six trials in the log
        ("1,,2", "an empty item"),
        (",", "an empty item"),
    ],
)
def test_a_wrong_thrust_list_is_a_usage_error(cli, thrust, message):
    code, out, err = cli("fit", LOG, "--thrust", thrust, "--json")
    assert code == 2, err
    assert message in err
    assert json.loads(out)["error"]["exit_code"] == 2


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b'{"parameters": {"m_a": {"value": 15.0}, "T_a": {"value": NaN}}}', "T_a is nan"),
        (b"\xff\xfe\x00binary", "not a text file"),
    ],
)
def test_a_params_file_that_cannot_be_used_is_named(cli, tmp_path, content, message):
    params = tmp_path / "p.json"
    params.write_bytes(content)
    code, _, err = cli("fit", LOG, "--params", params)
    assert code == 2, err
    assert "p.json" in err and message in err
