"""Time units, the column map's units and scales, raw counts, gravity headers, odd files."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import LogReadError, UsageError
from balancer_id.read import read_log
from balancer_id.read.generic import parse_spec
from balancer_id.read.timebase import to_seconds


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def _rows(n: int, time: object, accel: tuple[float, float, float]) -> str:
    rng = np.random.default_rng(1)
    lines = []
    for i in range(n):
        a = np.asarray(accel) + rng.normal(0, 0.01 * max(1.0, abs(accel[2])), 3)
        lines.append(f"{time(i)},{a[0]:.6g},{a[1]:.6g},{a[2]:.6g}")
    return "\n".join(lines) + "\n"


def test_epoch_ms_from_the_name_and_the_values(tmp_path: Path) -> None:
    body = _rows(200, lambda i: 1768149426894 + 13 * i, (0.0, 0.0, 1.0))
    log = read_log(_write(tmp_path, "ms.csv", "Time_ms,AX,AY,AZ\n" + body))
    (rec,) = log.recordings
    assert rec.sample_rate_hz == pytest.approx(1000 / 13)
    assert rec.time[0] == 0.0 and rec.time[-1] == pytest.approx(199 * 0.013)
    assert rec.started_at == pytest.approx(1768149426.894)
    (note,) = [n for n in log.notes if n.code == "read.time_unit"]
    assert "read in ms (from the column's name)" in note.text and note.text in log.warnings


def test_19_digit_ns_timestamps_are_not_missing(tmp_path: Path) -> None:
    body = _rows(300, lambda i: 1730147596612447367 + 1_000_000 * i, (0.0, 0.0, 9.81))
    log = read_log(_write(tmp_path, "ns.csv", "timestamp,accX,accY,accZ\n" + body))
    (rec,) = log.recordings
    assert rec.n_samples == 300
    assert rec.sample_rate_hz == pytest.approx(1000.0, rel=1e-3)
    (note,) = [n for n in log.notes if n.code == "read.time_unit"]
    assert "read in ns (from the size of its values)" in note.text


def test_header_unit_us_and_a_rate_out_of_range_warned(tmp_path: Path) -> None:
    body = _rows(50, lambda i: 5000 * i, (0.0, 0.0, 9.81))
    rec = read_log(_write(tmp_path, "us.csv", "t (us),ax,ay,az\n" + body)).recordings[0]
    assert rec.sample_rate_hz == pytest.approx(200.0)
    slow = read_log(
        _write(tmp_path, "slow.csv", "t,ax,ay,az\n" + _rows(50, lambda i: 5 * i, (0, 0, 9.81)))
    )
    # whole numbers 5 apart: 0.2 Hz in s (no accelerometer log), 200 Hz in ms: read in ms
    assert slow.recordings[0].sample_rate_hz == pytest.approx(200.0)
    (note,) = [n for n in slow.notes if n.code == "read.time_unit"]
    assert "read in ms (from its spacing: whole numbers 5 apart)" in note.text
    (unit,) = [i for i in slow.inferences if i.what == "time unit"]
    assert unit.decision == "ms" and "--columns time=t:" in unit.override


@pytest.mark.parametrize(
    ("role", "spec", "expected"),
    [
        ("time", "ms", ("ms", 1.0, 0.0)),
        ("ax", "counts/4096g", ("g", 1 / 4096, 0.0)),
        ("force", "0.00315N", ("N", 0.00315, 0.0)),
        ("force", "3.15e-6N+0.30", ("N", 3.15e-6, 0.30)),
        ("force", "2kN-1", ("N", 2000.0, -1000.0)),
        ("a", "mg", ("g", 1e-3, 0.0)),
        ("az", "m/s^2", ("m/s^2", 1.0, 0.0)),
    ],
)
def test_column_map_specs(role: str, spec: str, expected: tuple[str, float, float]) -> None:
    unit, factor, offset = parse_spec(role, spec)
    assert unit == expected[0]
    assert factor == pytest.approx(expected[1]) and offset == pytest.approx(expected[2])


def test_column_map_spec_with_a_wrong_unit_is_a_usage_error() -> None:
    with pytest.raises(UsageError, match="give a unit of s, sec, ms"):
        parse_spec("time", "N")
    with pytest.raises(UsageError, match="give a unit of N, kN, mN, kgf, lbf"):
        parse_spec("force", "g")
    for spec in ("counts/0g", "0N", "1e999N"):
        with pytest.raises(UsageError, match="finite and not zero"):
            parse_spec("force" if spec.endswith("N") else "ax", spec)


def test_raw_counts_refused_with_the_map_then_read_with_it(tmp_path: Path) -> None:
    body = _rows(100, lambda i: 0.01 * i, (-7.0, -320.0, -4094.0))
    path = _write(tmp_path, "counts.csv", "Time,AccX,AccY,AccZ\n" + body)
    with pytest.raises(LogReadError) as info:
        read_log(path)
    message = str(info.value)
    assert "raw sensor counts (~4096 counts per g?) or another unit" in message
    assert (
        "--columns time=Time,ax=AccX:counts/4096g,ay=AccY:counts/4096g,az=AccZ:counts/4096g"
        in message
    )
    cmap = {
        "time": "Time",
        "ax": "AccX:counts/4096g",
        "ay": "AccY:counts/4096g",
        "az": "AccZ:counts/4096g",
    }
    rec = read_log(path, columns=cmap).recordings[0]
    level = np.median(np.linalg.norm(rec.accel, axis=1))
    assert level == pytest.approx(np.hypot(4094, 320) / 4096 * G_DEFAULT, rel=0.01)
    assert rec.accel_includes_gravity


def test_force_scale_and_offset_from_the_map(tmp_path: Path) -> None:
    rows = "".join(f"{0.01 * i},{1600000 + 100 * i}\n" for i in range(20))
    path = _write(tmp_path, "cell.csv", "Time,Force\n" + rows)
    rec = read_log(path, columns={"time": "Time", "force": "Force:3.1535e-6N+0.30087"}).recordings[
        0
    ]
    np.testing.assert_allclose(
        rec.force[:2], [1600000 * 3.1535e-6 + 0.30087, 1600100 * 3.1535e-6 + 0.30087]
    )


def test_with_g_header_over_data_without_gravity_is_warned(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    lines = [
        f"{0.01 * i:.2f},{x:.4f},{y:.4f},{z:.4f}"
        for i, (x, y, z) in enumerate(rng.normal(0, 0.3, (200, 3)))
    ]
    head = '"Time (s)","Acceleration x (m/s^2)","Acceleration y (m/s^2)","Acceleration z (m/s^2)"\n'
    log = read_log(_write(tmp_path, "linear.csv", head + "\n".join(lines) + "\n"))
    assert not log.recordings[0].accel_includes_gravity
    (note,) = [n for n in log.notes if n.code == "read.gravity_header"]
    assert "the values hold no gravity" in note.text


def test_without_g_header_over_data_with_gravity_is_warned(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    up = np.array([0.2, -0.1, 0.97]) / np.linalg.norm([0.2, -0.1, 0.97])
    data = 9.81 * up + rng.normal(0, 0.05, (200, 3))
    lines = [f"{0.01 * i:.2f},{x:.4f},{y:.4f},{z:.4f}" for i, (x, y, z) in enumerate(data)]
    head = (
        '"Time (s)","Linear Acceleration x (m/s^2)","Linear Acceleration y (m/s^2)",'
        '"Linear Acceleration z (m/s^2)"\n'
    )
    log = read_log(_write(tmp_path, "withg.csv", head + "\n".join(lines) + "\n"))
    assert log.recordings[0].accel_includes_gravity
    (note,) = [n for n in log.notes if n.code == "read.gravity_header"]
    assert "the values hold gravity" in note.text


def test_zip_named_csv_is_named_a_zip(tmp_path: Path) -> None:
    path = tmp_path / "Raw Data.csv"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("Raw Data.csv", "Time (s),Acceleration x (m/s^2)\n0,1\n")
    with pytest.raises(LogReadError, match=r"is a zip archive.*unzip it"):
        read_log(path)


def test_rows_quoted_whole_are_unquoted(tmp_path: Path) -> None:
    names = ",".join(f'""Linear Acceleration {a} (m/s^2)""' for a in "xyz")
    head = f'"Time (s),{names}"\n'
    rows = "".join(f'"{0.005 * i:.3f},0.01,-0.02,{0.001 * i:.3f}"\n' for i in range(40))
    log = read_log(_write(tmp_path, "quoted.csv", head + rows))
    (rec,) = log.recordings
    assert rec.n_samples == 40 and rec.sample_rate_hz == pytest.approx(200.0)
    assert not rec.accel_includes_gravity
    assert any("one quoted field" in w for w in log.warnings)


def test_a_clock_that_restarts_makes_runs(tmp_path: Path) -> None:
    rows = "".join(f"{0.002 * (i % 20 + 1):.3f};{i}\n" for i in range(60))
    log = read_log(_write(tmp_path, "rig.csv", "time;force\n" + rows))
    assert [r.name for r in log.recordings] == ["Run 1", "Run 2", "Run 3"]
    assert all(r.n_samples == 20 for r in log.recordings)
    np.testing.assert_allclose(log.recordings[2].force, np.arange(40, 60))
    (note,) = [n for n in log.notes if n.code == "read.clock_restart"]
    assert "restarts 2 time(s) (lines 22, 42)" in note.text


@settings(max_examples=200, deadline=None, derandomize=True)
@given(role=st.sampled_from(["time", "force", "ax", "a"]), spec=st.text(max_size=30))
def test_any_spec_is_parsed_or_a_usage_error(role: str, spec: str) -> None:
    try:
        unit, factor, offset = parse_spec(role, spec)
    except UsageError as exc:
        assert "--columns" in str(exc) and "\n" not in str(exc)
    else:
        assert unit in ("s", "ms", "us", "ns", "min", "g", "m/s^2", "N")
        assert np.isfinite(factor) and factor != 0.0 and np.isfinite(offset)
        assert isinstance(offset, float)


@settings(max_examples=100, deadline=None, derandomize=True)
@given(
    start=st.floats(0, 2e18, allow_nan=False),
    step=st.sampled_from([1.0, 1e-3, 13.0, 1e6]),
)
def test_time_unit_from_values_gives_seconds_that_increase(start: float, step: float) -> None:
    raw = start + step * np.arange(50.0)
    base = to_seconds(raw)
    assert base.unit in ("s", "ms", "us", "ns")
    if np.all(np.diff(raw) > 0):
        assert np.all(np.diff(base.seconds) >= 0)
    if base.started_at is not None:
        assert base.seconds[0] == 0.0 and base.started_at > 1e8


def test_ns_values_under_a_seconds_header_are_read_by_their_spacing(tmp_path: Path) -> None:
    body = _rows(50, lambda i: 1730147596612447367 + 5_000_000 * i, (0.0, 0.0, 9.81))
    log = read_log(_write(tmp_path, "wrong.csv", "Time (s),ax,ay,az\n" + body))
    (rec,) = log.recordings
    assert rec.sample_rate_hz == pytest.approx(200.0, rel=1e-3)
    assert rec.started_at == pytest.approx(1730147596.6, abs=1.0)  # a clock time in ns
    (note,) = [n for n in log.notes if n.code == "read.time_unit"]
    assert "read in ns" in note.text and "the header says s" in note.text


@pytest.mark.parametrize(
    ("name", "factor"),
    [("Force (lbf)", 4.4482216152605), ("force_mN", 1e-3), ("Kraft (kN)", 1e3), ("F_N", 1.0)],
)
def test_a_force_unit_in_the_name_is_scaled_to_newtons(tmp_path: Path, name, factor) -> None:
    # a lbf or mN force read as N put m_a 4.4x low or 1000x high, and trusted
    rows = [f"{i * 0.005:.3f},{2.0 + 0.01 * (i % 3)},0.01,0.02,9.81" for i in range(100)]
    text = f"Time (s),{name},ax (m/s^2),ay (m/s^2),az (m/s^2)\n" + "\n".join(rows) + "\n"
    log = read_log(_write(tmp_path, "f.csv", text))
    (rec,) = log.recordings
    assert np.median(rec.force) == pytest.approx(2.01 * factor, rel=1e-6)
    said = [n.text for n in log.notes if n.code == "read.force_unit"]
    if factor == 1.0:
        assert said == []
    else:
        (text,) = said
        assert f"x{factor:.6g} to N" in text and text in log.warnings
        (unit,) = [i for i in log.inferences if i.what == "force unit"]
        assert unit.override.endswith(":N")
    # the column map's own unit wins over the name's
    mapped = read_log(
        tmp_path / "f.csv",
        columns={"time": "Time (s)", "force": f"{name}:N", "ax": "ax (m/s^2)",
                 "ay": "ay (m/s^2)", "az": "az (m/s^2)"},
    )  # fmt: skip
    assert np.median(mapped.recordings[0].force) == pytest.approx(2.01, rel=1e-6)


def test_a_units_row_under_the_names_is_read_as_the_headers_units(tmp_path: Path) -> None:
    # a logger's names row, then its units row: the units row was taken as the header
    # ("columns found: 's', 'N', ...") and the names skipped as metadata
    rows = [f"{i * 5},{2000 + 10 * (i % 3)},0.001,0.002,1.0" for i in range(100)]
    text = "Device: logger 7\ntime;force;accX;accY;accZ\n[ms];[mN];[g];[g];[g]\n"
    text = text.replace(";", ",") + "\n".join(rows) + "\n"
    log = read_log(_write(tmp_path, "units_row.csv", text))
    (rec,) = log.recordings
    assert rec.sample_rate_hz == pytest.approx(200.0)
    assert np.median(rec.force) == pytest.approx(2.01, rel=1e-6)
    assert any("units were read from the row under it" in w for w in log.warnings)
    assert any("1 line(s) before the header skipped" in w for w in log.warnings)
    # a first data row of words that are no units stays an error about the data
    three = "\n".join(f"{i * 0.005:.3f},2.0,9.81" for i in range(100))
    bad = _write(tmp_path, "words.csv", "time,force,az\nstart,push,up\n" + three)
    with pytest.raises(LogReadError, match="no time, force or acceleration column"):
        read_log(bad)
