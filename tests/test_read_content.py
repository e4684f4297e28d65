"""The reader decides by content (names only suggest) and says what it decided (issue 32)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import LogReadError
from balancer_id.read import Log, read_log
from balancer_id.read.inference import Inference
from balancer_id.trials import describe_log


def _resting_g(n: int, seed: int, noise: float = 0.004) -> np.ndarray:
    """A sensor at rest in g, tilted: gravity on all three axes, plus noise."""
    rng = np.random.default_rng(seed)
    up = np.array([0.1, -0.98, 0.17])
    return up / np.linalg.norm(up) + noise * rng.standard_normal((n, 3))


def _write(path: Path, header: list[str], rows: np.ndarray, sep: str = ",") -> Path:
    lines = [sep.join(header)] + [sep.join(f"{v:.15g}" for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _inference(log: Log, what: str) -> Inference:
    (found,) = [i for i in log.inferences if i.what == what]
    return found


def test_axis_family_in_a_semicolon_file_with_epoch_seconds(tmp_path: Path) -> None:
    n = 400
    t = 1_700_000_000.0 + 0.01 * np.arange(n)
    rows = np.column_stack([t, _resting_g(n, 1)])
    path = _write(
        tmp_path / "x.csv", ["Time", "AccelerationX", "AccelerationY", "AccelerationZ"], rows, ";"
    )
    log = read_log(path)
    (rec,) = log.recordings
    assert log.format == "generic"
    assert rec.accel is not None and rec.accel.shape[1] == 3 and rec.accel_includes_gravity
    level = float(np.median(np.linalg.norm(rec.accel, axis=1)))
    assert level == pytest.approx(G_DEFAULT, rel=0.01)  # read in g, converted
    unit = _inference(log, "acceleration unit")
    assert unit.decision == "g" and "constant direction" in unit.evidence
    assert unit.override == "--accel-unit m/s^2"
    assert rec.started_at == pytest.approx(1_700_000_000.0)


def test_acceleration_without_gravity_is_never_scaled_as_g(tmp_path: Path) -> None:
    """Hand-held linear acceleration: magnitude near 1, mean vector 0.6, no fixed direction."""
    rng = np.random.default_rng(7)
    n = 3000
    bias = np.array([0.35, 0.35, 0.35])  # |bias| = 0.6 m/s^2
    accel = bias + 0.8 * rng.standard_normal((n, 3))
    rows = np.column_stack([0.01 * np.arange(n), accel])
    log = read_log(_write(tmp_path / "hand.csv", ["t", "ax", "ay", "az"], rows))
    (rec,) = log.recordings
    assert rec.accel is not None and not rec.accel_includes_gravity
    np.testing.assert_allclose(rec.accel, accel, rtol=1e-5, atol=1e-5)  # not multiplied
    gravity = _inference(log, "gravity")
    assert gravity.decision.startswith("removed") and "no constant direction" in gravity.evidence
    assert _inference(log, "acceleration unit").weak  # nothing at rest to tell the unit by


def test_headerless_file_is_refused_saying_the_header_is_missing(tmp_path: Path) -> None:
    path = tmp_path / "Accelerometer.csv"
    path.write_text("1620421562007834600,0.01,9.8,0.1,0.2\n1620421562017834600,0.02,9.81,0.1,0.2\n")
    with pytest.raises(LogReadError, match="the header line is missing") as err:
        read_log(path)
    assert "1620421562007834600" in str(err.value) and "line 1" in str(err.value)


def test_values_a_billion_times_too_large_are_named(tmp_path: Path) -> None:
    n = 300
    rows = np.column_stack([0.01 * np.arange(n), _resting_g(n, 3) * G_DEFAULT * 1e9])
    lines = ["Time (s);ax (m/s^2);ay (m/s^2);az (m/s^2)"]
    lines += [";".join(f"{v:.2E}".replace(".", ",") for v in row) for row in rows]
    path = tmp_path / "mangled.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogReadError, match="a billion times too large") as err:
        read_log(path)
    assert "blank" not in str(err.value) and "1e-9m/s^2" in str(err.value)


def test_time_sec_is_the_time(tmp_path: Path) -> None:
    n = 200
    rows = np.column_stack([0.005 * np.arange(n), np.ones(n), _resting_g(n, 4) * G_DEFAULT])
    log = read_log(_write(tmp_path / "s.csv", ["Time sec", "Force", "AccX", "AccY", "AccZ"], rows))
    (rec,) = log.recordings
    assert rec.sample_rate_hz == pytest.approx(200.0) and rec.force is not None
    assert _inference(log, "time unit").decision == "s"


def test_inspect_lists_each_inference_with_evidence_and_override(tmp_path: Path) -> None:
    n = 400
    rows = np.column_stack([0.01 * np.arange(n), _resting_g(n, 5)])
    log = read_log(_write(tmp_path / "g.csv", ["time", "acc_x", "acc_y", "acc_z"], rows))
    info = describe_log(log, [])
    whats = [i["what"] for i in info["inferences"]]
    assert whats[:2] == ["layout", "columns"]
    assert {"time unit", "acceleration unit", "gravity"} <= set(whats)
    unit = next(i for i in info["inferences"] if i["what"] == "acceleration unit")
    assert unit["decision"] == "g" and "resting magnitude 1.0" in unit["evidence"]
    assert "±" in unit["evidence"] and unit["override"] and unit["text"].startswith("accel")


def test_gravity_forced_by_the_column_map(tmp_path: Path) -> None:
    n = 400
    rows = np.column_stack([0.01 * np.arange(n), _resting_g(n, 6) * G_DEFAULT])
    path = _write(tmp_path / "m.csv", ["t", "p", "q", "r"], rows)
    log = read_log(path, columns={"time": "t", "ax": "p", "ay": "q", "az": "r", "gravity": "no"})
    (rec,) = log.recordings
    assert not rec.accel_includes_gravity
    assert _inference(log, "gravity").evidence == "given in the column map"


def test_clipping_at_a_two_g_range_is_noted(tmp_path: Path) -> None:
    n = 1000
    accel = _resting_g(n, 8, noise=0.01) * G_DEFAULT
    for start in (300, 600):  # two shocks beyond a ±2 g range: pinned at +2 g on y
        accel[start : start + 6, 1] = 2 * G_DEFAULT
    rows = np.column_stack([0.01 * np.arange(n), accel])
    log = read_log(_write(tmp_path / "c.csv", ["t", "ax", "ay", "az"], rows))
    (note,) = [n for n in log.notes if n.code == "read.sensor_limit"]
    assert f"12 on y at {2 * G_DEFAULT:.4g} m/s^2 (+2 g, 2 runs)" in note.text
    assert log.recordings[0].saturated["accel"] == 12


def test_values_repeated_in_pairs_are_noted(tmp_path: Path) -> None:
    n = 400
    accel = np.repeat(_resting_g(n // 2, 9, noise=0.02) * G_DEFAULT, 2, axis=0)
    rows = np.column_stack([0.05 * np.arange(n), accel])
    log = read_log(_write(tmp_path / "p.csv", ["t", "ax", "ay", "az"], rows))
    (note,) = [n for n in log.notes if "repeated" in n.text]
    assert "repeated 2 times" in note.text and "(10 Hz)" in note.text


def _gate_file(path: Path, head: str, rows: list[str]) -> Path:
    path.write_text(head + "\n" + "\n".join(rows) + "\n")
    return path


def test_force_beside_event_timed_photogate_keeps_its_own_clock(tmp_path: Path) -> None:
    n, events = 500, 11
    tf = 0.02 * np.arange(n)
    te = np.linspace(0.3, 8.7, events)
    rows = [
        f"{tf[i]:.3f},{5 + np.sin(tf[i]):.4f}," + (f"{te[i]:.4f},{i % 2}" if i < events else ",")
        for i in range(n)
    ]
    head = "Run 1: Time (s),Run 1: Force (N),Run 1: Gate Time (s),Run 1: Gate State"
    (rec,) = read_log(_gate_file(tmp_path / "v.csv", head, rows)).recordings
    assert rec.n_samples == n and rec.sample_rate_hz == pytest.approx(50.0)


def test_force_under_an_event_clock_is_refused_not_cut(tmp_path: Path) -> None:
    n, events = 500, 11
    te = np.linspace(0.3, 8.7, events)
    rows = [
        (f"{te[i]:.4f},{i % 2}," if i < events else ",,") + f"{5 + np.sin(i / 50):.4f}"
        for i in range(n)
    ]
    head = "Run 1: Time (s),Run 1: Gate State,Run 1: Force (N)"
    with pytest.raises(LogReadError, match="clocks of their own") as err:
        read_log(_gate_file(tmp_path / "e.csv", head, rows))
    assert "500 values but only 11" in str(err.value)


def test_disjoint_clocks_are_refused_naming_them(tmp_path: Path) -> None:
    n = 300
    rows = [
        f"{0.01 * i:.3f},{5.0 + 0.01 * (i % 7):.3f},{100 + 0.01 * i:.3f},0.1,0.2,9.8"
        for i in range(n)
    ]
    head = "Time (s),Force (N),Time (s),ax (m/s^2),ay (m/s^2),az (m/s^2)"
    with pytest.raises(LogReadError, match="do not overlap: channels on disjoint clocks"):
        read_log(_gate_file(tmp_path / "d.csv", head, rows))


def test_one_axis_resting_steadily_at_one_is_gravity_in_g(tmp_path: Path) -> None:
    rng = np.random.default_rng(12)
    n = 600
    a = 1.0 + 0.005 * rng.standard_normal(n)
    a[300:330] += 0.3  # a lift
    rows = np.column_stack([0.01 * np.arange(n), a])
    log = read_log(_write(tmp_path / "one.csv", ["t", "a"], rows))
    (rec,) = log.recordings
    assert rec.accel is not None and rec.accel_includes_gravity
    assert float(np.median(rec.accel)) == pytest.approx(G_DEFAULT, rel=0.01)
    assert _inference(log, "acceleration unit").decision == "g"


def test_values_without_a_time_are_refused_or_named(tmp_path: Path) -> None:
    rows = [f"{0.01 * i:.2f},{1 + 0.1 * i:.1f}," for i in range(12)] + [",,9.8"] * 12
    path = tmp_path / "two.csv"
    path.write_text("t,F,a\n" + "\n".join(rows) + "\n")
    with pytest.raises(LogReadError, match="has 12 values but only 0 of them a time"):
        read_log(path)
    path.write_text("t,F,a\n" + "\n".join(rows[:14]) + "\n")  # two untimed: noted, not hidden
    log = read_log(path)
    assert any("2 value(s) but none on a row with a time" in w for w in log.warnings)


def test_metadata_lines_above_the_header_are_skipped_and_said(tmp_path: Path) -> None:
    n = 200
    rows = np.column_stack([0.01 * np.arange(n), np.ones(n), _resting_g(n, 13) * G_DEFAULT])
    body = _write(tmp_path / "b.csv", ["t", "F", "ax", "ay", "az"], rows).read_text()
    path = tmp_path / "m.csv"
    path.write_text("Device: Phone X\nSample rate: 100 Hz\n\n" + body)
    log = read_log(path)
    assert log.recordings[0].n_samples == n and log.recordings[0].force is not None
    assert any("2 line(s) before the header skipped" in w for w in log.warnings)


def test_g_force_columns_are_acceleration_in_g(tmp_path: Path) -> None:
    n = 300
    rows = np.column_stack([0.01 * np.arange(n), _resting_g(n, 14)])
    rows = np.column_stack([rows, np.linalg.norm(rows[:, 1:], axis=1)])
    log = read_log(_write(tmp_path / "pt.csv", ["time", "gFx", "gFy", "gFz", "TgF"], rows))
    (rec,) = log.recordings
    assert rec.force is None and rec.accel is not None and rec.accel.shape[1] == 3
    level = float(np.median(np.linalg.norm(rec.accel, axis=1)))
    assert level == pytest.approx(G_DEFAULT, rel=0.01)


def test_time_written_as_clock_text_across_midnight(tmp_path: Path) -> None:
    n = 400
    seconds = 86_398.0 + 0.01 * np.arange(n)  # 23:59:58 to past midnight
    clock = [f"{int(v // 3600) % 24:02d}:{int(v % 3600 // 60):02d}:{v % 60:06.3f}" for v in seconds]
    accel = _resting_g(n, 15) * G_DEFAULT
    lines = ["Time,ax,ay,az"] + [
        f"{c},{a[0]:.5f},{a[1]:.5f},{a[2]:.5f}" for c, a in zip(clock, accel, strict=True)
    ]
    path = tmp_path / "clock.csv"
    path.write_text("\n".join(lines) + "\n")
    log = read_log(path)
    (rec,) = log.recordings
    assert rec.n_samples == n and rec.sample_rate_hz == pytest.approx(100.0, rel=1e-3)
    assert any("read from clock text" in w for w in log.warnings)
