"""Fault injection: nothing the user gave is lost, nothing hangs, every failure is one line.

Each case here was a data loss, a hang or a wrong exit code found by a hostile-input run
(issue "Nothing lost, nothing hung"). Bad files are generated, never committed.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import SAMPLE_LOGS

from balancer_id.batch import LOCK_NAME, _folder_lock, run_batch
from balancer_id.errors import OutputExistsError, OutputWriteError, UsageError
from balancer_id.files import atomic_write_text, check_output
from balancer_id.simulation.synth import keep_mask

LOG = SAMPLE_LOGS / "paper_balancer.csv"


@pytest.fixture
def log_copy(tmp_path: Path) -> Path:
    """A copy of a sample log the test may try to destroy."""
    path = tmp_path / "log.csv"
    shutil.copy(LOG, path)
    return path


def _one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("balancer-id: error: ")
    assert "Traceback" not in err
    return lines[0]


# -- no user file is replaced by accident ------------------------------------------------
@pytest.mark.parametrize(
    "args",
    [
        ("inspect", "{log}", "--plot", "{log}"),
        ("inspect", "{log}", "--plot", "{link}"),  # the same file by another name
        ("fit", "{log}", "--report", "{log}", "--overwrite"),
        ("compare", "{log}", "--plot", "{log}", "--overwrite"),
        ("improve", "{log}", "--plot", "{log}"),
        ("report", "{log}", "--out", "{log}", "--overwrite"),
    ],
)
def test_an_output_that_is_an_input_is_refused(cli, log_copy, args):
    link = log_copy.parent / "hardlink.csv"
    os.link(log_copy, link)
    before = log_copy.read_bytes()
    code, _, err = cli(*(a.format(log=log_copy, link=link) for a in args))
    assert code == 2
    assert "one of the inputs" in _one_error_line(err)
    assert log_copy.read_bytes() == before


def test_an_existing_output_is_replaced_only_with_overwrite(cli, tmp_path):
    target = tmp_path / "notes.png"
    target.write_text("my notes")
    code, _, err = cli("inspect", LOG, "--plot", target)
    assert code == 2 and "--overwrite" in _one_error_line(err)
    assert target.read_text() == "my notes"
    code, _, err = cli("inspect", LOG, "--plot", target, "--overwrite")
    assert code == 0, err
    assert target.read_bytes().startswith(b"\x89PNG")


def test_a_read_only_output_is_never_replaced(cli, tmp_path):
    target = tmp_path / "keep.html"
    target.write_text("keep me")
    target.chmod(stat.S_IRUSR | stat.S_IRGRP)
    code, _, err = cli("fit", LOG, "--report", target, "--overwrite")
    assert code == 2 and "read-only" in _one_error_line(err)
    assert target.read_text() == "keep me"


def test_a_full_disk_is_one_line_and_leaves_the_old_file(tmp_path):
    mount = tmp_path / "small"
    mount.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip("cannot mount a small tmpfs here")
    try:
        target = mount / "out.txt"
        target.write_text("old")
        with pytest.raises(OutputWriteError, match="disk is full") as info:
            atomic_write_text(target, "x" * 200_000)
        assert info.value.exit_code == 3
        assert target.read_text() == "old"
        assert [p.name for p in mount.iterdir()] == ["out.txt"]  # no temporary left
    finally:
        subprocess.run(["umount", str(mount)], check=False)


def test_check_output_refuses_folders_and_special_files(tmp_path):
    with pytest.raises(UsageError, match="is a folder"):
        check_output(tmp_path, overwrite=True)
    with pytest.raises(UsageError, match="does not exist"):
        check_output(tmp_path / "missing" / "x.png")
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(UsageError, match="not a regular file"):
        check_output(fifo, overwrite=True)
    (tmp_path / "x").write_text("x")
    with pytest.raises(OutputExistsError):
        check_output(tmp_path / "x")


# -- options are checked at the door ---------------------------------------------------
@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("fit", LOG, "--g", "0"), "--g"),
        (("fit", LOG, "--g", "-9.8"), "--g"),
        (("fit", LOG, "--g", "nan"), "--g"),
        (("fit", LOG, "--starts", "0"), "--starts"),
        (("fit", LOG, "--starts", "-3"), "--starts"),
        (("improve", LOG, "--max-steps", "-1"), "--max-steps"),
        (("compare", LOG, "--model", ","), "--model"),
        (("simulate", "--rate", "0", "--out", "{tmp}/s.csv"), "--rate"),
        (("simulate", "--noise", "-1", "--out", "{tmp}/s.csv"), "--noise"),
        (("simulate", "--drop", "1.0", "--out", "{tmp}/s.csv"), "--drop"),
    ],
)
def test_bad_option_values_are_usage_errors(cli, tmp_path, args, words):
    code, _, err = cli(*(str(a).format(tmp=tmp_path) for a in args))
    assert code == 2
    assert words in _one_error_line(err)


@pytest.mark.parametrize(
    ("args", "words"), [(("--bogus",), "--bogus"), (("--starts", "abc"), "--starts")]
)
def test_click_usage_errors_are_one_line_too(args, words):
    code = "from balancer_id.cli import main; main()"
    done = subprocess.run(
        [sys.executable, "-c", code, "fit", str(LOG), *args], capture_output=True, text=True
    )
    assert done.returncode == 2
    assert words in _one_error_line(done.stderr)


def test_json_prints_one_object_on_failure(cli, tmp_path):
    code, out, err = cli("fit", tmp_path / "missing.csv", "--json")
    assert code == 3
    error = json.loads(out)["error"]
    assert error["exit_code"] == 3 and "missing.csv" in error["message"]
    assert set(error) >= {"kind", "message", "file", "line", "column"}
    _one_error_line(err)


def test_control_characters_never_reach_the_terminal(cli, tmp_path):
    evil = tmp_path / "evil\x1b[31mred.csv"
    evil.write_text("Time (s),Force (N)\n")
    code, _, err = cli("fit", evil)
    assert code in (3, 4)
    assert "\x1b" not in _one_error_line(err)


# -- nothing hangs -----------------------------------------------------------------------
@pytest.mark.parametrize("fraction", [0.5, 0.99, 1.0, 2.0])
def test_dropping_any_fraction_of_samples_terminates(fraction):
    keep = keep_mask(2000, fraction, np.random.default_rng(0))
    assert keep[0] and keep[-1]
    target = min(int(min(fraction, 1.0) * 2000), 1998)
    assert target <= (~keep).sum() <= min(target + 5, 1998)  # bursts of up to 5 samples


def test_a_pipe_in_a_batch_folder_fails_its_row_and_the_rest_go_on(tmp_path):
    folder = tmp_path / "logs"
    folder.mkdir()
    shutil.copy(LOG, folder / "good.csv")
    os.mkfifo(folder / "pipe.csv")
    result = run_batch([folder], tmp_path / "out", jobs=1)
    rows = {Path(r.file).name: r for r in result.rows}
    assert rows["good.csv"].ok
    assert not rows["pipe.csv"].ok and rows["pipe.csv"].exit_code == 3
    assert "not a regular file" in rows["pipe.csv"].error


# -- batch: one writer per folder, safe to interrupt and to resume ----------------------
def test_a_second_batch_into_the_same_folder_is_refused(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    with _folder_lock(out), pytest.raises(UsageError, match="another batch"):
        run_batch([LOG], out, jobs=1)
    # the lock file stays (never unlinked while held), empty and unlocked
    assert (out / LOCK_NAME).read_text() == ""
    with _folder_lock(out):
        pass


def test_earlier_results_need_resume_or_overwrite(tmp_path):
    out = tmp_path / "out"
    first = run_batch([LOG], out, jobs=1)
    assert first.n_ok == 1
    with pytest.raises(OutputExistsError, match="--resume"):
        run_batch([LOG], out, jobs=1)
    messages: list[str] = []
    again = run_batch([LOG], out, jobs=1, resume=True, progress=messages.append)
    assert again.n_ok == 1 and any("1 of 1 log(s) already done" in m for m in messages)
    assert again.rows[0].parameters == first.rows[0].parameters


def _batch_cmd(folder: Path, out: Path, *extra: str) -> list[str]:
    code = "from balancer_id.cli import main; main()"
    return [sys.executable, "-c", code, "batch", str(folder), "--out", str(out), *extra]


def _descendants(pid: int) -> list[int]:
    """Process ids of every live descendant of ``pid`` (Linux /proc)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            children.setdefault(int(fields[1]), []).append(int(entry.name))
    out, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc")
@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGKILL])
def test_a_stopped_batch_leaves_no_process_and_resumes(tmp_path, how):
    folder = tmp_path / "logs"
    folder.mkdir()
    for k in range(12):  # the paper's log: a fit of a second or so, a dozen still to do
        shutil.copy(LOG, folder / f"h{k:02d}.csv")
    out = tmp_path / "out"
    proc = subprocess.Popen(
        _batch_cmd(folder, out, "--jobs", "2"),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(out.glob("h*.json"))) < 1:
        time.sleep(0.2)
    assert list(out.glob("h*.json")), "no result arrived"
    workers = _descendants(proc.pid)
    os.kill(proc.pid, how)
    proc.wait(timeout=60)
    if how == signal.SIGTERM:
        assert proc.returncode == 130
        rows = (out / "summary.csv").read_text().splitlines()[1:]
        assert len(rows) == 12  # every log has a row, finished or not
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(Path(f"/proc/{p}").exists() for p in workers):
        time.sleep(0.2)
    alive = [p for p in workers if Path(f"/proc/{p}").exists()]
    assert not alive, f"processes outlived the batch: {alive}"
    done_before = len(list(out.glob("h*.json")))
    resumed = subprocess.run(
        _batch_cmd(folder, out, "--jobs", "2", "--resume"), capture_output=True, text=True
    )
    assert resumed.returncode == 0, resumed.stderr
    assert f"{done_before} of 12 log(s) already done" in resumed.stderr
    assert (out / "summary.csv").read_text().count(",ok,") == 12


def test_escape_sequences_from_a_log_are_shown_escaped(cli, tmp_path):
    from balancer_id.cli import _printable

    shown = _printable({"runs": [{"name": "Run \x1b[2J#1"}], "n": 3})
    assert shown == {"runs": [{"name": "Run \\x1b[2J#1"}], "n": 3}


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--thrust", "inf"], "--thrust inf: give a finite value"),
        (["--thrust", "1e308"], "--thrust 1e+308: give a finite value"),
        (["--noise", "1e308"], "--noise 1e+308: give a finite value"),
        (["--force-noise", "1e308"], "--force-noise 1e+308: give a finite value"),
        (["--rate", "1e308"], "--rate 1e+308: give a finite value"),
        (["--rest", "1e308"], "--rest 1e+308: give a finite value"),
        (["--duration", "1e308"], "--duration 1e+308: give a finite value"),
        (["--seed", "-1"], "--seed -1: give a seed >= 0"),
        (["--rate", "100000", "--duration", "86400"], "samples; shorten the runs"),
    ],
)
def test_simulate_refuses_values_that_would_write_no_finite_log(cli, tmp_path, args, message):
    out = tmp_path / "sim.csv"
    code, _, err = cli("simulate", *args, "--out", out)
    assert code == 2 and message in " ".join(err.split())
    assert not out.exists()


def test_simulate_never_writes_over_its_params_file(cli, tmp_path):
    params = tmp_path / "model.json"
    params.write_text('{"model": "variable_viscosity", "parameters": {"m_a": {"value": 15.1}}}')
    before = params.read_bytes()
    code, _, err = cli("simulate", "--params", params, "--out", params, "--overwrite")
    assert code == 2 and "model.json" in err
    assert params.read_bytes() == before


def test_fit_refuses_an_absurd_number_of_starts(cli):
    from conftest import SAMPLE_LOGS

    code, _, err = cli("fit", SAMPLE_LOGS / "paper_balancer.csv", "--starts", "100000")
    assert code == 2 and "at most 1000 starts" in err
