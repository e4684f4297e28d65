"""``run_batch``: one fit per log in parallel; bad logs are rows, never the end of the batch."""

from __future__ import annotations

import csv
import json
import operator
import os
import sys
from functools import partial
from pathlib import Path

import numpy as np
import pytest

from balancer_id.batch import BatchResult, collect_logs, run_batch, run_in_processes
from balancer_id.errors import UsageError
from balancer_id.model import parse_model
from balancer_id.read.recording import Recording
from balancer_id.read.writers import write_log
from balancer_id.simulation.synth import write_synthetic_log

TRUE = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
THRUSTS = [2.45, -4.9, 7.35]
#: relative path of each good log -> its true m_a
GOOD = {"a/run.csv": 12.0, "b/run.csv": 15.1, "c.csv": 19.0}
SUMMARY_HEAD = [
    "file",
    "status",
    "error",
    "exit_code",
    "model",
    "n_trials",
    "m_a",
    "m_a_stderr",
    "T_a",
    "T_a_stderr",
]
SUMMARY_TAIL = ["rmse", "nrmse_fit_percent", "aic", "bic", "seconds"]


def _rest_only(path: Path, seed: int) -> None:
    """A recording of the load at rest: it reads fine but holds no step."""
    rng = np.random.default_rng(seed)
    t = np.arange(800) * 0.005
    accel = np.array([0.0, 0.0, 9.8]) + rng.normal(0.0, 0.03, (t.size, 3))
    force = rng.normal(0.0, 0.03, t.size)
    write_log(path, [Recording("Run #1", t, force, accel)], "pasco-capstone")


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder of 3 good logs (two share a stem), an unreadable one and a rest-only one."""
    root = tmp_path_factory.mktemp("batch") / "logs"
    model = parse_model("variable_viscosity")
    for k, (rel, m_a) in enumerate(GOOD.items()):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        write_synthetic_log(root / rel, model, {**TRUE, "m_a": m_a}, THRUSTS, seed=k, duration_s=4)
    (root / "garbage.csv").write_text("hello,world\nnot,numbers\n", encoding="utf-8")
    _rest_only(root / "rest.csv", seed=7)
    (root / "notes.txt").write_text("not a log", encoding="utf-8")
    (root / ".hidden").mkdir()
    (root / ".hidden" / "x.csv").write_text("skipped", encoding="utf-8")
    (root / "old").mkdir()  # an earlier batch's summary is not a log
    (root / "old" / "summary.csv").write_text(
        "file,status,error,exit_code,model,n_trials\nx.csv,ok,,0,base,2\n", encoding="utf-8"
    )
    (root / "out").mkdir()
    (root / "out" / "stale.csv").write_text("an old result, not an input", encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def batch(logs: Path) -> tuple[BatchResult, list[str]]:
    """The batch over the folder (plus a duplicate) with 2 worker processes."""
    messages: list[str] = []
    result = run_batch([logs, logs / "c.csv"], logs / "out", jobs=2, progress=messages.append)
    return result, messages


def test_inputs_are_expanded_sorted_and_deduplicated(logs: Path) -> None:
    found = collect_logs([logs, logs / "c.csv", logs / "notes.txt"], out_dir=logs / "out")
    rel = [p.relative_to(logs).as_posix() for p in found]
    # hidden folders, the output folder, non-CSV files and earlier summaries in folders
    # are skipped; a file given by name is kept whatever its suffix
    assert rel == ["a/run.csv", "b/run.csv", "c.csv", "garbage.csv", "rest.csv", "notes.txt"]


def test_rows_and_exit_code(batch: tuple[BatchResult, list[str]], logs: Path) -> None:
    result, messages = batch
    assert [Path(r.file).relative_to(logs).as_posix() for r in result.rows] == [
        *GOOD,
        "garbage.csv",
        "rest.csv",
    ]
    assert (result.n_ok, result.n_failed, result.exit_code) == (3, 2, 3)
    assert len([m for m in messages if m.startswith("[")]) == 5
    assert json.loads(json.dumps(result.to_dict()))["n_failed"] == 2


def test_each_good_log_recovers_its_own_mass(
    batch: tuple[BatchResult, list[str]], logs: Path
) -> None:
    result, _ = batch
    names = {}
    for row in result.rows[:3]:
        rel = Path(row.file).relative_to(logs).as_posix()
        doc = json.loads(Path(row.json).read_text(encoding="utf-8"))
        assert doc["status"] == "ok" and doc["file"] == row.file
        assert doc["parameters"]["m_a"]["value"] == pytest.approx(GOOD[rel], rel=0.03)
        assert row.n_trials == 3 and row.exit_code == 0
        names[rel] = Path(row.json).name
    # the same stem twice: a numeric suffix tells the results apart
    assert names == {"a/run.csv": "run.json", "b/run.csv": "run_2.json", "c.csv": "c.json"}


@pytest.mark.parametrize(("name", "code"), [("garbage.csv", 3), ("rest.csv", 4)])
def test_bad_logs_are_failed_rows(
    batch: tuple[BatchResult, list[str]], logs: Path, name: str, code: int
) -> None:
    result, _ = batch
    (row,) = [r for r in result.rows if r.file.endswith(name)]
    assert (row.status, row.exit_code) == ("failed", code)
    assert name in row.error and "\n" not in row.error
    doc = json.loads(Path(row.json).read_text(encoding="utf-8"))
    assert doc["status"] == "failed" and doc["exit_code"] == code and name in doc["error"]


def test_summary_has_one_row_per_log(batch: tuple[BatchResult, list[str]], logs: Path) -> None:
    result, _ = batch
    assert result.summary_path == logs / "out" / "summary.csv"
    with result.summary_path.open(encoding="utf-8", newline="") as handle:
        reader = csv.DictReader(handle)
        columns = list(reader.fieldnames or [])
        table = list(reader)
    assert columns[: len(SUMMARY_HEAD)] == SUMMARY_HEAD
    assert {"D0", "D0_stderr", "A", "A_stderr", *SUMMARY_TAIL} <= set(columns)
    assert [r["file"] for r in table] == [r.file for r in result.rows]
    assert [r["status"] for r in table] == ["ok"] * 3 + ["failed"] * 2
    assert [r["exit_code"] for r in table] == ["0", "0", "0", "3", "4"]
    assert float(table[2]["m_a"]) == pytest.approx(GOOD["c.csv"], rel=0.03)
    assert table[3]["m_a"] == "" and "garbage.csv" in table[3]["error"]
    # issue 11: a verdict and the fit's warnings, so "ok" never hides a doubtful fit
    assert [r["verdict"] for r in table][3:] == ["failed", "failed"]
    for r, row in zip(table[:3], result.rows[:3], strict=True):
        assert r["verdict"] == ("identified, check the warnings" if row.warnings else "identified")
        assert r["warnings"] == " | ".join(row.warnings)


def test_output_folder_is_clean(batch: tuple[BatchResult, list[str]], logs: Path) -> None:
    out = logs / "out"
    assert sorted(p.name for p in out.iterdir()) == [
        ".balancer-id-batch.lock",  # stays, empty: a lock is never unlinked (race-free)
        "c.json",
        "garbage.json",
        "rest.json",
        "run.json",
        "run_2.json",
        "stale.csv",  # untouched: not an input, and never overwritten
        "summary.csv",
    ]
    assert (out / "stale.csv").read_text(encoding="utf-8") == "an old result, not an input"


def test_in_process_run_matches(logs: Path, tmp_path: Path) -> None:
    result = run_batch([logs / "c.csv", logs / "garbage.csv"], tmp_path / "one", jobs=1)
    assert [r.status for r in result.rows] == ["ok", "failed"]
    assert result.rows[0].parameters["m_a"]["value"] == pytest.approx(GOOD["c.csv"], rel=0.03)
    assert result.exit_code == 3


def test_refuses_an_output_file(logs: Path, tmp_path: Path) -> None:
    target = tmp_path / "results"
    target.write_text("keep me", encoding="utf-8")
    with pytest.raises(UsageError, match="is a file"):
        run_batch([logs / "c.csv"], target)
    assert target.read_text(encoding="utf-8") == "keep me"


def test_refuses_inputs_in_the_output_folder(logs: Path) -> None:
    with pytest.raises(UsageError, match="holds the input"):
        run_batch([logs / "out" / "stale.csv"], logs / "out")
    with pytest.raises(UsageError, match="holds the input"):
        run_batch([logs / "c.csv"], logs)


def test_refuses_no_input_and_bad_jobs(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(UsageError, match="no log found"):
        run_batch([tmp_path / "empty"], tmp_path / "out")
    with pytest.raises(UsageError, match="--jobs"):
        run_batch([tmp_path / "x.csv"], tmp_path / "out", jobs=0)
    assert not (tmp_path / "out").exists()


def test_scheduler_without_dask_says_what_to_install(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    with pytest.raises(UsageError, match=r"pip install 'balancer-id\[dask\]'"):
        run_batch([tmp_path / "x.csv"], tmp_path / "out", scheduler="tcp://127.0.0.1:8786")


def test_a_crashing_worker_fails_only_its_own_item() -> None:
    # operator.call(f) runs f() in the worker: os._exit kills that worker outright
    items = [
        (0, partial(dict, status="ok", n=0)),
        (1, partial(os._exit, 3)),
        (2, partial(dict, status="ok", n=2)),
        (3, partial(dict, status="ok", n=3)),
    ]
    got: dict[int, dict] = {}
    told: list[str] = []
    run_in_processes(operator.call, items, got.__setitem__, jobs=2, notify=told.append)
    assert sorted(got) == [0, 1, 2, 3]
    assert told and "died" in told[0]
    assert [got[k]["n"] for k in (0, 2, 3)] == [0, 2, 3]
    assert got[1]["status"] == "failed" and "died" in got[1]["error"]


@pytest.mark.slow
def test_dask_local_cluster(logs: Path, tmp_path: Path) -> None:
    pytest.importorskip("dask.distributed")
    result = run_batch(
        [logs / "c.csv", logs / "garbage.csv", logs / "rest.csv"],
        tmp_path / "dask",
        jobs=2,
        scheduler="local",
    )
    assert [r.status for r in result.rows] == ["ok", "failed", "failed"]
    assert [r.exit_code for r in result.rows] == [0, 3, 4]
    assert result.rows[0].parameters["m_a"]["value"] == pytest.approx(GOOD["c.csv"], rel=0.03)
    assert result.exit_code == 3
    assert (tmp_path / "dask" / "summary.csv").is_file()
    # the same results as the local run: every value, error and message
    local = run_batch(
        [logs / "c.csv", logs / "garbage.csv", logs / "rest.csv"], tmp_path / "local", jobs=1
    )
    for d, ll in zip(result.rows, local.rows, strict=True):
        assert (d.file, d.status, d.exit_code, d.error) == (
            ll.file,
            ll.status,
            ll.exit_code,
            ll.error,
        )
        assert d.parameters.keys() == ll.parameters.keys()
        for name, p in d.parameters.items():
            assert p["value"] == pytest.approx(ll.parameters[name]["value"], rel=1e-9)
            assert p["stderr"] == pytest.approx(ll.parameters[name]["stderr"], rel=1e-6)
        for name, v in d.metrics.items():
            assert v == pytest.approx(ll.metrics[name], rel=1e-9)


def test_a_fit_that_cannot_determine_m_a_does_not_read_just_ok() -> None:
    from balancer_id.batch.rows import BatchRow

    row = BatchRow(file="x.csv", status="ok", warnings=["the data cannot determine m_a"])
    rec = row.summary_record(["m_a"])
    assert rec["verdict"] == "identified, check the warnings"
    assert "cannot determine m_a" in str(rec["warnings"])
    assert BatchRow(file="y.csv", status="ok").summary_record([])["verdict"] == "identified"
