"""The fleet view of a batch (batch --diagnose --report) and the recording time of a log."""

from __future__ import annotations

import json
import os
import re
from datetime import UTC, datetime
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from balancer_id.batch import BatchRow, request_key, run_batch
from balancer_id.batch.worker import recording_time
from balancer_id.cli.app import app
from balancer_id.model import parse_model
from balancer_id.read import read_log
from balancer_id.report.blocks import Table
from balancer_id.report.fleet import fleet_sections, robust_outliers, write_fleet_report
from balancer_id.simulation.synth import write_synthetic_log


def test_robust_outliers_flag_the_planted_value_only() -> None:
    rng = np.random.default_rng(3)
    x = 15.0 + rng.normal(0.0, 0.2, 40)
    x[17] = 19.0  # 20 standard deviations out
    flags = robust_outliers(x)
    assert np.flatnonzero(flags).tolist() == [17]
    assert not robust_outliers([1.0, 2.0, 100.0, 3.0]).any()  # too few logs to judge
    assert not robust_outliers([5.0] * 9 + [6.0]).any()  # no spread to measure
    with_nan = np.append(x, np.nan)
    assert robust_outliers(with_nan)[17] and not robust_outliers(with_nan)[-1]


def _as_fit(path: Path) -> SimpleNamespace:
    """What recording_time reads of a fit: the log as the reader read it."""
    log = read_log(path)
    return SimpleNamespace(trial_set=SimpleNamespace(logs=[SimpleNamespace(log=log)]))


def test_recording_time_from_the_export_else_the_file(tmp_path: Path) -> None:
    # a SPARKvue export with ';' between cells and decimal commas: the reader's clock
    stamped = tmp_path / "stamped.csv"
    stamped.write_text(
        "Date and Time;Time (s);Force (N);Acceleration (m/s²)\n"
        "2024-03-05 08:15:02;0,0;1,0;9,8\n;0,005;1,0;9,8\n;0,010;1,0;9,8\n",
        encoding="utf-8",
    )
    os.utime(stamped, (1_700_000_000, 1_700_000_000))  # a copy's time, not the recording's
    got = recording_time(_as_fit(stamped), str(stamped))
    assert got["source"] == "export"
    local = datetime(2024, 3, 5, 8, 15, 2).astimezone(UTC)  # a wall clock in local time
    assert got["time"] == local.isoformat(timespec="seconds")
    plain = tmp_path / "plain.csv"
    plain.write_text("Time (s),Force (N)\n0.0,1.0\n0.005,1.0\n0.01,1.0\n", encoding="utf-8")
    os.utime(plain, (1_700_000_000, 1_700_000_000))
    got = recording_time(_as_fit(plain), str(plain))
    assert got["source"] == "file time"
    assert got["time"] == "2023-11-14T22:13:20+00:00"


def _row(name: str, m_a: float, doc: dict, folder: Path) -> BatchRow:
    path = folder / f"{name}.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return BatchRow(
        file=f"{name}.csv",
        status="ok",
        json=str(path),
        model="variable_viscosity",
        n_trials=6,
        parameters={"m_a": {"value": m_a, "stderr": 0.1}, "T_a": {"value": 0.33, "stderr": 0.01}},
        metrics={"rmse": 0.03},
    )


def test_fleet_sections_flag_outliers_and_list_missing_effects(tmp_path: Path) -> None:
    masses = [15.0, 15.2, 14.9, 15.1, 14.8, 15.3, 22.0]
    rows = []
    for k, m_a in enumerate(masses):
        verdict = "effect missing" if k == 3 else "adequate"
        doc = {
            "recorded": {"time": f"2024-03-0{k + 1}T08:00:00", "source": "export"},
            "diagnosis": {
                "verdict": verdict,
                "suggestions": [{"change": "+karnopp", "command": f"balancer-id fit log{k}.csv"}],
            },
        }
        rows.append(_row(f"log{k}", m_a, doc, tmp_path))
    rows.append(BatchRow(file="bad.csv", status="failed", error="bad.csv: unreadable"))
    sections = fleet_sections(rows)
    titles = [s.title for s in sections]
    assert titles == ["Fleet", "Logs", "Not counted", "Parameters across logs", "Effect missing"]
    logs = next(b for b in sections[1].blocks if isinstance(b, Table))
    marked = [r[0] for r in logs.rows if any("outlier" in getattr(c, "text", "") for c in r)]
    assert marked == ["log6.csv"]
    apart = next(b for b in sections[2].blocks if isinstance(b, Table))
    assert [r[0] for r in apart.rows] == ["log3.csv"]  # its effect is missing: not counted
    missing = next(b for b in sections[4].blocks if isinstance(b, Table))
    assert missing.rows == [["log3.csv", "+karnopp", "balancer-id fit log3.csv"]]
    text = " ".join(getattr(b, "text", "") for b in sections[3].blocks)
    assert "recorded (from the export)" in text
    out = write_fleet_report(rows, tmp_path / "fleet.html")
    html = out.read_text(encoding="utf-8")
    assert "log3.csv" in html and "Effect missing" in html and "data:image/png" in html


def test_diagnose_changes_the_request_key(tmp_path: Path) -> None:
    log = tmp_path / "x.csv"
    log.write_text("t,F\n0,1\n", encoding="utf-8")
    plain = request_key(str(log), "variable_viscosity", None, None, ())
    assert plain == request_key(str(log), "variable_viscosity", None, None, (), None, False)
    assert plain != request_key(str(log), "variable_viscosity", None, None, (), None, True)


@pytest.fixture(scope="module")
def two_logs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("fleet") / "logs"
    folder.mkdir()
    model = parse_model("variable_viscosity")
    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
    for k, m_a in enumerate((12.0, 18.0)):
        write_synthetic_log(
            folder / f"run{k}.csv",
            model,
            {**truth, "m_a": m_a},
            [2.45, -4.9],
            seed=k,
            duration_s=4,
        )
    return folder


@pytest.mark.slow
def test_batch_diagnose_lists_the_missing_effect(tmp_path: Path) -> None:
    # a short log of a balancer with Coulomb friction (the README's hose log took a 4 s
    # fit and a force discovery; any missing effect makes the point)
    log = tmp_path / "friction.csv"
    model = parse_model("variable_viscosity+karnopp")
    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4, "f_s": 0.8}
    write_synthetic_log(log, model, truth, [2.45, -4.9, 7.35], seed=2, duration_s=4)
    ticks: list[tuple[int, int]] = []
    result = run_batch(
        [log], tmp_path / "out", jobs=1, diagnose=True, tick=lambda d, n: ticks.append((d, n))
    )
    assert ticks[-1] == (1, 1)
    doc = json.loads(Path(result.rows[0].json or "").read_text(encoding="utf-8"))
    assert doc["diagnosis"]["verdict"] == "effect missing"
    assert doc["recorded"]["source"] in ("export", "file time")
    sections = fleet_sections(result.rows)
    missing = next(b for b in sections[-1].blocks if isinstance(b, Table))
    assert [r[0] for r in missing.rows] == [result.rows[0].file]


def test_cli_batch_report_and_progress_off_a_terminal(two_logs: Path, tmp_path: Path) -> None:
    report = tmp_path / "fleet.html"
    args = ["batch", str(two_logs), "--out", str(tmp_path / "out"), "--jobs", "1"]
    res = CliRunner().invoke(app, [*args, "--report", str(report)])
    assert res.exit_code == 0, res.output
    html = report.read_text(encoding="utf-8")
    assert "run0.csv" in html and "run1.csv" in html and "m_a" in html
    assert "file&#x27;s modification time" in html or "file's modification time" in html
    assert "\x1b[" not in res.output  # no bar drawn when stderr is not a terminal
    assert re.search(r"\[2/2\]", res.output)
    # the report is an output like any other: refused when it exists, without --overwrite
    again = CliRunner().invoke(
        app, ["batch", str(two_logs), "--out", str(tmp_path / "o2"), "--report", str(report)]
    )
    assert again.exit_code == 2
    bad = CliRunner().invoke(app, [*args[:4], "--out", str(tmp_path / "o3"), "--report", "x.txt"])
    assert bad.exit_code == 2 and "must end in .html or .pdf" in bad.output


def test_a_value_within_three_of_its_standard_errors_is_never_an_outlier():
    from balancer_id.report.fleet import robust_outliers

    # ten logs at 6.0 +- 0.01 and one at 5.6 whose own standard error is 0.2 (2 se away)
    rng = np.random.default_rng(4)
    values = [*list(6.0 + rng.normal(0, 0.01, 10)), 5.6]
    assert robust_outliers(values)[-1]  # the spread alone would flag it
    stderrs = [0.01] * 10 + [0.2]
    assert not robust_outliers(values, stderrs)[-1]
    # the same value with a tight standard error is an outlier
    assert robust_outliers(values, [0.01] * 10 + [0.01])[-1]


def test_flat_logs_with_outliers_show_no_trend_and_a_real_drift_shows_one():
    from balancer_id.report.fleet import robust_outliers, robust_trend

    rng = np.random.default_rng(5)
    day = 86400.0
    t = np.arange(12) * day
    flat = 0.27 + rng.normal(0, 0.005, 12)
    flat[[9, 11]] = [0.45, 0.46]  # two late outliers pull a least-squares line up
    out = robust_outliers(flat)
    assert out[[9, 11]].all() and out.sum() == 2
    assert robust_trend(t[~out], flat[~out]) is None
    assert np.polyfit(t, flat, 1)[0] * 11 * day > 0.1  # what least squares claimed
    rising = 0.27 + 0.01 * np.arange(12) + rng.normal(0, 0.003, 12)
    trend = robust_trend(t, rising)
    assert trend is not None
    slope, _, low, high = trend
    assert low <= slope <= high and slope * day == pytest.approx(0.01, rel=0.2)


def test_summary_verdict_is_the_logs_own_diagnosis_or_untrusted():
    from balancer_id.batch.rows import BatchRow, judge_row

    row = BatchRow(file="a.csv", status="ok")
    judge_row(row, {"trusted": True, "diagnosis": {"verdict": "effect missing"}})
    assert row.verdict == "effect missing"
    row = BatchRow(file="b.csv", status="ok")
    judge_row(row, {"trusted": False})
    assert row.verdict == "not trusted"
    row = BatchRow(file="c.csv", status="ok")
    judge_row(row, {"trusted": True})
    assert row.verdict == "identified"


def test_untrusted_and_effect_missing_logs_are_listed_apart_and_not_counted(tmp_path: Path):
    """Issue 33: a wild untrusted fit (m_a 6.23 ± 74 kg) and a log whose diagnosis says an
    effect is missing stay out of the median, the quartiles, the outliers and the trend."""
    rng = np.random.default_rng(8)
    rows = []
    for k in range(8):
        doc = {"recorded": {"time": f"2024-03-{k + 1:02d}T08:00:00", "source": "export"},
               "trusted": True, "diagnosis": {"verdict": "adequate", "suggestions": []}}
        rows.append(_row(f"log{k}", 15.0 + float(rng.normal(0, 0.05)), doc, tmp_path))
    bad = _row("wild", 6.23, {"trusted": False, "untrusted_because": ["m_a at a bound"],
                              "recorded": {"time": "2024-03-20T08:00:00", "source": "export"}},
               tmp_path)
    bad.trusted = False
    bad.parameters["m_a"]["stderr"] = 74.0
    rows.append(bad)
    rows.append(_row("drifted", 40.0, {"trusted": True,
                                       "recorded": {"time": "2024-03-21T08:00:00"},
                                       "diagnosis": {"verdict": "effect missing"}}, tmp_path))
    sections = fleet_sections(rows)
    summary = next(b for b in sections[0].blocks if isinstance(b, Table))
    m_a = next(r for r in summary.rows if r[0] == "m_a")
    assert m_a[1] == "8"  # counted logs only
    lo, hi = (float(x) for x in m_a[4].split(" .. "))
    assert 14.8 < lo and hi < 15.2  # neither 6.23 nor 40 in the range
    assert getattr(m_a[5], "text", m_a[5]) == "0"  # no outlier: they were never counted
    apart = next(s for s in sections if s.title == "Not counted")
    table = next(b for b in apart.blocks if isinstance(b, Table))
    reasons = {r[0]: getattr(r[1], "text", r[1]) for r in table.rows}
    assert reasons["wild.csv"].startswith("fit not trusted: m_a at a bound")
    assert "effect is missing" in reasons["drifted.csv"]
    lead = sections[0].blocks[0].text
    assert "8 counted" in lead and "2 listed apart" in lead
    trends = next(s for s in sections if s.title == "Parameters across logs")
    assert "No parameter has a significant trend" in " ".join(
        getattr(b, "text", "") for b in trends.blocks
    )
