"""What a newcomer meets after the set-up (issue 29): a resumed batch keeps its diagnosed
results, logs a stopped batch never reached are "interrupted" (130), not "a bug" (1), and
``improve --discover`` says "wrote" once."""

from __future__ import annotations

import itertools
import json

import pytest

from balancer_id.batch.inputs import _resumed_row
from balancer_id.batch.rows import (
    INTERRUPTED_EXIT_CODE,
    _fill_missing,
    _Task,
    _write_log_result,
)


def _ok_payload() -> dict:
    return {
        "status": "ok",
        "seconds": 1.0,
        "result": {
            "model": "viscous",
            "trials": [{"index": 0}],
            "parameters": {"m_a": {"value": 15.0, "stderr": 0.1}},
            "metrics": {"rmse": 0.03},
            "trusted": True,
            "warnings": [],
        },
    }


def test_a_diagnosed_result_serves_a_resume_without_diagnose_not_the_reverse(tmp_path):
    task = _Task("log.csv", str(tmp_path / "log.csv"), tmp_path / "log.json")
    _write_log_result(task, _ok_payload(), "viscous", "key-diagnosed", fit_request="key-fit")
    assert json.loads(task.output.read_text())["request_fit"] == "key-fit"
    kept = _resumed_row(task, "key-fit")
    assert kept is not None and kept.status == "ok" and kept.n_trials == 1
    assert _resumed_row(task, "key-diagnosed") is not None
    plain = _Task("b.csv", str(tmp_path / "b.csv"), tmp_path / "b.json")
    _write_log_result(plain, _ok_payload(), "viscous", "key-fit", fit_request="key-fit")
    assert "request_fit" not in json.loads(plain.output.read_text())
    assert _resumed_row(plain, "key-diagnosed") is None  # a diagnosis was asked: refit


def test_logs_a_stopped_batch_never_reached_are_interrupted_not_a_bug(tmp_path):
    tasks = [_Task(f"{n}.csv", f"/x/{n}.csv", tmp_path / f"{n}.json") for n in "ab"]
    rows = _fill_missing([None, None], tasks, "viscous")
    assert [r.exit_code for r in rows] == [INTERRUPTED_EXIT_CODE] * 2 == [130, 130]
    assert all("--resume" in r.error and r.status == "failed" for r in rows)


def test_improve_says_wrote_once(capsys):
    from rich.console import Console

    from balancer_id.report.terminal import print_improve

    step = {
        "model": "variable_viscosity+found", "added": "found", "rmse": 0.03, "aic": 1.0,
        "bic": 2.0, "nrmse_fit_percent": 90.0, "cv_rmse": 0.03, "parameters": {},
        "evidence": "", "command": "balancer-id fit x.csv", "discovered": True,
    }
    result = {
        "steps": [step], "rejected": [], "final_model": step["model"],
        "final_summary": "consistent with noise",
        "discovery_note": {"code": "improve.discovered", "text": "wrote found.py: effect"},
    }
    console = Console(width=160, record=True)
    print_improve(console, result)
    assert "wrote found.py" not in console.export_text()  # the CLI says it on stderr
    result["discovery_note"] = {"code": "improve.no_discovery", "text": "nothing found"}
    console = Console(width=160, record=True)
    print_improve(console, result)
    assert "nothing found" in console.export_text()


# --- the library does what the CLI does (issue 29, item 4) -------------------------------


def test_the_library_groups_compares_and_holds_an_earlier_fit(tmp_path):
    from conftest import PAPER, SAMPLE_LOGS

    import balancer_id as bid

    log = SAMPLE_LOGS / "paper_balancer.csv"
    trials = bid.load_trials(log)
    grouped = bid.fit_groups(trials, "runs:1-3,4-6", model="viscous")
    assert len(grouped) == 2 and next(label for label, _ in grouped).startswith("runs")
    for _, result in grouped:  # each half alone still finds the paper's mass (15.1 kg)
        assert result.values["m_a"] == pytest.approx(PAPER["m_a"], rel=0.1)
    assert "group(s) by runs:1-3,4-6" in repr(grouped)
    doc = grouped.to_dict()
    assert doc["group_by"] == "runs:1-3,4-6" and len(doc["groups"]) == 2
    table = bid.compare(trials, ["viscous", "variable_viscosity"])
    assert "lowest BIC" in table._repr_html_() and "variable_viscosity" in repr(table)
    first = bid.fit(trials, model="viscous")
    saved = tmp_path / "fit.json"
    saved.write_text(json.dumps(first.to_dict()))
    held = bid.fit(trials, model="viscous", params=saved)  # held, as the CLI's --params
    assert held.values["m_a"] == pytest.approx(first.values["m_a"])
    assert held.match.parameters["m_a"].stderr is None  # held, not fitted


def test_the_api_lists_fit_groups():
    import balancer_id as bid

    assert {"fit_groups", "GroupFits"} <= set(dir(bid))


def test_the_fleet_gives_the_discovery_command_when_no_effect_explains(tmp_path):
    from balancer_id.batch.rows import BatchRow
    from balancer_id.report.fleet import _missing_blocks

    doc = {"diagnosis": {
        "verdict": "effect missing", "suggestions": [],
        "discovery": {"formula": "F = -4.016*z",
                      "command": "balancer-id improve hose.csv --discover --effects-out d.py"},
    }}
    rows = [BatchRow(file="hose.csv", status="ok")]
    table = _missing_blocks(rows, [doc], [0])[1]
    assert table.rows == [[
        "hose.csv", "no built-in effect; a force was found: F = -4.016*z (N)",
        "balancer-id improve hose.csv --discover --effects-out d.py",
    ]]


def test_fleet_dates_never_crowd_the_axis():
    from datetime import datetime, timedelta

    from matplotlib.figure import Figure

    from balancer_id.report.fleet import _date_axis

    fig = Figure(figsize=(3.2, 2))
    ax = fig.add_subplot()
    start = datetime(2026, 1, 1)
    ax.plot([start + timedelta(hours=7 * k) for k in range(40)], range(40), "o")
    _date_axis(ax)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    labels = [t for t in ax.get_xticklabels() if t.get_text()]
    boxes = [t.get_window_extent() for t in labels]
    assert 2 <= len(labels) <= 6
    for a, b in itertools.pairwise(boxes):
        assert not a.overlaps(b), [t.get_text() for t in labels]
