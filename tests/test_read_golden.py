"""One small hand-written file per layout (``tests/golden/``), with every value asserted."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from balancer_id.constants import G_DEFAULT
from balancer_id.read import Gap, read_log

GOLDEN = Path(__file__).resolve().parent / "golden"


def test_capstone_golden() -> None:
    """BOM, CRLF, ``;`` with decimal comma, E notation, two ragged runs, a dropped sample."""
    log = read_log(GOLDEN / "capstone_semicolon_decimal_comma.csv")
    assert log.format == "pasco-capstone"
    run1, run2 = log.recordings
    assert (run1.name, run2.name) == ("Run #1", "Run #2")
    np.testing.assert_allclose(run1.time, [0.0, 0.005, 0.01, 0.02, 0.025])
    assert run1.force is not None and run1.accel is not None
    np.testing.assert_allclose(run1.force, [-7.10e-15, 0.03, 2.45, 2.48, 2.44], rtol=1e-12)
    np.testing.assert_allclose(
        run1.accel,
        [[0.1, -0.2, 9.8], [0.2, -0.2, 9.6], [0.0, 0.0, 10.0], [0.0, 0.2, 9.8], [0.2, 0.0, 9.8]],
    )
    assert run1.sample_rate_hz == pytest.approx(200.0)
    assert run1.gaps == [Gap(0.01, 0.02, 1)]
    np.testing.assert_allclose(run2.time, [0.0, 0.005, 0.01])  # padding dropped
    assert run2.force is not None and run2.accel is not None
    np.testing.assert_allclose(run2.force, [1.5, 1.53, 1.56])
    np.testing.assert_allclose(run2.accel[:, 2], [9.7, 9.9, 9.8])
    assert run2.gaps == []
    assert run1.accel_includes_gravity and run2.accel_includes_gravity
    assert len(log.warnings) == 1 and "gap" in log.warnings[0]


def test_sparkvue_golden() -> None:
    """User-named runs, resultant column, derived column blank at the edges, two rates."""
    log = read_log(GOLDEN / "sparkvue_named_runs.csv")
    assert log.format == "pasco-sparkvue"
    first, second = log.recordings
    assert first.name == "9.9"
    np.testing.assert_allclose(first.time, [0.0, 0.05, 0.1])
    assert first.force is not None and first.accel is not None
    np.testing.assert_allclose(first.force, [0.0, 0.1, -0.9])
    np.testing.assert_allclose(first.accel, [[0.1, -0.3, 9.2], [0.4, -0.5, 10.2], [0.0, -0.4, 9.6]])
    assert first.extra == {}  # "Accel (Resultant)" is ignored
    assert first.sample_rate_hz == pytest.approx(20.0)
    assert second.name == "Trial B"
    np.testing.assert_allclose(second.time, [0.01, 0.02, 0.03])
    assert second.force is None and second.accel is not None
    assert second.accel.shape == (3, 1) and second.accel_axes == ("z",)
    np.testing.assert_allclose(second.accel[:, 0], [0.43, -0.24, 0.92])
    assert not second.accel_includes_gravity
    np.testing.assert_allclose(second.extra["Position (m)"], [0.49, 0.48, 0.48])
    assert second.sample_rate_hz == pytest.approx(100.0)
    assert log.warnings == []


def test_phyphox_golden() -> None:
    """``;`` + decimal comma, NaN row, empty gyro cell, no final newline, time from 1.25 s."""
    log = read_log(GOLDEN / "phyphox_semicolon_decimal_comma.csv")
    assert log.format == "phyphox"
    (rec,) = log.recordings
    assert rec.name == "Run 1"
    np.testing.assert_allclose(rec.time, [1.25, 1.27, 1.28, 1.29])  # the NaN row is dropped
    assert rec.accel is not None and not rec.accel_includes_gravity
    np.testing.assert_allclose(
        rec.accel, [[0.01, -0.02, 0.3], [0.02, 0.0, -1.0], [-0.005, 0.04, 0.75], [0.0, 0.0, 0.0]]
    )
    gyro = rec.extra["Gyroscope x (rad/s)"]
    np.testing.assert_allclose(gyro, [0.0015, np.nan, 0.002, 0.0])  # empty cell -> NaN
    assert set(rec.extra) == {"Gyroscope x (rad/s)"}  # "Absolute acceleration" ignored
    assert rec.gaps == [Gap(1.25, 1.27, 1)]
    assert rec.sample_rate_hz == pytest.approx(100.0)


def test_generic_golden_guess_and_g_units() -> None:
    """Names guessed from keywords; values in g found from the resting magnitude."""
    log = read_log(GOLDEN / "generic_keywords_in_g.csv")
    assert log.format == "generic"
    (rec,) = log.recordings
    np.testing.assert_allclose(rec.time, [10.0, 10.005, 10.01, 10.015])
    assert rec.force is not None and rec.accel is not None
    np.testing.assert_allclose(rec.force, [0.0, 0.03, 2.45, 2.46])
    expected = np.array(
        [[0.01, -0.02, 1.0], [0.0, -0.01, 1.01], [0.02, 0.0, 0.99], [0.01, -0.02, 1.02]]
    )
    np.testing.assert_allclose(rec.accel, expected * G_DEFAULT)
    assert rec.accel_includes_gravity
    assert len(log.warnings) == 1 and "looks like g" in log.warnings[0]
    (guess,) = [n for n in log.notes if n.code == "read.column_guess"]
    assert guess.text == (
        "columns guessed from their names: time=timestamp,force=F_load,ax=acc_x,ay=acc_y,"
        "az=acc_z (pass --columns to choose others)"
    )


def test_generic_golden_with_column_map_case_insensitive() -> None:
    log = read_log(
        GOLDEN / "generic_keywords_in_g.csv",
        columns={"time": "TIMESTAMP", "force": "f_load", "a": "ACC_Z"},
        accel_unit="g",
    )
    assert log.format == "generic"
    (rec,) = log.recordings
    assert rec.accel is not None and rec.accel.shape == (4, 1) and rec.accel_axes == ("z",)
    np.testing.assert_allclose(rec.accel[:, 0], np.array([1.0, 1.01, 0.99, 1.02]) * G_DEFAULT)
    assert rec.accel_includes_gravity
    assert log.warnings == []  # the unit was given


def test_sensor_logger_golden() -> None:
    """``time`` in ns since 1970, ``seconds_elapsed``, axes in the order z, y, x, no units."""
    log = read_log(GOLDEN / "sensorlogger_accelerometer.csv")
    assert log.format == "sensor-logger"
    (rec,) = log.recordings
    np.testing.assert_allclose(rec.time, [0.0, 0.01, 0.02, 0.04], atol=1e-12)
    assert rec.accel is not None and rec.accel_axes == ("x", "y", "z")
    np.testing.assert_allclose(rec.accel[0], [0.10, 0.20, 0.30])  # x, y, z from z, y, x
    assert not rec.accel_includes_gravity  # |a| ~0.4: no gravity
    (gap,) = rec.gaps
    assert (gap.t_before, gap.t_after, gap.n_missing) == (
        pytest.approx(0.02),
        pytest.approx(0.04),
        1,
    )
    assert rec.started_at == pytest.approx(1760565906.248623, abs=1e-6)
    assert log.started_at == rec.started_at
    (unit,) = [n for n in log.notes if n.code == "read.time_unit"]
    assert "2025-10-15 22:05:06 UTC" in unit.text


def test_vernier_golden() -> None:
    """``Data Set N:Quantity(unit)``: one run per data set, each on its own time column."""
    log = read_log(GOLDEN / "vernier_graphical_analysis.csv")
    assert log.format == "vernier"
    accel, force = log.recordings
    assert (accel.name, force.name) == ("Data Set 1", "Data Set 2")
    np.testing.assert_allclose(accel.time, [0.0, 0.05, 0.1])
    assert accel.accel is not None and accel.accel.shape == (3, 1)
    np.testing.assert_allclose(accel.accel[:, 0], [0.04, 0.05, -0.06])
    assert not accel.accel_includes_gravity and accel.force is None
    assert "Position (m)" in accel.extra
    assert force.force is not None
    np.testing.assert_allclose(force.force, [1.5, 1.6, 1.7, 1.8])


@pytest.mark.parametrize(
    ("header", "force", "axes"),
    [
        ("Latest: Time (s),Latest: Force (N)", True, 0),  # Graphical Analysis
        (
            "Run 1: Time (s),Run 1: X-axis acceleration (m/s²),"
            "Run 1: Y-axis acceleration (m/s²),Run 1: Z-axis acceleration (m/s²)",
            False,
            3,
        ),  # LabQuest / Logger Pro, a 3-axis accelerometer
    ],
)
def test_vernier_prefixes(tmp_path, header: str, force: bool, axes: int) -> None:
    n_values = header.count(",")
    rows = [
        ",".join(
            [f"{0.01 * i:.2f}"]
            + ["9.8" if k == n_values else "0.1" for k in range(1, n_values + 1)]
        )
        for i in range(20)
    ]
    path = tmp_path / "vernier.csv"
    path.write_text(header + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    log = read_log(path)
    assert log.format == "vernier"
    (rec,) = log.recordings
    assert rec.name == header.split(":")[0]
    assert (rec.force is not None) == force
    assert (0 if rec.accel is None else rec.accel.shape[1]) == axes
    if axes == 3:
        assert rec.accel_axes == ("x", "y", "z") and rec.accel_includes_gravity


def test_sensor_logger_gyroscope_file_is_not_read_as_acceleration(tmp_path) -> None:
    """Sensor Logger writes the same header for every sensor: the file name tells them apart."""
    from balancer_id.errors import LogReadError

    path = tmp_path / "Gyroscope.csv"
    path.write_bytes((GOLDEN / "sensorlogger_accelerometer.csv").read_bytes())
    with pytest.raises(LogReadError, match=r"'gyroscope' file .* no acceleration"):
        read_log(path)
    mapped = {"time": "seconds_elapsed", "ax": "x", "ay": "y", "az": "z"}
    assert read_log(path, columns=mapped).recordings[0].n_samples == 4  # the map decides


def test_sparkvue_wall_clock_gives_each_run_its_start() -> None:
    """SPARKvue's ``Date and Time <run>``: the first cell of each run, in local time."""
    from datetime import datetime

    log = read_log(GOLDEN / "sparkvue_named_runs.csv")
    first, second = log.recordings
    assert first.started_at == datetime(2026, 1, 13, 8, 33, 11).timestamp()
    assert second.started_at == datetime(2022, 5, 6, 14, 36, 52).timestamp()
    assert log.started_at == second.started_at  # the earliest run
