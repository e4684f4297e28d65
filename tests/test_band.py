"""Response bands (issue 34.1): the covariance carried through the sensitivities, the band
widened by the noise, and the stretches where a measurement leaves it."""

from __future__ import annotations

import numpy as np
import pytest
from test_fit import step_trials

from balancer_id.identify import fit_match, match_trials
from balancer_id.identify.band import covariance_of, noise_sigma, response_band
from balancer_id.identify.data import FitData
from balancer_id.model import parse_model

TRUTH = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
THRUSTS = [2.45, -4.9, 7.35]


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.default_rng(3)
    trials = step_trials("variable_viscosity", TRUTH, THRUSTS, 0.03, rng, seconds=6.0)
    match = match_trials(parse_model(), trials, start={"m_a": 14.0, "T_a": 0.3})
    return match, fit_match(match)


def test_band_is_the_covariance_through_the_sensitivities(fitted):
    # delta method checked against finite differences of the simulation: the variance at
    # each sample is g^T C g with g the response's gradient
    match, _ = fitted
    names, cov = covariance_of(match)
    model = match.model
    base = np.asarray(model.vector(match.values()), float)
    grads = []
    for name in names:
        i = model.param_names.index(name)
        h = 1e-4 * abs(base[i])
        up, down = base.copy(), base.copy()
        up[i] += h
        down[i] -= h
        packed = match.data.packed
        grads.append((packed.run(model, up)[:, 0] - packed.run(model, down)[:, 0]) / (2 * h))
    g = np.array(grads).T
    sd_fd = np.sqrt(np.einsum("ij,jk,ik->i", g, cov, g))
    band = response_band(match)
    sd = (band.model_high - band.model_low) / (2 * 1.959963984540054)
    moving = sd_fd > 0.2 * sd_fd.max()
    assert np.allclose(sd[moving], sd_fd[moving], rtol=0.02)
    assert np.all(band.model_low <= band.simulated + 1e-15)
    assert np.all(band.simulated <= band.model_high + 1e-15)


def test_noise_band_holds_new_measurements_at_the_nominal_rate(fitted):
    # a held-out recording of the same balancer (fresh noise, another thrust): 95 % of its
    # samples fall inside the band widened by the noise
    match, result = fitted
    rng = np.random.default_rng(11)
    new = step_trials("variable_viscosity", TRUTH, [-3.5, 6.0], 0.03, rng, seconds=6.0)
    band = result.band(new)
    y = FitData.build(new).y
    assert noise_sigma(match) == pytest.approx(0.03, rel=0.1)
    assert 0.93 <= band.coverage(y) <= 0.97
    assert band.stretches(y) == []


def test_wrong_model_leaves_the_band_in_stretches():
    # the viscosity falls with the thrust (A = 0.4) but a constant one is fitted: the
    # measurement leaves the noise band over seconds, on the light and heavy steps
    rng = np.random.default_rng(5)
    trials = step_trials("variable_viscosity", TRUTH, [2.45, -7.35], 0.02, rng, seconds=8.0)
    match = match_trials(parse_model("viscous"), trials, start={"m_a": 14.0, "T_a": 0.3})
    band = response_band(match)
    found = band.stretches(match.y)
    assert found, "a misfit of several noise levels must show"
    assert sum(s.t_end - s.t_start for s in found) > 1.0
    assert band.coverage(match.y) < 0.9


def test_frame_and_series_carry_the_band(fitted):
    _, result = fitted
    frame = result.to_frame()
    for col in ("model_low", "model_high", "noise_low", "noise_high"):
        assert col in frame
    assert (frame.noise_low <= frame.model_low + 1e-12).all()
    assert (frame.model_high <= frame.noise_high + 1e-12).all()
    inside = (frame.measured >= frame.noise_low) & (frame.measured <= frame.noise_high)
    assert 0.93 <= inside.mean() <= 0.97


def test_fit_series_writes_band_columns(cli, tmp_path):
    out = tmp_path / "series.csv"
    code, _, err = cli("fit", "sample_logs/paper_balancer.csv", "--series", str(out))
    assert code == 0, err
    header = out.read_text().splitlines()[0].split(",")
    assert header[-4:] == ["model_low", "model_high", "noise_low", "noise_high"]


def test_fit_json_summarises_the_band(fitted, cli):
    # the right model: about 5 % of the samples outside the noise band, no failing stretch,
    # one entry per trial whose half-widths are the band's own
    _, result = fitted
    d = result.to_dict()["band"]
    band = result.band()
    assert d["method"] == "covariance" and d["level"] == 0.95
    assert 0.03 <= d["share_outside"] <= 0.07
    assert d["failing_stretches"] == 0
    assert [t["index"] for t in d["trials"]] == [td.index for td in band.trials]
    first = band.slices()[0]
    half = (band.model_high[first] - band.model_low[first]) / 2
    assert d["trials"][0]["model_halfwidth_median"] == pytest.approx(np.median(half))
    assert all(t["noise_halfwidth_median"] > t["model_halfwidth_median"] for t in d["trials"])
    assert d["noise_halfwidth_median"] == pytest.approx(1.96 * d["sigma"], rel=0.05)
    code, out, err = cli("fit", "sample_logs/paper_balancer.csv", "--json", "--no-cache")
    assert code == 0, err
    import json

    assert 0.0 <= json.loads(out)["band"]["share_outside"] <= 0.1


def test_fit_json_band_shows_a_wrong_model():
    from balancer_id.identify.band import band_summary

    rng = np.random.default_rng(5)
    trials = step_trials("variable_viscosity", TRUTH, [2.45, -7.35], 0.02, rng, seconds=8.0)
    match = match_trials(parse_model("viscous"), trials, start={"m_a": 14.0, "T_a": 0.3})
    d = band_summary(response_band(match), match.y)
    assert d["share_outside"] > 0.1
    assert d["failing_stretches"] >= 1
    assert max(t["share_outside"] for t in d["trials"]) > 0.15
