"""Profile-likelihood intervals: they agree with Wald where the fit is well determined and
stay inside the physical bounds where it is not."""

from __future__ import annotations

import pytest
from test_fit import step_trials

from balancer_id.identify import match_trials
from balancer_id.identify.intervals import chi2_quantile_1dof, profile_interval, wald_crosses_bound
from balancer_id.model import parse_model


def test_chi_square_quantile():
    assert chi2_quantile_1dof(0.95) == pytest.approx(3.841459, rel=1e-6)
    assert chi2_quantile_1dof(0.6826894921) == pytest.approx(1.0, rel=1e-6)


def test_profile_matches_wald_for_a_well_determined_mass(rng):
    # viscous model, noise 0.03 m/s^2: the cost is nearly quadratic in m_a around the optimum
    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0}
    trials = step_trials("viscous", truth, [2.45, -4.9, 7.35], 0.03, rng, seconds=5.0)
    fit = match_trials(parse_model("viscous"), trials, start={"m_a": 14.0, "T_a": 0.3})
    est = fit.parameters["m_a"]
    interval = profile_interval(fit, "m_a")
    lo, hi = est.ci95
    assert not wald_crosses_bound(fit, "m_a")
    assert interval.low == pytest.approx(lo, abs=0.15 * (hi - lo))
    assert interval.high == pytest.approx(hi, abs=0.15 * (hi - lo))
    assert interval.low < truth["m_a"] < interval.high


def test_profile_stops_at_the_bound_when_the_data_allow_it(rng):
    # almost no viscosity and short trials: D0 is barely in the data, its Wald interval
    # crosses zero; the profile interval ends at the bound D0 = 0 and says so
    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 0.2}
    trials = step_trials("viscous", truth, [2.45, -4.9], 0.05, rng, seconds=2.5)
    fit = match_trials(parse_model("viscous"), trials, start={"m_a": 14.0, "T_a": 0.3})
    assert wald_crosses_bound(fit, "D0")
    interval = profile_interval(fit, "D0")
    assert interval.low == 0.0 and interval.low_at_bound
    assert not interval.high_at_bound
    assert interval.high > fit.parameters["D0"].value
    assert interval.low <= truth["D0"] <= interval.high


def test_fit_reports_the_profile_interval_where_wald_crosses_a_bound(rng):
    # issue 11: the interval the user sees (JSON ci95, the summary) respects the bounds
    from balancer_id.identify.api import fit

    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 0.2}
    trials = step_trials("viscous", truth, [2.45, -4.9], 0.05, rng, seconds=2.5)
    result = fit(trials, model="viscous")
    d0 = result.to_dict()["parameters"]["D0"]
    assert d0["ci95_method"] == "profile"
    assert d0["ci95"][0] >= 0.0  # D0 >= 0: the bound, not "-0.3"
    assert result.match.parameters["D0"].wald_ci95[0] < 0.0
    from balancer_id.identify.intervals import trades_closely

    m_a = result.to_dict()["parameters"]["m_a"]  # Wald's, unless it trades beyond 0.98
    assert m_a["ci95_method"] == ("profile" if trades_closely(result.match, "m_a") else "wald")
    assert "profile" in result.summary() and any("profile" in w for w in result.warnings)
    assert not any("far from quadratic" in w for w in result.warnings)  # a true bound


def test_a_profile_far_narrower_than_wald_is_called_out_on_a_misfit():
    # the hose log fitted without the hose: m_a and T_a trade at first order (corr -1),
    # the Wald error is many times the profile's half-width, and the note says why
    from conftest import SAMPLE_LOGS

    from balancer_id.identify.api import fit

    result = fit(SAMPLE_LOGS / "hose_walkthrough.csv")
    m_a = result.match.parameters["m_a"]
    low, high = m_a.ci95
    wald_low, wald_high = m_a.wald_ci95
    assert (high - low) * 3 < wald_high - wald_low
    note = next(str(w) for w in result.warnings if str(w).startswith("m_a:"))
    assert "far from quadratic" in note and "no uncertainty" in note


@pytest.mark.parametrize(
    ("cost", "threshold", "inside", "outside", "crossing"),
    [
        (lambda x: (x - 2.0) ** 2, 4.0, 2.0, 8.0, 4.0),  # a quadratic profile: x = 2 + 2
        (lambda x: (x - 2.0) ** 4, 16.0, 2.0, 9.0, 4.0),  # flat, then steep: regula falsi stalls
        (lambda x: (x + 1.0) ** 2, 9.0, -1.0, -10.0, -4.0),  # the lower end, walking down
    ],
)
def test_a_profile_end_is_found_where_the_cost_crosses_within_its_tolerance(
    cost, threshold, inside, outside, crossing
):
    from balancer_id.identify.intervals import MAX_REFITS_PER_END, _crossing

    calls = []

    def counted(x: float) -> float:
        calls.append(x)
        return cost(x)

    found = _crossing(counted, threshold, (inside, cost(inside)), (outside, cost(outside)), inside)
    # 0.5 % of the end's distance from the value, the documented tolerance
    assert found == pytest.approx(crossing, abs=5e-3 * abs(outside - inside))
    assert len(calls) <= MAX_REFITS_PER_END // 2
    assert all(min(inside, outside) < x < max(inside, outside) for x in calls)  # never an end


def test_a_cost_that_cannot_be_computed_is_bisected():
    from balancer_id.identify.intervals import _crossing

    def cost(x: float) -> float:
        return float("inf") if x > 5.0 else (x - 2.0) ** 2

    found = _crossing(cost, 4.0, (2.0, 0.0), (8.0, float("inf")), 2.0)
    assert found == pytest.approx(4.0, abs=0.1)


def test_a_close_trade_gets_its_interval_from_the_profile_no_narrower_than_wald(rng):
    # issue 31: beyond a correlation of 0.98 the cost is no bowl along the valley the
    # parameters trade in, and the Wald interval missed the truth; such a parameter's
    # interval is its profile's, each end no narrower than Wald's (the profile's
    # threshold does not know the trials' scatter the standard error was widened to)
    from balancer_id.identify.intervals import attach_profile_intervals, trades_closely

    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0}
    trials = step_trials("viscous", truth, [2.45, -4.9, 7.35], 0.03, rng, seconds=5.0)
    fit = match_trials(parse_model("viscous"), trials, start={"m_a": 14.0, "T_a": 0.3})
    assert attach_profile_intervals(fit) == []  # well determined: Wald's stands
    fit.correlations.setdefault("m_a", {})["T_a"] = 0.99
    fit.correlations.setdefault("T_a", {})["m_a"] = 0.99
    assert trades_closely(fit, "m_a") and not trades_closely(fit, "D0")
    assert sorted(attach_profile_intervals(fit)) == ["T_a", "m_a"]
    for name in ("m_a", "T_a"):
        est = fit.parameters[name]
        assert est.ci95_method == "profile"
        wald = est.wald_ci95
        assert est.ci95[0] <= wald[0] and est.ci95[1] >= wald[1]
        assert est.ci95[0] < truth[name] < est.ci95[1]
    assert fit.parameters["D0"].ci95_method == "wald"
