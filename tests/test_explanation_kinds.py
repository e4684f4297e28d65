"""The registry of explanation kinds, and the sensor's and the time trend's kinds."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import PAPER, PAPER_THRUSTS

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.arena import ArenaInput
from balancer_id.diagnostics.explanations import KINDS, Verdict, kind_of
from balancer_id.diagnostics.explanations.force_delay import ForceDelay
from balancer_id.diagnostics.explanations.sensor_clipping import pinned_level, soft_clip
from balancer_id.diagnostics.explanations.sensor_gain import SensorGain
from balancer_id.diagnostics.explanations.time_trend import _wander_design, blocks
from balancer_id.identify.data import TrialData
from balancer_id.identify.matching import match_trials
from balancer_id.model import parse_model
from balancer_id.read.recording import Log
from balancer_id.segment import find_trials
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings

#: The m_a and T_a held at the truth in the quick fits below (the kinds vary the rest).
HOLD = {"m_a": PAPER["m_a"]}


def test_every_kind_is_complete_and_listed_once():
    keys = [k.key for k in KINDS]
    assert len(keys) == len(set(keys))
    for k in KINDS:
        assert k.kind and k.mimics and k.separating_trial, k.key
        assert isinstance(k.verdict, Verdict)
        assert kind_of(k.key) is k
    # the JSON contract's strings (CONTRACT.md) are the enum's values
    assert {v.value for v in Verdict} == {
        "adequate",
        "effect missing",
        "parameter changed",
        "parameter drift",
        "sensor effect",
        "ambiguous",
    }
    assert {k.kind for k in KINDS} == {
        "effect",
        "split",
        "drift",
        "trend",
        "sensor",
        "pair",
        "discovered",
    }
    # an unknown key (an old record) is a missing effect, as before
    assert kind_of("no such kind").verdict == Verdict.EFFECT_MISSING


def _trials(recs: list) -> list[TrialData]:
    trials = [
        TrialData.from_trial(t) for t in find_trials(Log(Path("k.csv"), "pasco-capstone", recs))
    ]
    for k, td in enumerate(trials):
        td.index = k
    return trials


def _recordings(seed: int, thrusts=PAPER_THRUSTS[:4], **sensor) -> list:
    settings = SensorSettings(tilt_deg=8.0, accel_noise=0.02, force_noise=0.02, **sensor)
    recs = synthetic_recordings(
        parse_model("variable_viscosity"), PAPER, list(thrusts), sensor=settings, seed=seed
    )
    return [dataclasses.replace(r, name=f"Run #{k + 1}") for k, r in enumerate(recs)]


def _arena(trials: list[TrialData], fit: object = None) -> ArenaInput:
    model = parse_model("variable_viscosity")
    match = match_trials(model, trials, start={"T_a": 0.3, "D0": 6.0, "A": 0.4}, fixed=HOLD)
    return ArenaInput(
        match=match,
        trials=trials,
        runs=[td.source for td in trials],
        noise_floor=0.02,
        independence=arena.independence(match),
        threads=1,
        fit=fit,  # type: ignore[arg-type]
    )


def _late_force(recs: list, delay: float) -> list:
    return [dataclasses.replace(r, force=np.interp(r.time - delay, r.time, r.force)) for r in recs]


def test_a_late_force_channel_is_found_with_its_interval_and_no_delay_is_null():
    recs = _recordings(5)
    late = ForceDelay().propose(_arena(_trials(_late_force(recs, 0.040))))
    (e,) = late
    d, se = e.detail["force_delay_s"], e.detail["force_delay_stderr_s"]
    # 40 ms within 4 standard errors (and a few ms: the 5 ms sample interval)
    assert isinstance(se, float) and se < 0.01
    assert abs(d - 0.040) < max(4 * se, 0.006)
    assert e.delta_bic > arena.BIC_THRESHOLD and not e.null
    assert e.detail["late_channel"] == "force" and e.verdict == Verdict.SENSOR_EFFECT
    # the same log on time: the shift found is under a sample, or worth nothing
    (e0,) = ForceDelay().propose(_arena(_trials(recs)))
    assert e0.null or e0.delta_bic < arena.BIC_THRESHOLD


def test_a_late_acceleration_is_the_twin_of_a_dead_time():
    kind = ForceDelay()
    late_accel = kind.make(
        "acceleration channel 50 ms late",
        200.0,
        0.02,
        detail={"force_delay_s": -0.050, "force_delay_stderr_s": 0.002, "sample_interval_s": 0.005},
    )
    dead = kind_of("effect").make(
        "+dead_time", 205.0, 0.02, effects=["dead_time"], detail={"values": {"tau_d": 0.049}}
    )
    other = kind_of("effect").make(
        "+dead_time", 205.0, 0.02, effects=["dead_time"], detail={"values": {"tau_d": 0.150}}
    )
    assert kind.twin(late_accel, dead)  # the same delay: no recording of this kind tells
    assert not kind.twin(late_accel, other)  # another delay
    late_force = dataclasses.replace(
        late_accel, detail={**late_accel.detail, "force_delay_s": 0.05}
    )
    assert not kind.twin(late_force, dead)  # a dead time cannot make the force late
    from balancer_id.diagnostics.verdict import rivals

    assert rivals(dead, late_accel, confounded=False)


def test_a_hot_accelerometer_is_its_gain_and_a_true_one_is_not_proposed():
    recs = _recordings(7)
    log = SimpleNamespace(log=SimpleNamespace(recordings=recs))
    fit = SimpleNamespace(trial_set=SimpleNamespace(logs=[log], options=SimpleNamespace(g=9.8)))
    hot = [dataclasses.replace(r, accel=r.accel * 1.05) for r in recs]
    (e,) = SensorGain().propose(_arena(_trials(hot), fit))
    assert abs(e.detail["gain"] - 1.05) < 0.005
    assert abs(e.detail["rest_magnitude"] - 1.05 * 9.8) < 0.02
    assert e.verdict == Verdict.SENSOR_EFFECT and e.delta_bic > arena.BIC_THRESHOLD
    # m_a held at the truth, D0 carries the gain's share of the response when it is
    # left out: with the gain fitted, D0 is the truth's again
    assert abs(e.detail["values"]["D0"] - PAPER["D0"]) / PAPER["D0"] < 0.05
    assert SensorGain().propose(_arena(_trials(recs), fit)) == []
    # a bias effect that fits as well is the same sensor read as an offset
    bias = kind_of("effect").make("+bias", e.delta_bic + 1.0, 0.02, effects=["bias"])
    assert SensorGain().absorbs(e, bias)


def test_clipping_is_runs_at_one_value_or_a_band_two_trials_reach():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 1, 200)
    peaks = [np.sin(np.pi * t) * h for h in (1.0, 0.7, -1.0)]
    noisy = [p + rng.normal(0, 0.01, p.size) for p in peaks]
    assert pinned_level(noisy, 1.0, 0.03) is None  # one trial peaks there, once
    clipped = [np.minimum(p, 0.6) for p in noisy]
    level, n = pinned_level(clipped, 1.0, 0.03)
    assert level == pytest.approx(0.6) and n >= 20
    # projected through a tilted sensor: beyond the knee it still grows a little
    soft = [soft_clip(p, 0.6, 0.05, 1.0) + rng.normal(0, 0.01, p.size) for p in peaks]
    found = pinned_level(soft, 1.0, 0.03)
    assert found is not None and 0.6 <= found[0] <= 0.65
    # one trial clipped, nearly vertical: its samples at the limit have lost their noise
    lower = noisy[1] * 0.5 / 0.7  # peaks under the limit
    one = [np.minimum(noisy[0], 0.6 + rng.normal(0, 0.001, t.size)), lower, noisy[2]]
    assert pinned_level(one, 1.0, 0.03) is None  # one trial in the band: not enough alone
    level, n = pinned_level(one, 1.0, 0.03, noise=0.01)
    assert 0.6 <= level <= 0.605 and n >= 20
    assert pinned_level(noisy, 1.0, 0.03, noise=0.01) is None  # a noisy peak keeps its noise
    assert np.allclose(soft_clip(np.array([0.5, 0.8]), 0.6, 0.0, 1.0), [0.5, 0.6])
    assert np.allclose(soft_clip(np.array([-0.5, -0.8]), -0.6, 0.1, -1.0), [-0.5, -0.62])


def test_blocks_cut_long_runs_in_time_and_leave_short_ones_whole():
    def td(source: str, t0: float) -> SimpleNamespace:
        return SimpleNamespace(source=source, time=np.array([t0, t0 + 8.0]))

    trials = [td("s", 8.0 * k) for k in range(12)] + [td("r", 0.0), td("q", 0.0)]
    inp = SimpleNamespace(trials=trials, runs=[x.source for x in trials])
    b = blocks(inp)  # type: ignore[arg-type]
    assert b is not None and b.span_s == pytest.approx(96.0)
    long = [g for g in b.groups if len(g) > 1]
    assert [i for g in long for i in g] == list(range(12)) and len(long) == 6
    taus = [float(tau) for g, tau in zip(b.groups, b.tau, strict=True) if len(g) > 1]
    assert taus[0] < -0.35 and taus[-1] > 0.35 and taus == sorted(taus)
    assert [g for g in b.groups if len(g) == 1] == [[12], [13]]
    short = SimpleNamespace(trials=trials[:5], runs=["s"] * 5)
    assert blocks(short) is None  # type: ignore[arg-type]
    # the trend with a value per block: one column per block of a long run after its
    # first; the short runs' trials keep the base
    design = _wander_design(b)
    assert design is not None and design.shape == (len(b.groups), 5)
    rows = {tuple(r) for r in design[:6]}
    assert design[0].sum() == 0 and len(rows) == 6  # the first block is the base
    assert np.all(design[6:] == 0) and np.all(design.sum(axis=0) == 1)
    # two long runs: each run's first block is its base
    two = [td("s", 8.0 * k) for k in range(8)] + [td("t", 8.0 * k) for k in range(8)]
    b2 = blocks(SimpleNamespace(trials=two, runs=[x.source for x in two]))  # type: ignore[arg-type]
    d2 = _wander_design(b2)
    assert d2 is not None and d2.shape == (8, 6)
    assert d2[0].sum() == 0 and d2[4].sum() == 0


def test_force_delay_moves_the_force_back_when_read_and_is_refused_out_of_range(tmp_path):
    from balancer_id.errors import UsageError
    from balancer_id.read import write_log
    from balancer_id.trials import ReadOptions, read

    recs = _recordings(11, thrusts=PAPER_THRUSTS[:1])
    late = _late_force(recs, 0.040)
    path = tmp_path / "late.csv"
    write_log(path, late, "pasco-capstone")
    options = ReadOptions(force_delay=0.040)
    moved = read(path, options).recordings[0]
    # the step is back where it was (within the written precision), not 40 ms late
    step = np.flatnonzero(np.abs(np.diff(recs[0].force)) > 1.0)[0]
    back = np.flatnonzero(np.abs(np.diff(moved.force)) > 1.0)[0]
    assert abs(back - step) <= 1
    assert options.cli_args() == ["--force-delay", "0.04"]
    with pytest.raises(UsageError, match="--force-delay"):
        ReadOptions(force_delay=2.0)
