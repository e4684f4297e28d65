"""Reader behaviour on the PASCO/phyphox traps: shared time, other rates, units, limits."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from balancer_id.constants import ACCEL_RANGE_G, FORCE_RANGE_N, G_DEFAULT
from balancer_id.errors import LogReadError
from balancer_id.read import read_log
from balancer_id.read.header import classify, split_name
from balancer_id.read.sniff import sniff


def _write(tmp_path: Path, name: str, text: str, encoding: str = "utf-8") -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode(encoding))
    return path


@pytest.mark.parametrize(
    ("raw", "expected"),
    [
        ("Force (N) Run #1", ("Force", "N", "Run #1")),
        ("Time (s) Auto", ("Time", "s", "Auto")),
        ("Force (N) 9.9", ("Force", "N", "9.9")),
        ("Accel (Resultant) (m/s²) Run 1", ("Accel (Resultant)", "m/s²", "Run 1")),
        ("Date and Time Run 1", ("Date and Time", "", "Run 1")),
        ("Date and Time 11.4", ("Date and Time", "", "11.4")),
        ("Acceleration x (m/s^2)", ("Acceleration x", "m/s^2", "")),
        ("acc_x", ("acc_x", "", "")),
    ],
)
def test_split_name(raw: str, expected: tuple[str, str, str]) -> None:
    assert split_name(raw) == expected


@pytest.mark.parametrize(
    ("raw", "kind", "axis", "linear"),
    [
        ("Acceleration - x (m/s²) Run 1", "accel", "x", False),
        ("Linear Acceleration z (m/s^2)", "accel", "z", True),
        ("Y (m/s^2)", "accel", "y", False),
        ("Acceleration (m/s²) Run 2", "accel", "", False),
        ("Absolute acceleration (m/s^2)", "ignore", "", False),
        ("Gyroscope x (rad/s)", "gyro", "x", False),
        ("Mass (g)", "other", "", False),
        ("Acceleration z (g)", "accel", "z", False),
    ],
)
def test_classify(raw: str, kind: str, axis: str, linear: bool) -> None:
    col = classify(0, raw)
    assert (col.kind, col.axis, col.linear) == (kind, axis, linear)


@pytest.mark.parametrize(
    ("text", "delimiter", "decimal"),
    [
        ("a,b\n1.5,2\n", ",", "."),
        ("a;b\n1,5;2\n", ";", ","),
        ("a;b\n1.5;2\n", ";", "."),
        ("a\tb\n1,5\t2\n", "\t", ","),
        ('"a"\t"b"\n1.5E-2\t2\n', "\t", "."),
        ("a b\n1.5 2\n", " ", "."),
    ],
)
def test_sniff_delimiter_and_decimal(
    tmp_path: Path, text: str, delimiter: str, decimal: str
) -> None:
    sniffed = sniff(_write(tmp_path, "s.csv", text))
    assert (sniffed.delimiter, sniffed.decimal, sniffed.header) == (delimiter, decimal, ["a", "b"])


def test_shared_time_column_for_several_runs(tmp_path: Path) -> None:
    text = "Time (s),Force (N) Run #1,Force (N) Run #2\n0,1,5\n0.005,2,6\n0.01,3,\n0.015,,\n"
    log = read_log(_write(tmp_path, "shared.csv", text))
    assert log.format == "pasco-capstone"
    run1, run2 = log.recordings
    assert (run1.name, run2.name) == ("Run #1", "Run #2")
    np.testing.assert_allclose(run1.time, [0.0, 0.005, 0.01])
    np.testing.assert_allclose(run2.time, [0.0, 0.005])
    assert run2.force is not None
    np.testing.assert_allclose(run2.force, [5.0, 6.0])


def _multirate_text() -> str:
    lines = [
        "Time (s);Force (N) Run #1;Acceleration x (g) Run #1;Acceleration y (g) Run #1;"
        "Acceleration z (g) Run #1;Position (m) Run #1"
    ]
    for i in range(200):
        t = f"{i * 0.005:.3f}".replace(".", ",")
        force = "1,5" if i % 10 == 0 else ""
        pos = "0,5" if i % 10 == 0 else ""
        lines.append(f"{t};{force};0,01;0,02;1,00;{pos}")
    return "\ufeff" + "\r\n".join(lines) + "\r\n\r\n"


def test_slower_force_under_a_shared_time_column_is_interpolated(tmp_path: Path) -> None:
    log = read_log(_write(tmp_path, "multirate.csv", _multirate_text()))
    (run,) = log.recordings
    assert run.name == "Run #1" and run.n_samples == 191  # up to the last force sample
    assert run.sample_rate_hz == pytest.approx(200.0)
    assert run.accel is not None and run.force is not None
    # An explicit "(g)" unit is converted without a warning about the unit.
    np.testing.assert_allclose(run.accel[0], np.array([0.01, 0.02, 1.0]) * G_DEFAULT)
    np.testing.assert_allclose(run.force, 1.5)
    assert np.isnan(run.extra["Position (m)"][1])  # extra channels keep NaN
    assert not any("looks like g" in w for w in log.warnings)
    (note,) = [w for w in log.warnings if "different rates" in w]
    assert "force (20 Hz) and acceleration (200 Hz)" in note
    assert "interpolated linearly" in note and "9 acceleration sample(s)" in note


def test_values_in_g_auto_and_forced_units(tmp_path: Path) -> None:
    rows = "\n".join(f"{i * 0.01:.2f},0.01,-0.02,1.0{i % 3}" for i in range(50))
    path = _write(tmp_path, "g.csv", "time,ax,ay,az\n" + rows + "\n")
    auto = read_log(path)
    assert auto.recordings[0].accel is not None
    assert auto.recordings[0].accel[0, 2] == pytest.approx(1.0 * G_DEFAULT)
    assert any("looks like g" in w for w in auto.warnings)
    # forced to m/s^2, an accelerometer with gravity resting at 1.0 contradicts the unit
    with pytest.raises(LogReadError, match=r"rests at a magnitude of 1\.01 m/s\^2") as err:
        read_log(path, accel_unit="m/s^2")
    assert err.value.exit_code == 3 and "--accel-unit g or auto" in str(err.value)
    custom = read_log(path, accel_unit="g", g=9.81)
    assert custom.recordings[0].accel is not None
    assert custom.recordings[0].accel[0, 2] == pytest.approx(9.81)


def test_saturation_is_counted_and_warned(tmp_path: Path) -> None:
    limit = ACCEL_RANGE_G * G_DEFAULT
    rows = [
        f"{i * 0.005:.3f},{FORCE_RANGE_N if i in (3, 4) else 1.0},0,0,{limit if i == 7 else 9.8}"
        for i in range(40)
    ]
    text = "Time (s) Run #1,Force (N) Run #1,Acceleration x (m/s²) Run #1," + (
        "Acceleration y (m/s²) Run #1,Acceleration z (m/s²) Run #1\n"
    )
    log = read_log(_write(tmp_path, "sat.csv", text + "\n".join(rows) + "\n"))
    assert log.recordings[0].saturated == {"force": 2, "accel": 1}
    assert sum("sensor limit" in w for w in log.warnings) == 2


def test_force_only_and_accel_only_are_valid(tmp_path: Path) -> None:
    force_only = read_log(_write(tmp_path, "f.csv", "Time (s),Force (N)\n0,1\n0.1,2\n"))
    assert force_only.recordings[0].accel is None
    accel_only = read_log(_write(tmp_path, "a.csv", "t,a\n0,9.8\n0.1,9.7\n0.2,9.9\n"))
    rec = accel_only.recordings[0]
    assert rec.force is None and rec.accel is not None
    assert rec.accel.shape == (3, 1) and rec.accel_axes == ("z",) and rec.accel_includes_gravity


def test_time_in_milliseconds(tmp_path: Path) -> None:
    log = read_log(_write(tmp_path, "ms.csv", "Time (ms),Force (N)\n0,1\n5,2\n10,3\n"))
    np.testing.assert_allclose(log.recordings[0].time, [0.0, 0.005, 0.01])
    assert log.recordings[0].sample_rate_hz == pytest.approx(200.0)


def test_phyphox_per_sensor_linear_file_name(tmp_path: Path) -> None:
    rows = "\n".join(f"{i * 0.01:.9E};{0.02:.9E};{-0.01:.9E};{0.03:.9E}" for i in range(20))
    text = '"Time (s)";"X (m/s^2)";"Y (m/s^2)";"Z (m/s^2)"\n' + rows
    log = read_log(_write(tmp_path, "Linear Accelerometer.csv", text))
    assert log.format == "phyphox"
    assert not log.recordings[0].accel_includes_gravity


def test_phyphox_gyroscope_goes_to_extra(tmp_path: Path) -> None:
    header = '"Time (s)","Acceleration x (m/s^2)","Acceleration y (m/s^2)",'
    header += '"Acceleration z (m/s^2)","Gyroscope x (rad/s)"\n'
    rows = "\n".join(f"{i * 0.01:.9E},0,0,9.8,{i * 1e-3:.9E}" for i in range(10))
    log = read_log(_write(tmp_path, "gyro.csv", header + rows))
    rec = log.recordings[0]
    assert rec.extra["Gyroscope x (rad/s)"][3] == pytest.approx(0.003)
    assert rec.accel_includes_gravity


def test_blank_run_is_dropped(tmp_path: Path) -> None:
    text = "Time (s) Run #1,Force (N) Run #1,Time (s) Run #2,Force (N) Run #2\n0,1,,\n0.1,2,,\n"
    log = read_log(_write(tmp_path, "blankrun.csv", text))
    assert [r.name for r in log.recordings] == ["Run #1"]
    assert any("Run #2" in w for w in log.warnings)


def test_utf16_export(tmp_path: Path) -> None:
    text = "\ufeffTime (s)\tForce (N)\r\n0\t1,5\r\n0,1\t2,5\r\n"
    log = read_log(_write(tmp_path, "u16.csv", text, encoding="utf-16-le"))
    assert log.recordings[0].force is not None
    np.testing.assert_allclose(log.recordings[0].force, [1.5, 2.5])


def test_capstone_time_column_per_rate(tmp_path: Path) -> None:
    """Capstone writes one time column per rate; each measurement takes the one before it."""
    header = (
        "Time (s) Run #1,Acceleration x (m/s²) Run #1,Acceleration y (m/s²) Run #1,"
        "Acceleration z (m/s²) Run #1,Time (s) Run #1,Force (N) Run #1,"
        "Time (s) Run #1,Position (m) Run #1\n"
    )
    rows = []
    for i in range(40):
        slow = f"{i * 0.05:.2f},{i * 0.1:.1f}" if i < 4 else ","
        pos = f"{i * 0.5:.1f},{i}" if i < 2 else ","
        rows.append(f"{i * 0.005:.3f},{i},0,9.8,{slow},{pos}")
    log = read_log(_write(tmp_path, "rates.csv", header + "\n".join(rows) + "\n"))
    (run,) = log.recordings
    assert run.name == "Run #1" and run.sample_rate_hz == pytest.approx(200.0)
    # the acceleration's own samples, up to the force's last sample (0.15 s)
    assert run.n_samples == 31 and run.accel is not None and run.force is not None
    np.testing.assert_array_equal(run.accel[:, 0], np.arange(31.0))
    np.testing.assert_allclose(run.force, 2.0 * run.time, atol=1e-12)  # force = t / 0.5 s
    assert any("interpolated linearly" in w for w in log.warnings)


def _capstone_fast_force(rate_force: float, every: int, n: int = 2000) -> str:
    """One time column at ``rate_force``; acceleration blank in ``every - 1`` rows of ``every``."""
    lines = ["Time (s),Force (N) Run #1,Acceleration z (m/s²) Run #1"]
    for i in range(n):
        t = i / rate_force
        accel = f"{9.8 + 0.001 * i:.4f}" if i % every == 0 else ""
        lines.append(f"{t:.6f},{np.sin(2 * np.pi * 3 * t) + 0.01 * (i % 2):.6f},{accel}")
    return "\n".join(lines) + "\n"


def test_capstone_faster_force_makes_one_run_on_the_accel_times(tmp_path: Path) -> None:
    """Issue 8: force at 1000 Hz, acceleration blank in 4 rows of 5 -> one run at 200 Hz."""
    log = read_log(_write(tmp_path, "capstone.csv", _capstone_fast_force(1000.0, 5)))
    assert log.format == "pasco-capstone"
    (run,) = log.recordings
    assert run.n_samples == 400 and run.sample_rate_hz == pytest.approx(200.0)
    assert run.accel is not None and run.force is not None
    # the acceleration is the file's values, not interpolated
    np.testing.assert_allclose(run.accel[:, 0], 9.8 + 0.001 * np.arange(0, 2000, 5))
    np.testing.assert_allclose(run.time, np.arange(0, 2000, 5) / 1000.0)
    # the force is the mean of the 5 samples centred on each accel sample (no time shift)
    t = np.arange(2000) / 1000.0
    force = np.round(np.sin(2 * np.pi * 3 * t) + 0.01 * (np.arange(2000) % 2), 6)
    inner = [force[i - 2 : i + 3].mean() for i in range(5, 1995, 5)]
    np.testing.assert_allclose(run.force[1:-1], inner, atol=1e-9)
    # a 3 Hz sine averaged over 5 ms keeps its phase and ~all of its amplitude
    expected = np.sin(2 * np.pi * 3 * run.time) + 0.005
    np.testing.assert_allclose(run.force[1:-1], expected[1:-1], atol=2e-3)
    (note,) = [w for w in log.warnings if "different rates" in w]
    assert "force (1000 Hz) and acceleration (200 Hz)" in note and "averaged" in note
    assert "not interpolated" in note


def test_sensor_time_columns_of_their_own_make_one_run(tmp_path: Path) -> None:
    """Capstone/SPARKvue layout: each sensor with its own time column, one run."""
    header = "Time (s) Run #1,Force (N) Run #1,Time (s) Run #1,Acceleration z (m/s²) Run #1\n"
    rows = []
    for i in range(500):  # force at 500 Hz, acceleration at 100 Hz (blank after row 100)
        acc = f"{i / 100:.3f},{9.8 + 0.01 * (i % 7):.3f}" if i < 100 else ","
        rows.append(f"{i / 500:.4f},{i / 500:.4f},{acc}")
    log = read_log(_write(tmp_path, "own.csv", header + "\n".join(rows) + "\n"))
    (run,) = log.recordings
    assert run.n_samples == 100 and run.sample_rate_hz == pytest.approx(100.0)
    assert run.force is not None
    np.testing.assert_allclose(run.force[1:], run.time[1:], atol=1e-9)  # linear force: mean = t
    assert any("averaged" in w for w in log.warnings)


def test_quoted_decimal_comma_with_comma_delimiter(tmp_path: Path) -> None:
    text = '"Time (s)","Force (N)"\n"0","1,5"\n"0,05","-7,10E-15"\n"0,1","2"\n'
    log = read_log(_write(tmp_path, "quoted.csv", text))
    rec = log.recordings[0]
    np.testing.assert_allclose(rec.time, [0.0, 0.05, 0.1])
    assert rec.force is not None
    np.testing.assert_allclose(rec.force, [1.5, -7.1e-15, 2.0])


def test_force_on_its_own_time_column_without_acceleration_keeps_its_times(tmp_path: Path) -> None:
    header = "Time (s) Run #1,Acceleration z (m/s²) Run #1,Time (s) Run #1,Force (N) Run #1\n"
    rows = [f"{i / 100:.2f},,{i / 500:.4f},{i * 0.1:.1f}" for i in range(50)]
    log = read_log(_write(tmp_path, "f.csv", header + "\n".join(rows) + "\n"))
    (run,) = log.recordings
    assert run.accel is None and run.force is not None
    np.testing.assert_allclose(run.time, np.arange(50) / 500)
    assert any("acceleration column is empty" in w for w in log.warnings)


def test_a_force_past_the_50_n_range_is_another_sensor_not_one_at_its_limit(tmp_path: Path):
    """A 78 N push recorded by a larger sensor: nothing is at a limit (the PASCO ±50 N
    range is claimed only where the values stop at it)."""
    rows = [f"{i * 0.005:.3f},{78.0 + 0.1 * (i % 3) if i > 5 else 0.2},0,0,9.8" for i in range(40)]
    text = "Time (s),Force (N),Acceleration x (m/s²),Acceleration y (m/s²),Acceleration z (m/s²)\n"
    log = read_log(_write(tmp_path, "big.csv", text + "\n".join(rows) + "\n"))
    assert "force" not in log.recordings[0].saturated
    assert not any("sensor limit" in str(w) for w in log.warnings)
