"""Tracking a parameter in time within one session (issue 33, ``fit --track``)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from simlib.drift import alternating_levels, record_drifting
from simlib.sessions import session_thrust, write_recordings

from balancer_id.errors import UsageError
from balancer_id.identify.api import fit
from balancer_id.identify.random_walk import smooth_walk
from balancer_id.model import parse_model
from balancer_id.simulation.synth import SensorSettings

TRUTH = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
MODEL = parse_model("variable_viscosity")
DURATION = 120.0


def _warming(t):
    """Oil warming at the issue's rate (8 -> 4 kg/s over 10 min): 0.4 kg/s a minute."""
    return 7.0 - 0.4 * t / 60.0


def _session(tmp_path, d0_of_t, seed: int, name: str = "s.csv", duration: float = DURATION):
    rng = np.random.default_rng(seed)
    thrust = session_thrust(alternating_levels(int((duration - 2) / 8), rng), 8.0)
    rec = record_drifting(
        MODEL, lambda t: {**TRUTH, "D0": d0_of_t(t)}, thrust, duration,
        sensor=SensorSettings(tilt_deg=8.0), seed=seed,
    )
    path = tmp_path / name
    write_recordings(path, [rec])
    return path


@pytest.fixture(scope="module")
def falling(tmp_path_factory):
    """A 4-min session with D0 falling 7 -> 5.4 kg/s (oil warming at the issue's rate,
    8 -> 4 over 10 min), its path and fit."""
    # 4 minutes, not 2: over 2 minutes (7 blocks, an 11 % fall) "moving" at p < 0.001 held
    # on 1 of 5 seeds (p 0.0009-0.005; 0.0013-0.05 once the resting level is pooled over
    # the log); over 4 minutes, p < 1e-5 on 5 of 5
    path = _session(tmp_path_factory.mktemp("falling"), _warming, 3, duration=240.0)
    return path, fit(str(path), track=["D0"])


def test_a_falling_viscosity_is_tracked_inside_its_band(falling):
    _, result = falling
    track = result.tracking.tracks["D0"]
    truth = _warming(track.time_s)
    assert track.moving
    inside = np.mean((truth >= track.lo) & (truth <= track.hi))
    assert inside >= 0.7, inside  # a 95 % band, 7 blocks
    assert abs(track.value[0] - truth[0]) < 0.25 and abs(track.value[-1] - truth[-1]) < 0.25
    # the other parameters refitted with D0 moving: the joint fit's blend is gone
    assert abs(result.tracking.shared["m_a"] - 15.1) < 0.15
    out = result.to_dict()["tracking"]["parameters"]["D0"]
    assert -2.0 < out["end_minus_start"]["change"] < -0.9  # the truth: -1.6
    lo, hi = out["largest_change"]["ci95"]
    assert lo < out["largest_change"]["change"] < hi < 0


def test_a_constant_viscosity_is_not_called_moving(tmp_path):
    path = _session(tmp_path, lambda t: 6.0, seed=4)
    track = fit(str(path), track=["D0"]).tracking.tracks["D0"]
    assert not track.moving
    assert np.all(track.lo < 6.0 + 0.1) and np.all(track.hi > 6.0 - 0.1)


def test_walk_smoother_follows_a_step_and_stays_flat_without_one():
    rng = np.random.default_rng(0)
    t = np.arange(60.0) * 10
    se = np.full(t.size, 0.1)
    step = np.where(t < 300, 1.0, 2.0)
    w = smooth_walk(t, step + rng.normal(0, 0.1, t.size), se)
    assert w.p_value < 1e-6
    assert abs(w.value[5] - 1.0) < 0.1 and abs(w.value[-5] - 2.0) < 0.1
    flat = smooth_walk(t, 1.0 + rng.normal(0, 0.1, t.size), se)
    assert flat.ratio == 0.0 or flat.p_value > 0.01
    assert np.ptp(flat.value) < 0.05


def test_track_names_are_checked_before_reading(tmp_path):
    with pytest.raises(UsageError, match="--track X: not a parameter"):
        fit(str(tmp_path / "missing.csv"), track=["X"])
    with pytest.raises(UsageError, match="held with --fix"):
        fit(str(tmp_path / "missing.csv"), track=["D0"], fixed={"D0": 5.0})


def test_cli_track_prints_start_end_and_writes_series(tmp_path, cli, falling):
    path, _ = falling
    series = tmp_path / "out.csv"
    code, out, err = cli("fit", path, "--track", "D0", "--series", series, "--json")
    # 5: the joint fit's constant D0 misfits a 22 % fall (its residual is correlated) and
    # says so; the track is written either way
    assert code in (0, 5), err
    d = json.loads(out)["tracking"]["parameters"]["D0"]
    assert d["moving"] and d["start"]["value"] > d["end"]["value"] + 0.4
    text = (tmp_path / "out-track.csv").read_text()
    assert text.startswith("parameter,time_s,value,ci95_low,ci95_high,local,local_stderr")
    code, out, err = cli("fit", path, "--track", "D0")
    assert code in (0, 5), err
    assert "D0 [kg/s]: moves" in out and "largest change" in out
    code, _, err = cli("fit", path, "--track", "X")
    assert code == 2 and "--track X: not a parameter" in err


def test_library_display_and_report_show_the_track(falling, tmp_path):
    _, result = falling
    assert "D0 [kg/s]: moves" in result.summary()
    assert "tracked in time" in result._repr_html_()
    assert "D0 [kg/s]" in result.tracking._repr_html_()
    frame = result.tracking.to_frame()
    assert list(frame["parameter"].unique()) == ["D0"]
    assert (frame["ci95_low"] < frame["value"]).all()
    png = result.tracking.plot(tmp_path / "track.png")
    assert png.read_bytes()[:4] == b"\x89PNG"
    from balancer_id.report.document import write_fit_report

    html = write_fit_report(result, tmp_path / "fit.html").read_text(encoding="utf-8")
    assert "Parameters in time" in html and "data:image/png" in html


def test_a_moving_within_two_level_blocks_does_not_pull_the_shared_values(tmp_path, monkeypatch):
    # A (tracked in blocks of two levels, the light one first) warming up fast at 1.5 kg:
    # each block's one A and the shared D0 took up A's change between the block's trials,
    # the same way in every block (D0 3 % low, the truth outside the band at 13 of 14
    # blocks). With each trial's offset from the smoothed path in the model, they do not.
    import balancer_id.identify.tracking as tracking

    k = 1.5 / 15.1
    truth = {"m_a": 1.5, "T_a": 0.12, "D0": 6.0 * k, "A": 0.4 / k}
    dur = 300.0

    def a_of(t):
        return truth["A"] * (1 - 0.34 * (1 - np.exp(-np.asarray(t) / (0.25 * dur))))

    rng = np.random.default_rng(220352449)
    hold = float(rng.integers(6, 11))
    levels = [x * k for x in alternating_levels(int((dur - 2) / hold), rng)]
    rec = record_drifting(
        MODEL, lambda t: {**truth, "A": float(a_of(t))}, session_thrust(levels, hold), dur,
        sensor=SensorSettings(accel_noise=0.03, force_noise=0.001,
                              tilt_deg=float(rng.uniform(3, 20))),
        seed=220352449,
    )
    path = tmp_path / "warm.csv"
    write_recordings(path, [rec])
    result = fit(str(path), track=["A"], profile=False)
    track = result.tracking.tracks["A"]
    inside = np.mean((a_of(track.time_s) >= track.lo) & (a_of(track.time_s) <= track.hi))
    assert inside >= 0.85, inside
    assert result.tracking.shared["D0"] == pytest.approx(truth["D0"], rel=0.015)
    monkeypatch.setattr(tracking, "WITHIN_PASSES", 0)  # uncorrected: pulled
    pulled = fit(str(path), track=["A"], profile=False).tracking
    assert pulled.shared["D0"] < 0.98 * truth["D0"]
