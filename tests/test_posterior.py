"""Posterior sampling (issue 34.2): credible intervals that respect the bounds where Wald's
do not, agree with Wald's where the cost is quadratic, and priors checked up front."""

from __future__ import annotations

import numpy as np
import pytest
from test_fit import step_trials

from balancer_id.errors import UsageError
from balancer_id.identify.api import fit
from balancer_id.identify.posterior import Prior, parse_prior, sample_posterior


@pytest.fixture(scope="module")
def near_bound():
    # almost no viscosity and short trials: D0's Wald interval crosses zero
    rng = np.random.default_rng(7)
    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 0.2}
    trials = step_trials("viscous", truth, [2.45, -4.9], 0.05, rng, seconds=2.5)
    return truth, fit(trials, model="viscous", posterior=True, seed=1)


def test_credible_interval_respects_the_bound_where_wald_does_not(near_bound):
    truth, result = near_bound
    post = result.posterior
    assert post is not None and post.converged
    lo, hi = post.credible()["D0"]
    wald = result.match.parameters["D0"].wald_ci95
    assert wald[0] < 0.0 <= lo  # the samples never leave D0 >= 0
    assert lo <= truth["D0"] <= hi
    codes = {(n.code, n.subject) for n in result.all_notes if hasattr(n, "code")}
    assert ("fit.posterior_disagrees", "D0") in codes
    # the well-determined mass: credible and Wald agree within a quarter of the width
    m_lo, m_hi = post.credible()["m_a"]
    w_lo, w_hi = result.match.parameters["m_a"].wald_ci95
    assert abs(m_lo - w_lo) < 0.25 * (w_hi - w_lo) and abs(m_hi - w_hi) < 0.25 * (w_hi - w_lo)
    assert 0.15 < post.acceptance < 0.75 and all(t > 0 for t in post.tau.values())


def test_result_carries_the_posterior_everywhere(near_bound):
    _, result = near_bound
    out = result.to_dict()["posterior"]
    assert set(out["parameters"]) == {"m_a", "T_a", "D0"}
    assert out["converged"] is True and out["n_samples"] > 500
    assert out["parameters"]["D0"]["wald95"][0] < 0 <= out["parameters"]["D0"]["credible95"][0]
    assert result.band().method == "posterior"
    assert "[[Posterior]]" in result.summary()


def test_a_prior_pulls_the_posterior(near_bound):
    # a tight prior on the mass far from what the data say moves its median towards it
    _, result = near_bound
    free = result.posterior.median()["m_a"]
    mu = round(free + 1.0, 3)
    pulled = sample_posterior(
        result.match, priors=[parse_prior(f"m_a=normal:{mu},0.05")], max_steps=300, seed=1
    )
    assert pulled.median()["m_a"] > free + 0.5
    assert pulled.priors == [Prior("m_a", mu, 0.05)]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("m_a=15", "expected NAME=normal:MU,SD"),
        ("m_a=uniform:1,2", "expected NAME=normal:MU,SD"),
        ("m_a=normal:15,-1", "positive SD"),
        ("m_a=normal:x,1", "must be numbers"),
    ],
)
def test_bad_priors_are_usage_errors(text, message):
    with pytest.raises(UsageError, match=message):
        parse_prior(text)


def test_cli_refuses_a_bad_prior_before_reading(cli):
    code, _, err = cli("fit", "sample_logs/paper_balancer.csv", "--prior", "m_a=normal:15,0")
    assert code == 2
    assert "--prior 'm_a=normal:15,0'" in err and "Traceback" not in err


def test_a_prior_on_a_parameter_not_fitted_is_refused(near_bound):
    _, result = near_bound
    with pytest.raises(UsageError, match="A: not a fitted parameter"):
        fit(result.match.data.trials, model="viscous", priors=["A=normal:0.4,0.1"])


def test_jeffreys_prior_vanishes_where_the_data_cannot_tell_parameters_apart():
    from balancer_id.identify.posterior import _log_jeffreys

    rng = np.random.default_rng(0)
    s = rng.normal(size=(200, 3))
    assert _log_jeffreys(s) == pytest.approx(0.5 * np.linalg.slogdet(s.T @ s)[1])
    # a parameter the response does not depend on (no viscosity at any level reached),
    # or two that move it alike: the prior is (nearly) nothing there
    dead = s.copy()
    dead[:, 2] = 0.0
    assert _log_jeffreys(dead) == -np.inf
    alike = s.copy()
    alike[:, 2] = 2.0 * s[:, 1]
    assert _log_jeffreys(alike) < _log_jeffreys(s) - 10
    # a change of a parameter's unit moves the log prior by a constant only
    scaled = s * [1.0, 1.0, 1000.0]
    assert _log_jeffreys(scaled) == pytest.approx(_log_jeffreys(s) + np.log(1000.0))


@pytest.mark.slow
def test_short_log_posterior_leaves_the_corner_with_no_viscosity():
    # two levels, 1.5 s each: the fit ends far up the D0-A ridge (D0 ~ 1e4, no viscosity at
    # the heavier level); a flat prior's posterior sat there too (m_a 15.97-16.93, the
    # truth 15.1 outside); Jeffreys' prior is small where the data tell nothing apart
    rng = np.random.default_rng(437874)
    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
    t = np.arange(0.0, 2.5, 0.005)
    from balancer_id.identify.data import TrialData
    from balancer_id.model import parse_model
    from balancer_id.simulation.engine import TrialInput, simulate_many
    from balancer_id.simulation.inputs import Thrust

    inputs = [TrialInput(t, Thrust.step(1.0, f)) for f in (2.45, -4.9)]
    sims = simulate_many(parse_model(), truth, inputs)
    trials = [
        TrialData(k, f, "up" if f > 0 else "down", 1.0, inp, s.accel + rng.normal(0, 0.05, t.size))
        for k, (f, inp, s) in enumerate(zip((2.45, -4.9), inputs, sims, strict=True))
    ]
    result = fit(trials, posterior=True, seed=437874)
    cred = result.posterior.credible()
    assert result.match.parameters["D0"].value > 100  # the ridge
    for name in ("m_a", "T_a", "A"):
        assert cred[name][0] <= truth[name] <= cred[name][1], name
    # the corner of no viscosity (D0 up to its support's 1e6 under the flat prior) is left
    assert cred["D0"][1] < 1e5
