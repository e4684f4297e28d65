"""Every real export in ``/work/shared/real_logs`` reads with the right layout and numbers.

The expected numbers were checked by hand against the files (``awk`` over the columns:
row counts, first and last times, median time step).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from balancer_id.read import Log, read_log

REAL_LOGS = next(  # ../shared next to the checkout, or one folder up for a worktree
    (
        p / "shared" / "real_logs"
        for p in Path(__file__).resolve().parents[2:4]
        if (p / "shared" / "real_logs").is_dir()
    ),
    Path(__file__).resolve().parents[2] / "shared" / "real_logs",
)

pytestmark = pytest.mark.skipif(not REAL_LOGS.is_dir(), reason="real_logs folder not present")


def _log(name: str) -> Log:
    path = REAL_LOGS / name
    if not path.is_file():
        pytest.skip(f"{name} not present")
    return read_log(path)


def test_capstone_style_semicolon_decimal_comma_bom() -> None:
    log = _log("pasco_style_force_semicolon_Tmpecho_rakettmotor_rakettdata.csv")
    assert log.format == "pasco-capstone"
    (rec,) = log.recordings
    assert rec.name == "Run #1"  # "Time (s) Auto" is the shared time of "Force (N) Run #1"
    assert rec.n_samples == 51
    assert rec.sample_rate_hz == pytest.approx(20.0)
    assert rec.time[0] == 0.0 and rec.time[-1] == pytest.approx(2.5)
    assert rec.force is not None and rec.accel is None
    assert rec.force[0] == pytest.approx(-7.10e-15, rel=1e-12)  # "-7,10E-15"
    assert rec.force[6] == pytest.approx(2.3)  # line 8: "0,3;2,3"
    assert rec.force.max() == pytest.approx(11.0)  # line 13: "0,55;11"
    assert rec.gaps == [] and rec.saturated == {}
    assert log.warnings == []


def test_sparkvue_accel_three_axes() -> None:
    log = _log("sparkvue_accel_fordaz570-boop_Acel_ExportedData.csv")
    assert log.format == "pasco-sparkvue"
    (rec,) = log.recordings
    assert rec.name == "Run 1"
    assert rec.n_samples == 131
    assert rec.sample_rate_hz == pytest.approx(20.0)
    assert (rec.time[0], rec.time[-1]) == (0.0, pytest.approx(6.5))
    assert rec.force is None
    assert rec.accel is not None and rec.accel.shape == (131, 3)
    assert rec.accel_axes == ("x", "y", "z")
    assert rec.accel_includes_gravity
    np.testing.assert_allclose(rec.accel[0], [-0.1, -0.3, 9.2])
    np.testing.assert_allclose(rec.accel[-1], [0.3, -0.5, 10.7])
    assert "Accel (Resultant) (m/s²)" not in rec.extra  # the resultant is ignored
    assert rec.gaps == []


def test_sparkvue_force_user_named_runs() -> None:
    log = _log("sparkvue_force_Ryguy-1_Lab-8-Data_ExportedData.csv")
    assert log.format == "pasco-sparkvue"
    names = [r.name for r in log.recordings]
    assert names == ["9.9", "11.4", "13.6", "15.2", "16.7", "17.7", "19.0", "20.1", "21.4"]
    counts = [r.n_samples for r in log.recordings]
    assert counts == [280, 314, 182, 220, 194, 230, 212, 196, 180]
    last = [r.time[-1] for r in log.recordings]
    np.testing.assert_allclose(last, [13.95, 15.65, 9.05, 10.95, 9.65, 11.45, 10.55, 9.75, 8.95])
    for rec in log.recordings:
        assert rec.sample_rate_hz == pytest.approx(20.0)
        assert rec.accel is None and rec.force is not None
        assert not np.isnan(rec.force).any()  # the padding of short runs is dropped
        assert rec.gaps == []
    assert log.recordings[4].force[0] == pytest.approx(-1.0)  # run 16.7, first row
    assert log.recordings[1].force[-1] == pytest.approx(-0.7)  # last line of the file


def test_sparkvue_motion_multirate_runs() -> None:
    log = _log("sparkvue_motion_multirate_piiskop_physics-spring-pendulum_ExportedData.csv")
    assert log.format == "pasco-sparkvue"
    assert [r.name for r in log.recordings] == ["Run 1", "Run 2", "Run 3"]
    # Acceleration (derived) is blank in the first two and the last rows of each run.
    assert [r.n_samples for r in log.recordings] == [38, 204, 1043]
    rates = [r.sample_rate_hz for r in log.recordings]
    np.testing.assert_allclose(rates, [20.0, 20.0, 100.0])
    firsts = [r.time[0] for r in log.recordings]
    lasts = [r.time[-1] for r in log.recordings]
    np.testing.assert_allclose(firsts, [0.1, 0.1, 0.02])
    np.testing.assert_allclose(lasts, [1.95, 10.25, 10.44])
    run3 = log.recordings[2]
    assert run3.accel is not None and run3.accel.shape == (1043, 1)
    assert run3.accel_axes == ("z",)
    assert not run3.accel_includes_gravity  # a motion sensor's kinematic acceleration
    assert run3.accel[0, 0] == pytest.approx(0.49)
    assert set(run3.extra) == {"Position (m)", "Velocity (m/s)"}
    assert run3.extra["Position (m)"][0] == pytest.approx(0.48)
    assert run3.extra["Velocity (m/s)"][0] == pytest.approx(-0.24)
    assert run3.force is None


@pytest.mark.parametrize(
    ("name", "n", "rate", "t0", "t1", "with_g", "row0"),
    [
        (
            "phyphox_accel_with_g_comma_100Hz_andrefcmoraes_phys.i_Raw_Data.csv",
            476,
            100.0828,
            0.0,
            4.749854859,
            True,
            [-1.340752989e-1, 6.224924326e-2, 9.763554573],
        ),
        (
            "phyphox_accelerometer_semicolon_XYZ_kartof0nix_AIR-math-tools_Accelerometer.csv",
            3560,
            100.7760,
            1.033708337e-3,
            35.31527508,
            True,
            [-1.422042847e-2, 6.764433289e-1, 9.927505646],
        ),
        (
            "phyphox_linear_accel_comma_200Hz_Kamyk0417_Opracowanie-fizyka_Raw_Data.csv",
            1741,
            197.9463,
            5.250333700e-2,
            8.873459431,
            False,
            [0.0, 0.0, 0.0],
        ),
        (
            "phyphox_linear_accel_tab_200Hz_Tecnicianapprentice_Comunicacion-digital_Raw_Data.csv",
            2162,
            206.3720,
            2.269948700e-2,
            10.54990258,
            False,
            [3.168015957, -6.462129951e-1, 3.733539879e-1],
        ),
    ],
)
def test_phyphox_exports(
    name: str, n: int, rate: float, t0: float, t1: float, with_g: bool, row0: list[float]
) -> None:
    log = _log(name)
    assert log.format == "phyphox"
    (rec,) = log.recordings
    assert rec.n_samples == n
    assert rec.sample_rate_hz == pytest.approx(rate, abs=1e-3)
    assert rec.time[0] == pytest.approx(t0, abs=1e-12)
    assert rec.time[-1] == pytest.approx(t1)
    assert rec.accel_includes_gravity is with_g
    assert rec.accel is not None and rec.accel.shape == (n, 3)
    np.testing.assert_allclose(rec.accel[0], row0, rtol=1e-9, atol=1e-12)
    assert rec.force is None
    assert rec.extra == {}  # "Absolute acceleration" is ignored


def test_phyphox_semicolon_without_final_newline_keeps_last_row() -> None:
    log = _log("phyphox_accelerometer_semicolon_XYZ_kartof0nix_AIR-math-tools_Accelerometer.csv")
    rec = log.recordings[0]
    assert rec.accel is not None
    np.testing.assert_allclose(rec.accel[-1], [7.176077271e-1, -3.431314545, 9.385183411])


def test_phyphox_tab_dropped_samples_are_gaps_not_interpolated() -> None:
    log = _log(
        "phyphox_linear_accel_tab_200Hz_Tecnicianapprentice_Comunicacion-digital_Raw_Data.csv"
    )
    rec = log.recordings[0]
    # Lines 426 and 427 of the file: steps of 46.0 ms and 19.4 ms at a 4.85 ms median step.
    assert [(g.t_before, g.t_after, g.n_missing) for g in rec.gaps] == [
        (pytest.approx(2.072385006), pytest.approx(2.118431707), 9),
        (pytest.approx(2.118431707), pytest.approx(2.137814537), 3),
    ]
    assert rec.n_samples == 2162  # nothing inserted
    assert any("gap" in w for w in log.warnings)
