"""Batch faults of issue 13: folders and files it may not read, user effects that raise or
exit inside a worker. Each is a failed row with its exit code; the other logs go on."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from balancer_id.batch import run_batch
from balancer_id.model import parse_model
from balancer_id.simulation.synth import write_synthetic_log

TRUE = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}

#: A user effect whose force raises when the drive force exceeds 5 N (the log with the
#: larger thrusts reaches it, the other does not).
FRAGILE = '''
from balancer_id import Effect, Param


class Fragile(Effect):
    """A hose that tears when pulled hard."""

    name = "fragile"
    summary = "a spring that raises beyond 5 N of drive force"
    parameters = (Param("k_f", 1.0, 0.0, 50.0, "N/m", "stiffness"),)
    example = {"k_f": 1.0}

    @staticmethod
    def force(f, v, z, h, k_f):
        if abs(f) > 5.0:
            raise ValueError("hose torn")
        return -k_f * z
'''


@pytest.fixture(scope="module")
def two_logs(tmp_path_factory):
    """A folder with a gentle log (thrusts up to 2.45 N) and a hard one (up to 7.35 N)."""
    root = tmp_path_factory.mktemp("faults") / "logs"
    (root / "sub").mkdir(parents=True)
    model = parse_model("variable_viscosity")
    write_synthetic_log(root / "gentle.csv", model, TRUE, [2.45, -2.45, 1.2], seed=1,
                        duration_s=4)  # fmt: skip
    write_synthetic_log(root / "sub" / "hard.csv", model, TRUE, [2.45, -4.9, 7.35], seed=2,
                        duration_s=4)  # fmt: skip
    return root


def _rows(result):
    return {Path(r.file).name: r for r in result.rows}


def test_a_folder_that_cannot_be_entered_is_a_failed_row(two_logs, tmp_path, monkeypatch):
    real = os.scandir
    sub = str(two_logs / "sub")

    def scandir(path="."):
        if os.fspath(path) == sub:
            raise PermissionError(13, "Permission denied", os.fspath(path))
        return real(path)

    monkeypatch.setattr(os, "scandir", scandir)
    result = run_batch([two_logs], tmp_path / "out", jobs=1)
    rows = _rows(result)
    assert rows["gentle.csv"].ok
    assert not rows["sub"].ok and rows["sub"].exit_code == 3
    assert "cannot be listed" in rows["sub"].error
    assert result.exit_code == 3


def test_a_given_folder_that_cannot_be_entered_is_a_failed_row(two_logs, tmp_path, monkeypatch):
    real = os.scandir
    top = str(two_logs)

    def scandir(path="."):
        if os.fspath(path) == top:
            raise PermissionError(13, "Permission denied", os.fspath(path))
        return real(path)

    monkeypatch.setattr(os, "scandir", scandir)
    result = run_batch([two_logs], tmp_path / "out", jobs=1)
    assert [(Path(r.file).name, r.exit_code) for r in result.rows] == [(two_logs.name, 3)]
    assert result.exit_code == 3


def test_a_file_that_cannot_be_read_is_a_failed_row(two_logs, tmp_path, monkeypatch):
    real = os.open
    hard = str(two_logs / "sub" / "hard.csv")

    def opener(path, *args, **kwargs):
        if os.fspath(path) == hard:
            raise PermissionError(13, "Permission denied", os.fspath(path))
        return real(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", opener)
    result = run_batch([two_logs], tmp_path / "out", jobs=1)
    rows = _rows(result)
    assert rows["gentle.csv"].ok
    assert not rows["hard.csv"].ok and rows["hard.csv"].exit_code == 3
    assert "hard.csv" in rows["hard.csv"].error and "ermission" in rows["hard.csv"].error
    assert "internal error" not in rows["hard.csv"].error


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_user_effect_that_raises_fails_its_row_and_the_rest_go_on(two_logs, tmp_path, jobs):
    effects = tmp_path / "fragile.py"
    effects.write_text(FRAGILE)
    logs = [two_logs / "gentle.csv", two_logs / "sub" / "hard.csv"]
    result = run_batch(logs, tmp_path / "out", model="variable_viscosity+fragile",
                       effects_files=[effects], jobs=jobs)  # fmt: skip
    rows = _rows(result)
    assert rows["gentle.csv"].ok, rows["gentle.csv"].error
    assert not rows["hard.csv"].ok and rows["hard.csv"].exit_code == 4
    assert "hose torn" in rows["hard.csv"].error and str(effects) in rows["hard.csv"].error
    assert result.exit_code == 3


def test_user_code_that_exits_inside_a_worker_is_a_failed_row(two_logs, tmp_path, monkeypatch):
    import balancer_id.identify.api as api

    real = api.fit

    def fit(paths, **kwargs):
        if Path(paths[0]).name == "hard.csv":
            raise SystemExit(7)  # what a user effect's sys.exit() raises
        return real(paths, **kwargs)

    monkeypatch.setattr(api, "fit", fit)
    effects = tmp_path / "hose.py"
    shutil.copy(Path(__file__).parents[1] / "examples" / "effects" / "hose_spring.py", effects)
    result = run_batch([two_logs], tmp_path / "out", model="variable_viscosity",
                       effects_files=[effects], jobs=1)  # fmt: skip
    rows = _rows(result)
    assert rows["gentle.csv"].ok
    assert not rows["hard.csv"].ok and rows["hard.csv"].exit_code == 4
    assert "exit(7)" in rows["hard.csv"].error


def test_the_batch_key_tells_long_trajectory_tables_apart(tmp_path):
    import numpy as np

    from balancer_id.batch.inputs import request_key
    from balancer_id.segment.move import TabulatedMove

    log = tmp_path / "a.csv"
    log.write_text("x")
    t = np.linspace(0.0, 5.0, 5001)
    one = TabulatedMove(t, 0.2 * t / 5.0)
    other = TabulatedMove(t, one.position.copy())
    other.position[2500] += 1e-3  # numpy's repr elides the middle of a long array
    assert repr(one) == repr(other)
    keys = {request_key(str(log), "viscous+servo", None, None, (), move) for move in (one, other)}
    assert len(keys) == 2



def test_batch_progress_never_sends_control_characters_to_the_terminal(cli, tmp_path):
    from balancer_id.cli.progress import batch_progress

    shown: list[str] = []
    with batch_progress(shown.append) as (say, _):
        say("[1/1] run '\x1b]0;pwned\x07\x1b[2J' ok")
    assert shown and "\x1b" not in shown[0] and "\x07" not in shown[0]
    assert "pwned" in shown[0]
    # end to end: a log named with escapes
    bad = tmp_path / "evil\x1b]0;pwned\x07\x1b[2J.csv"
    bad.write_text("Time (s),Force (N)\n0,1\n", encoding="utf-8")
    code, _, err = cli("batch", bad, "--out", tmp_path / "out")
    assert code == 3 and "\x1b" not in err and "\x07" not in err


def test_batch_never_replaces_a_file_it_did_not_write(cli, tmp_path):
    from conftest import SAMPLE_LOGS

    out = tmp_path / "out"
    out.mkdir()
    log = tmp_path / "log0.csv"
    log.write_bytes((SAMPLE_LOGS / "paper_balancer.csv").read_bytes())
    theirs = out / "log0.json"
    theirs.write_text('{"my": "notes"}', encoding="utf-8")
    for extra in ([], ["--overwrite"]):
        code, _, err = cli("batch", log, "--out", out, *extra)
        assert code == 2 and "log0.json is not a result of balancer-id" in err
        assert theirs.read_text(encoding="utf-8") == '{"my": "notes"}'


def test_the_batch_lock_is_never_followed_through_a_symlink_nor_removed(cli, tmp_path):
    from conftest import SAMPLE_LOGS

    from balancer_id.batch.inputs import LOCK_NAME

    victim = tmp_path / "victim.txt"
    victim.write_text("precious", encoding="utf-8")
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_NAME).symlink_to(victim)
    code, _, err = cli("batch", SAMPLE_LOGS / "paper_balancer.csv", "--out", out)
    assert code == 2 and "symbolic link" in err
    assert victim.read_text(encoding="utf-8") == "precious"
    (out / LOCK_NAME).unlink()
    code, _, err = cli("batch", SAMPLE_LOGS / "paper_balancer.csv", "--out", out)
    assert code == 0, err
    assert (out / LOCK_NAME).is_file() and not (out / LOCK_NAME).is_symlink()
