"""Identification: the paper's method and simulation matching recover the truth."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import PAPER, PAPER_THRUSTS, SAMPLE_LOGS

from balancer_id.errors import IdentificationError
from balancer_id.identify import fit, match_trials, paper_method
from balancer_id.identify.coupling import coupling
from balancer_id.identify.data import TrialData
from balancer_id.model import parse_model
from balancer_id.simulation import Thrust, TrialInput, simulate_many

#: The paper's viscosity held off (its force -D0 exp(-A|h|) v is exactly zero): trials of
#: "variable_viscosity+karnopp" with it are those of karnopp alone, simulated in a kernel
#: the suite compiles anyway instead of one more.
NO_VISCOSITY = {"D0": 0.0, "A": 0.0}


def step_trials(spec, truth, thrusts, noise, rng, seconds=8.0):
    model = parse_model(spec)
    t = np.arange(0.0, seconds, 0.005)
    inputs = [TrialInput(t, Thrust.step(1.0, f)) for f in thrusts]
    sims = simulate_many(model, truth, inputs)
    return [
        TrialData(k, f, "up" if f > 0 else "down", 1.0, inp, s.accel + rng.normal(0, noise, t.size))
        for k, (f, inp, s) in enumerate(zip(thrusts, inputs, sims, strict=True))
    ]


def test_paper_method_on_first_order_steps(rng):
    # no viscosity: the steady acceleration is f_in/m_a and 95 % is reached at 3 T_a
    truth = {"m_a": 15.1, "T_a": 0.33, **NO_VISCOSITY}
    trials = step_trials("variable_viscosity", truth, PAPER_THRUSTS, 0.03, rng)
    classic = paper_method(trials)
    assert classic.m_a == pytest.approx(15.1, rel=0.02)
    assert classic.T_a == pytest.approx(0.33, rel=0.05)
    assert abs(classic.intercept_N) < 0.1
    table = classic.T_a_table()
    assert {(row["direction"]) for row in table} == {"up", "down"}
    assert len(table) == 6


def test_paper_method_sees_friction_as_an_intercept(rng):
    truth = {"m_a": 15.1, "T_a": 0.33, "f_s": 1.0, **NO_VISCOSITY}
    trials = step_trials("variable_viscosity+karnopp", truth, [2.45, 4.9, 7.35], 0.01, rng)
    classic = paper_method(trials)
    # the first-order fit ignores the break-away delay, which biases a_zc up a little:
    # the intercept shows the friction, somewhat low
    assert 0.7 < classic.intercept_N < 1.1


def test_simulation_matching_recovers_the_papers_balancer(rng):
    # noise 0.03 m/s^2 over 6 x 1600 samples: standard errors ~0.3 % (m_a) .. 2 % (D0)
    trials = step_trials("variable_viscosity", PAPER, PAPER_THRUSTS, 0.03, rng)
    result = match_trials(parse_model(), trials, start={"m_a": 14.0, "T_a": 0.25})
    for name, value in PAPER.items():
        est = result.parameters[name]
        assert est.value == pytest.approx(value, rel=0.06), name
        assert abs(est.value - value) < 4 * est.stderr, name
    assert result.metrics["rmse"] == pytest.approx(0.03, rel=0.05)
    assert "A" in result.correlations


def test_one_thrust_level_holds_A_and_says_so(rng):
    trials = step_trials("variable_viscosity", PAPER, [2.45, -2.45], 0.03, rng)
    result = match_trials(parse_model(), trials, start={"m_a": 15.0, "T_a": 0.3})
    assert result.parameters["A"].vary is False
    assert any("two or more thrust levels" in w for w in result.warnings)


def test_fix_holds_a_nameplate_value(rng):
    trials = step_trials("variable_viscosity", PAPER, PAPER_THRUSTS, 0.03, rng)
    result = match_trials(parse_model(), trials, fixed={"m_a": 15.1})
    assert result.parameters["m_a"].value == 15.1
    assert result.parameters["m_a"].stderr is None
    assert result.parameters["D0"].value == pytest.approx(6.0, rel=0.06)


def test_no_trial_is_an_identification_error():
    with pytest.raises(IdentificationError, match="no trial"):
        match_trials(parse_model(), [])


@pytest.mark.parametrize("name", ["paper_balancer.csv", "quantized_sensor.csv"])
def test_sample_logs_give_the_truth_back(name):
    truth = next(
        s for s in json.loads((SAMPLE_LOGS / "TRUTH.json").read_text()) if s["file"] == name
    )
    result = fit([SAMPLE_LOGS / name], per_trial=True)
    values = result.values
    # tolerances: ~4 standard errors at the sample logs' noise
    assert values["m_a"] == pytest.approx(truth["params"]["m_a"], rel=0.03)
    assert values["T_a"] == pytest.approx(truth["params"]["T_a"], rel=0.08)
    assert values["D0"] == pytest.approx(truth["params"]["D0"], rel=0.12)
    assert values["A"] == pytest.approx(truth["params"]["A"], rel=0.15)
    out = result.to_dict()
    assert set(out) >= {"model", "parameters", "classic", "trials", "metrics"}
    assert set(out["metrics"]) >= {"rmse", "nrmse_fit_percent", "aic", "bic", "n_samples"}
    assert len(out["per_trial"]) == len(out["trials"])
    json.dumps(out, allow_nan=False)


def test_coupling_matches_routh_hurwitz():
    m, T, D = 15.1, 0.33, 3.0
    for k_r, c_r in [(300.0, 150.0), (3000.0, 20.0)]:
        c = coupling(m, T, D, k_r, c_r)
        routh = (T * D + m) * (D + c_r) > T * m * k_r
        assert (c.stability_margin > 0) == routh
        assert (max(p.real for p in c.poles) < 0) == routh
    stiff = coupling(m, T, D, 3000.0, 20.0)
    assert stiff.oscillation_hz > 0 and stiff.damping_ratio < 0


def test_a_fit_that_does_not_converge_says_why(rng):
    trials = step_trials("variable_viscosity", PAPER, PAPER_THRUSTS, 0.03, rng, seconds=4.0)
    with pytest.raises(IdentificationError, match="did not converge") as err:
        fit(trials, max_nfev=1)
    assert "--fix" in str(err.value)


@pytest.mark.parametrize("spec", ["variable_viscosity", "variable_viscosity+karnopp"])
def test_the_early_stop_lands_on_the_least_squares_optimum(spec, rng):
    # the fit stops once the step left is a small fraction of each standard error; a
    # fit run to scipy's tight tolerances (finite-difference Jacobian, no early stop)
    # must agree within 5 % of each standard error
    model = parse_model(spec)
    truth = {**PAPER, "f_s": 0.5} if "karnopp" in spec else PAPER
    trials = step_trials(spec, truth, PAPER_THRUSTS, 0.03, rng)
    start = {"m_a": 14.0, "T_a": 0.25}
    quick = match_trials(model, trials, start=start)
    tight = match_trials(model, trials, start=start, diff_step=1e-7)
    assert quick.success, quick.message
    for name, est in quick.parameters.items():
        assert abs(est.value - tight.parameters[name].value) <= 0.05 * est.stderr, name
    assert quick.metrics["rmse"] == pytest.approx(tight.metrics["rmse"], rel=1e-5)


def test_extra_starts_find_the_same_optimum(rng):
    # starts drawn around the given one (some far: their Gauss-Newton steps leave the
    # bounds or raise the cost and the trust-region method takes over) end at one minimum
    model = parse_model("variable_viscosity")
    trials = step_trials("variable_viscosity", PAPER, PAPER_THRUSTS, 0.03, rng)
    one = match_trials(model, trials, start={"m_a": 14.0, "T_a": 0.25})
    many = match_trials(model, trials, start={"m_a": 14.0, "T_a": 0.25}, n_starts=4, seed=3)
    assert many.success, many.message
    assert many.nfev > one.nfev
    for name, est in one.parameters.items():
        assert abs(est.value - many.parameters[name].value) <= 0.05 * est.stderr, name


def test_a_multi_start_fit_tells_each_start(rng):
    # issue 11: `fit --starts 3` says which start it is on (the CLI's spinner listens)
    from balancer_id.status import listening

    truth = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0}
    told: list[str] = []
    with listening(told.append):
        match_trials(
            parse_model("viscous"),
            step_trials("viscous", truth, [2.45, -4.9], 0.03, rng),
            start={"m_a": 14.0, "T_a": 0.3},
            n_starts=3,
        )
    assert told == ["start 1/3", "start 2/3", "start 3/3"]


def test_coupling_uses_the_drive_lag_it_is_given_and_never_invents_one():
    from balancer_id.identify.coupling import coupling_of

    base = {"m_a": 15.0, "D0": 6.0, "k_r": 150.0, "c_r": 100.0}
    split = coupling_of({**base, "T_up": 0.3, "T_down": 0.4})
    assert split.terms == coupling(15.0, 0.35, 6.0, 150.0, 100.0).terms  # their mean
    with pytest.raises(ValueError, match="drive lag"):
        coupling_of(base)
