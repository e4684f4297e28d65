"""Posterior sampling (issue 34.2): credible intervals that respect the bounds where Wald's
do not, agree with Wald's where the cost is quadratic, and priors checked up front."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_fit import step_trials

from balancer_id.errors import UsageError
from balancer_id.identify.api import fit
from balancer_id.identify.posterior import Prior, parse_prior, sample_posterior


@pytest.fixture(scope="module")
def near_bound():
    # almost no viscosity and short trials (1.5 s): D0's Wald interval crosses zero
    rng = np.random.default_rng(7)
    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 0.2}
    trials = step_trials("viscous", truth, [2.45, -4.9], 0.05, rng, seconds=1.5)
    # the lag held: a step cannot tell it from the viscous time m_a / D0 (the mirror,
    # test_the_posterior_holds_the_mirror_the_data_cannot_exclude); here D0's bound is
    return truth, fit(trials, model="viscous", fixed={"T_a": 0.33}, posterior=True, seed=1)


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
    # said for D0 (Wald's reaches below 0), not for the mass, where the two agree
    assert ("fit.posterior_disagrees", "m_a") not in codes
    said = [n.text for n in post.notes if n.code == "fit.posterior_disagrees"]
    assert len(said) == 1 and "reaches past the bound 0" in said[0]
    # the well-determined mass: credible and Wald agree within a quarter of the width
    m_lo, m_hi = post.credible()["m_a"]
    w_lo, w_hi = result.match.parameters["m_a"].wald_ci95
    assert abs(m_lo - w_lo) < 0.25 * (w_hi - w_lo) and abs(m_hi - w_hi) < 0.25 * (w_hi - w_lo)
    assert 0.15 < post.acceptance < 0.75 and all(t > 0 for t in post.tau.values())


def test_result_carries_the_posterior_everywhere(near_bound):
    _, result = near_bound
    out = result.to_dict()["posterior"]
    assert set(out["parameters"]) == {"m_a", "D0"}
    assert out["converged"] is True and out["n_samples"] > 500
    assert out["parameters"]["D0"]["wald95"][0] < 0 <= out["parameters"]["D0"]["credible95"][0]
    assert result.band().method == "posterior"
    # the convergence diagnostics and the spread added beside each interval
    from balancer_id.identify.posterior import unmodelled_spread

    bounds = np.array([result.posterior.bounds[n] for n in ("m_a", "D0")])
    added = unmodelled_spread(result.match, ["m_a", "D0"], bounds[:, 0], bounds[:, 1])
    for name in ("m_a", "D0"):
        assert 1.0 <= out["parameters"][name]["rhat"] < 1.05
        assert out["parameters"][name]["added_sd"] == pytest.approx(added[name])
    assert "[[Posterior]]" in result.summary()


def test_the_posterior_holds_the_mirror_the_data_cannot_exclude():
    # the viscous model's step answer is the same with the lag and m_a / D0 swapped: the
    # fit ends in one valley, its mirror start in the other (about alike); the posterior
    # samples both and weighs them, and the credible interval of m_a spans both. The
    # reference prior weighs them by how well each tells its parameters apart (the long
    # lag of the light one trades with its mass: 0.09 here, Jeffreys' gave 0.37), but
    # keeps it inside the interval (a share above 2.5 %) and names it
    rng = np.random.default_rng(7)
    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 0.2}
    trials = step_trials("viscous", truth, [2.45, -4.9], 0.05, rng, seconds=2.5)
    result = fit(trials, model="viscous", seed=1, profile=False)
    assert len(result.match.optima) >= 2
    post = sample_posterior(result.match, max_steps=200, n_walkers=12, seed=1)
    assert len(post.modes) == 2 and sum(m["weight"] for m in post.modes) == pytest.approx(1)
    light = min(post.modes, key=lambda m: m["values"]["m_a"])
    assert light["values"]["m_a"] < 2.0 and 0.05 < light["weight"] < 0.85
    lo, hi = post.credible()["m_a"]
    assert lo < 2.0 and 14.0 < hi
    assert "fit.posterior_modes" in {n.code for n in post.notes}


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


def test_reference_prior_vanishes_where_the_data_cannot_tell_parameters_apart():
    from balancer_id.identify.posterior import _log_reference

    rng = np.random.default_rng(0)
    s = rng.normal(size=(200, 3))
    theta, logged, width = np.array([15.0, 0.3, 6.0]), np.array([True, True, False]), 1.0

    def ref(sens):
        return _log_reference(sens, theta, logged, np.full(3, width), 0.05)

    d = np.sqrt(np.diag(s.T @ s))
    # informed parameters: only the information's shape counts, not its size (Jeffreys'
    # prior grows with every sensitivity and leaned to light masses and small A)
    assert ref(s) == pytest.approx(0.5 * np.linalg.slogdet((s.T @ s) / np.outer(d, d))[1])
    assert ref(s * [1.0, 1.0, 1000.0]) == pytest.approx(ref(s))
    # a parameter the response does not depend on (no viscosity at any level reached), or
    # two that move it alike: the prior is (nearly) nothing there
    dead = s.copy()
    dead[:, 2] = 0.0
    assert ref(dead) == -np.inf
    alike = s.copy()
    alike[:, 2] = 2.0 * s[:, 1]
    assert ref(alike) < ref(s) - 10
    # once the data no longer pin a parameter within its support's width (its standard
    # error with the others held, sigma / |s_j|, above the width), the prior falls as that
    # information does: D0's (unlogged) column 1000x weaker than that
    weak = s * [1.0, 1.0, 1e-3 * 0.05 / (width * d[2])]
    assert ref(weak) == pytest.approx(ref(s) - np.log(1000.0))


def test_short_log_posterior_leaves_the_corner_with_no_viscosity():
    # two levels, 1.5 s each: the fit ends far up the D0-A ridge (D0 ~ 1e4, no viscosity at
    # the heavier level); a flat prior's posterior sat there too (m_a 15.97-16.93, the
    # truth 15.1 outside); Jeffreys' prior is small where the data tell nothing apart. D0,
    # its interval reaching past 10x its fit, is sampled as its logarithm: in D0 itself the
    # walkers crawled along the ridge (acceptance 0.08, and 300 steps held neither the
    # truth's m_a nor its A). The reference prior, flat in log D0, counts the log's support
    # from 100x below D0's smallest optimum: down to 0 the corner with no viscosity at all
    # was a volume without end (D0's median sank to 0.2). A short chain (300 steps) tells
    # where the posterior lies; m_a's lower tail needs the full chain (14.79-16.78 at
    # 2646 steps, 50 autocorrelation times), which is not what is checked here.
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
    result = fit(trials, seed=437874)
    assert result.match.parameters["D0"].value > 100  # the ridge
    post = sample_posterior(result.match, max_steps=300, seed=437874)
    assert post.acceptance > 0.15
    cred = post.credible()
    for name in ("T_a", "A"):
        assert cred[name][0] <= truth[name] <= cred[name][1], name
    # the corner of no viscosity (D0 up to its support's 1e6 under the flat prior) is left
    assert cred["D0"][1] < 1e3 and np.median(post.samples[:, 2]) > 0.5


def test_bridge_weights_find_each_valleys_share():
    # two valleys of different widths and weights 0.3 / 0.7, each sampled on its own: the
    # bridge between their samples recovers the shares (a chain spread over both keeps
    # the share of walkers each started with, whatever the truth)
    from balancer_id.identify.posterior_modes import bridge_weights, region_of

    rng = np.random.default_rng(3)
    centres = np.array([[0.0, 0.0], [10.0, 4.0]])
    widths = np.array([[1.0, 0.5], [2.0, 0.3]])
    shares = np.array([0.3, 0.7])

    def log_p(x):
        x = np.asarray(x, float)
        dens = shares / np.prod(widths, axis=1) * np.exp(
            -0.5 * (((x - centres) / widths) ** 2).sum(axis=1)
        )
        return float(np.log(dens.sum()))

    chains = [c + w * rng.normal(size=(2000, 2)) for c, w in zip(centres, widths, strict=True)]
    w = bridge_weights(chains, log_p, region_of(centres), rng)
    assert w == pytest.approx(shares, abs=0.03)
    assert bridge_weights(chains[:1], log_p, region_of(centres[:1]), rng) == pytest.approx([1.0])


def test_credible_interval_is_one_sided_only_where_the_posterior_piles_at_a_bound():
    from balancer_id.identify.posterior import Posterior

    rng = np.random.default_rng(5)
    # D0 flat down to its bound 0; m_a in two valleys (0.6-2 and 12-16 kg) far above its
    # support's 0.013 kg: the first is cut by the bound, the second keeps both tails
    d0 = rng.uniform(0.0, 0.6, 4000)
    m_a = np.where(rng.random(4000) < 0.5, rng.uniform(0.6, 2.0, 4000), rng.normal(14, 1, 4000))
    post = Posterior(
        ["m_a", "D0"],
        np.column_stack([m_a, d0]),
        {"m_a": 14.0, "D0": 0.2},
        {},
        {},
        {"m_a": 10.0, "D0": 10.0},
        0.3,
        16,
        1000,
        20,
        5,
        bounds={"m_a": (0.013, 1e3), "D0": (0.0, 60.0)},
    )
    cred, equal = post.credible(), post.credible(kind="equal")
    assert cred["D0"][0] == 0.0 and cred["D0"][1] == pytest.approx(0.57, abs=0.02)
    assert equal["m_a"][0] == pytest.approx(np.percentile(m_a, 2.5))
    assert equal["m_a"][1] == pytest.approx(np.percentile(m_a, 97.5))
    # the highest-density interval spans both valleys too (each holds half)
    assert cred["m_a"][0] < 0.7 and 15.0 < cred["m_a"][1]


def test_credible_interval_keeps_the_sharp_edge_of_a_skewed_marginal():
    # a short log's D0: the likelihood drops sharply below (D0 ~ 5) and leaves the ridge
    # open above (flat in log D0 to 100x). The equal-tailed interval cut 2.5 % of the long
    # side's mass off the sharp one and started above a truth just inside the edge (six
    # steps of 1.5 s: D0 and A held the truth 80 / 85 %); the highest-density interval
    # starts at the edge and gives up the thin upper tail instead
    from balancer_id.identify.posterior import Posterior, highest_density

    rng = np.random.default_rng(11)
    edge, n = 5.0, 8000
    d0 = edge * np.exp(np.abs(rng.normal(0.0, 0.05, n)) + rng.exponential(1.0, n))
    post = Posterior(
        ["D0"], d0[:, None], {"D0": 12.0}, {}, {}, {"D0": 10.0}, 0.3, 16, 1000, 20, 5,
        bounds={"D0": (0.0, 1e4)},
    )
    lo, hi = post.credible()["D0"]
    e_lo, e_hi = post.credible(kind="equal")["D0"]
    assert np.mean((d0 >= lo) & (d0 <= hi)) == pytest.approx(0.95, abs=0.002)
    assert lo < edge * 1.05 < e_lo and hi < e_hi and hi - lo < e_hi - e_lo
    assert highest_density(np.arange(100.0), 0.9) == (0.0, 89.0)


def test_the_chain_is_measured_in_steps_and_the_clock_only_stops_it_named(near_bound):
    # a seed gives the same samples whatever the machine's speed: the chain's length is in
    # steps and autocorrelation times; the wall clock is a safety net that, when it stops
    # a chain, says so and never passes for a converged answer
    _, result = near_bound
    short = {"min_steps": 60, "max_steps": 400, "n_walkers": 8, "seed": 4}
    a = sample_posterior(result.match, **short)
    b = sample_posterior(result.match, **short, max_seconds=None)
    assert np.array_equal(a.samples, b.samples) and a.n_steps == b.n_steps > 60
    cut = sample_posterior(result.match, **short, max_seconds=0.0)
    assert cut.stopped_by_time and not cut.converged and cut.n_steps == 60
    assert cut.to_dict()["stopped_by_time"] is True and not a.stopped_by_time
    said = [n.text for n in cut.notes if n.code == "fit.posterior_not_converged"]
    assert said and "stopped by time" in said[0]
    assert "stopped by time" in cut.diagnostics_text()


def test_optima_without_a_barrier_between_them_are_one_valley():
    # two optima of a short log's D0-A ridge fell steadily from one to the other: sampled
    # as two valleys split by the nearest optimum, the ridge was cut in two and each half
    # paid a chain. Two bumps with a valley of density between them stay two
    from balancer_id.identify.posterior_modes import valleys

    def ridge(x):  # a long straight ridge, falling gently along it
        x = np.atleast_2d(x)
        return -0.5 * ((x[:, 1] - 0.5 * x[:, 0]) / 0.1) ** 2 - 0.3 * np.abs(x[:, 0])

    def bumps(x):
        x = np.atleast_2d(x)
        return np.logaddexp(
            -0.5 * np.sum((x - [0.0, 0.0]) ** 2, axis=1) / 0.2**2,
            -0.5 * np.sum((x - [3.0, 1.0]) ** 2, axis=1) / 0.2**2,
        )

    on_ridge = np.array([[0.0, 0.0], [6.0, 3.0], [-4.0, -2.0]])
    assert list(valleys(on_ridge, ridge)) == [0, 0, 0]
    apart = np.array([[0.0, 0.0], [3.0, 1.0], [0.1, 0.05]])
    assert list(valleys(apart, bumps)) == [0, 1, 0]


def test_convergence_is_judged_by_the_autocorrelation_and_split_rhat():
    # differential-evolution walkers in a valley cut by a bound accept 0.13 while their
    # chain is 50 autocorrelation times long and mixed: converged (the stretch move's
    # 0.15 floor called such chains unconverged). Walkers that never left the two places
    # they started in are not, whatever the acceptance
    from balancer_id.identify.posterior import RHAT_MAX, Posterior, posterior_notes, split_rhat

    rng = np.random.default_rng(2)
    mixed = rng.normal(size=(1000, 16, 2))
    stuck = mixed + np.where(np.arange(16) < 8, 0.0, 3.0)[None, :, None]
    assert np.all(np.abs(split_rhat(mixed) - 1) < 0.01)
    assert np.all(split_rhat(stuck) > 1.5)

    def post(rhat, acceptance=0.13):
        return Posterior(
            ["m_a", "T_a"], rng.normal(size=(2000, 2)), {"m_a": 0.0, "T_a": 0.0}, {}, {},
            {"m_a": 40.0, "T_a": 38.0}, acceptance, 16, 2100, 80, 20,
            rhat=dict(zip(["m_a", "T_a"], map(float, rhat), strict=True)),
        )

    assert post(split_rhat(mixed)).converged
    bad = post(split_rhat(stuck))
    assert not bad.converged and max(bad.rhat.values()) > RHAT_MAX
    said = [n.text for n in posterior_notes(bad) if n.code == "fit.posterior_not_converged"]
    assert said and "split R-hat" in said[0] and "split R-hat" in bad.diagnostics_text()
    assert not post(split_rhat(mixed), acceptance=0.05).converged  # stuck walkers


def test_walkers_start_shaped_as_the_valley(near_bound):
    # the walkers start in the valley's Laplace shape in the sampler's coordinates (log m_a,
    # D0 itself near its bound): a round ball spent the chain's first autocorrelation times
    # stretching into it. At the optimum that shape is the fit's own covariance
    from balancer_id.identify.band import covariance_of
    from balancer_id.identify.posterior import START_SHARE, _laplace_shape, _shaped_start

    _, result = near_bound
    match = result.match
    names = ["m_a", "D0"]
    logged = np.array([True, False])
    centre = np.array([np.log(match.parameters["m_a"].value), match.parameters["D0"].value])
    cov_u = _laplace_shape(match, names, logged)(centre)
    _, cov = covariance_of(match)
    scatter = np.array([match.parameters[n].scatter_ratio for n in names])
    jac = np.array([1.0 / match.parameters["m_a"].value, 1.0])
    expected = cov / np.outer(scatter, scatter) * np.outer(jac, jac)
    assert cov_u == pytest.approx(expected, rel=0.05)
    rng = np.random.default_rng(0)
    start = _shaped_start(cov_u, centre, 4000, rng, lambda us: np.zeros(len(us)))
    assert np.cov(start, rowvar=False) == pytest.approx(START_SHARE**2 * cov_u, rel=0.1)
    # a draw where the posterior vanishes is drawn again
    inside = _shaped_start(cov_u, centre, 50, rng, lambda us: np.where(us[:, 1] > 0.2, 0, -np.inf))
    assert inside.shape == (50, 2) and np.all(inside[:, 1] > 0.2)


def test_samples_carry_the_spread_the_likelihood_lacks():
    # a 0.2 kg cart's T_a: its standard error 2.4 ms is mostly the steps' places between
    # samples (1.7 ms) and the trials' scatter (4.2x the noise's); the likelihood holds
    # only the noise's 0.4 ms, and credible intervals from it alone missed the truth.
    # The samples get the rest as independent normal spread, reflected into the bounds
    from types import SimpleNamespace

    from balancer_id.identify.posterior import _spread, unmodelled_spread

    def estimate(value, stderr, phase_se, scatter_ratio):
        wald = (value - 1.96 * stderr, value + 1.96 * stderr)
        return SimpleNamespace(
            value=value, stderr=stderr, phase_se=phase_se, scatter_ratio=scatter_ratio,
            wald_ci95=wald,
        )

    match = SimpleNamespace(
        parameters={
            "T_a": estimate(0.044, 0.0024, 0.0017, 4.24),
            "m_a": estimate(0.2, 0.01, 0.0, 1.0),
            # a ridge's D0: its Wald interval reaches below 0, its error meaningless
            "D0": estimate(28000.0, 9e4, 10.0, 1.5),
        }
    )
    names = ["T_a", "m_a", "D0"]
    added = unmodelled_spread(match, names, np.zeros(3), np.full(3, 1e6))
    se = np.sqrt(0.0024**2 - 0.0017**2) / 4.24
    assert added["T_a"] == pytest.approx(np.sqrt(0.0024**2 - se**2))
    assert added["m_a"] == 0.0 and added["D0"] == 0.0
    rng = np.random.default_rng(1)
    x = _spread(np.full((20000, 2), [0.04, 0.001]), np.array([0.0023, 0.002]),
                np.array([0.0, 0.0]), np.array([1.0, 1.0]), rng)
    assert np.std(x[:, 0]) == pytest.approx(0.0023, rel=0.03)
    assert np.all(x[:, 1] >= 0.0)  # reflected at the bound, not piled on it or beyond
    mu, sd = 0.001, 0.002  # a folded normal's mean
    folded = sd * np.sqrt(2 / np.pi) * np.exp(-0.5 * (mu / sd) ** 2) + mu * math.erf(
        mu / (sd * np.sqrt(2))
    )
    assert np.mean(x[:, 1]) == pytest.approx(folded, rel=0.03)
