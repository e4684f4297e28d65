"""Experiment design (issue 34.3): the proposed trial shrinks the interval as predicted,
the prediction starts from the fit's own interval, and the command is a thin shell."""

from __future__ import annotations

import numpy as np
import pytest
from test_fit import step_trials

from balancer_id.errors import UsageError
from balancer_id.identify.api import fit
from balancer_id.identify.data import TrialData
from balancer_id.model import parse_model
from balancer_id.simulation.engine import simulate_many
from balancer_id.workflows.plan import plan

TRUTH = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}


@pytest.fixture(scope="module")
def first():
    rng = np.random.default_rng(4)
    trials = step_trials("variable_viscosity", TRUTH, [2.45, -2.45, 4.9], 0.03, rng, seconds=4.0)
    return trials, fit(trials, profile=False)


def test_prediction_starts_at_the_fits_interval_and_shrinks(first):
    _, result = first
    p = plan(result, separate=False)
    design = p.design
    for name, half in design.now.items():  # the Fisher information is the fit's covariance
        assert half == pytest.approx(1.96 * result.match.parameters[name].stderr, rel=0.02)
    assert len(design.proposals) == 3
    widest = max(design.now, key=lambda n: design.now[n] / abs(design.values[n]))
    assert all(q.target == widest for q in design.proposals)
    for q in design.proposals:
        assert q.after[widest] < q.before[widest]
    text = p.summary()
    assert "record a step of" in text and f"{widest}'s 95 % interval" in text
    assert p.to_dict()["proposals"][0]["target"] == widest


def test_recording_the_proposal_gives_the_predicted_interval(first):
    # the bench's check on one seed: record the trial on the true balancer, refit
    trials, result = first
    q = plan(result, separate=False, count=1, param="A").design.proposals[0]
    rng = np.random.default_rng(9)
    inp = q.candidate.trial_input()
    (sim,) = simulate_many(parse_model(), TRUTH, [inp])
    new = TrialData(
        9,
        q.candidate.thrust_N,
        q.candidate.direction,
        q.candidate.rest_s,
        inp,
        sim.accel + rng.normal(0, 0.03, inp.time.size),
    )
    again = fit([*trials, new], profile=False)
    achieved = 1.96 * again.match.parameters["A"].stderr
    assert achieved == pytest.approx(q.after["A"], rel=0.25)
    assert achieved < 1.96 * result.match.parameters["A"].stderr


def test_one_thrust_level_gets_another_level():
    # A held at a guess (one level cannot determine it): the plan names a new level
    rng = np.random.default_rng(2)
    trials = step_trials("variable_viscosity", TRUTH, [4.9, -4.9], 0.03, rng, seconds=6.0)
    result = fit(trials, profile=False)
    assert not result.match.parameters["A"].vary
    p = plan(result, separate=False, count=1)
    q = p.design.proposals[0]
    assert q.target == "A"
    assert abs(abs(q.candidate.thrust_N) - 4.9) > 0.5
    assert q.after["A"] < 0.5 * TRUTH["A"]
    assert any("A was held" in n for n in p.notes)


def test_a_speed_limit_not_reached_gets_the_trial_that_reaches_it():
    # a winding-speed limit at 1.05 m/s; the recorded steps (3 and 6 N, 4 s at 200 Hz)
    # went 0.83 m/s at most, so the fit gives v_max only as a bound. The plan's trial must
    # pass that bound in the balancer without the limit (simulated with it at its open
    # bound, no trial went faster: "none of the trials tried adds information" before), and
    # recording it on the true balancer turns the bound into a value
    truth = {"m_a": 15.0, "T_a": 0.3, "D0": 3.0, "v_max": 1.05}
    spec = "viscous+speed_limit"
    rng = np.random.default_rng(11)
    trials = step_trials(spec, truth, [3.0, -6.0], 0.03, rng, seconds=5.0)
    first = fit(trials, model=spec)
    v_max = first.match.parameters["v_max"]
    assert v_max.not_reached == "above" and v_max.ci95[0] < truth["v_max"]
    p = plan(first, count=1, separate=False)
    (q,) = p.design.proposals
    assert q.reaches == "v_max"
    assert q.peak_speed >= 1.2 * max(v_max.ci95[0], p.fastest)
    assert "reaches the bound" in p.proposal_text(1, q)
    model = parse_model(spec)
    inp = q.candidate.trial_input()
    (sim,) = simulate_many(model, truth, [inp])
    new = TrialData(
        2, q.candidate.thrust_N, q.candidate.direction, q.candidate.rest_s, inp,
        sim.accel + rng.normal(0, 0.03, inp.time.size),
    )  # fmt: skip
    both = fit([*trials, new], model=spec, profile=False).match.parameters["v_max"]
    assert both.not_reached is None
    assert abs(both.value - truth["v_max"]) < max(4 * both.stderr, 0.02)


def test_d_optimal_and_bad_param(first):
    _, result = first
    p = plan(result, separate=False, param="all", count=1)
    assert p.design.target == "all" and p.design.proposals[0].target == "all"
    with pytest.raises(UsageError, match="--param f_s: not a fitted parameter"):
        plan(result, separate=False, param="f_s")


def test_plan_command_json(cli):
    import json

    code, out, err = cli(
        "plan",
        "sample_logs/paper_balancer.csv",
        "--param",
        "D0",
        "--count",
        "1",
        "--no-separate",
        "--json",
    )
    assert code == 0, err
    obj = json.loads(out)
    assert obj["target"] == "D0" and len(obj["proposals"]) == 1
    prop = obj["proposals"][0]
    assert prop["halfwidth_after"]["D0"] < prop["halfwidth_before"]["D0"]
    assert {"thrust_N", "direction", "rest_s", "duration_s"} <= set(prop)
    code, _, err = cli("plan", "sample_logs/paper_balancer.csv", "--count", "0")
    assert code == 2 and "--count" in err


def _record(trials, candidate, seed):
    inp = candidate.trial_input()
    (sim,) = simulate_many(parse_model(), TRUTH, [inp])
    rng = np.random.default_rng(seed)
    new = TrialData(
        len(trials), candidate.thrust_N, candidate.direction, candidate.rest_s, inp,
        sim.accel + rng.normal(0, 0.03, inp.time.size),
    )
    return fit([*trials, new], profile=False)


def test_one_level_plan_holds_for_the_other_values_of_the_guess():
    # one level: A is held at a guess (1 / the level: half the truth). The trial is planned
    # at the values the guess could have too, each with the others refitted: all fit the
    # one level alike (D0 exp(-A |F|) the same there); the trial fills the travel the
    # recorded trials allow, and recorded on the true balancer it pins A as predicted
    import balancer_id.identify.design as design

    rng = np.random.default_rng(101)
    trials = step_trials("variable_viscosity", TRUTH, [4.9, -4.9], 0.03, rng, seconds=8.0)
    result = fit(trials, profile=False)
    match = result.match
    values = match.values()
    points = design._guessed_points(match, ["A"], values)
    assert len(points) == len(design.GUESS_FACTORS)
    viscosity = [pt["D0"] * np.exp(-pt["A"] * 4.9) for pt in points]
    assert np.allclose(viscosity, values["D0"] * np.exp(-values["A"] * 4.9), rtol=0.02)
    assert sorted(pt["A"] / values["A"] for pt in points) == pytest.approx(
        sorted(design.GUESS_FACTORS), rel=1e-6
    )
    grid = design.candidate_grid(trials)
    with np.errstate(all="ignore"):
        out0 = match.data.packed.run(match.model, np.asarray(match.model.vector(values)))
    travel = design.TRAVEL_FACTOR * float(np.max(np.abs(out0[:, 2])))
    fills = design._filling_travel(match, grid, values, travel)
    assert fills
    _, _, moves = design._candidate_information(match, fills, values, ["m_a"], 1.0)
    assert max(moves) <= travel and min(moves) > 0.6 * travel
    q = plan(result, separate=False, count=1).design.proposals[0]
    # on one level A and D0 trade (only D0 exp(-A |F|) is fixed): either is the widest
    # (their relative widths differ by 0.1 %), and either is narrowed by another level
    assert q.target in ("A", "D0") and abs(abs(q.candidate.thrust_N) - 4.9) > 0.5
    got = 1.96 * _record(trials, q.candidate, 5).match.parameters["A"].stderr
    assert got == pytest.approx(q.after["A"], rel=0.15)


def test_an_interval_set_by_the_steps_places_between_samples_is_not_the_plans_target():
    # a 0.2 kg cart at 200 Hz: T_a (0.04 s) is known to where its steps fell between
    # samples (dt^2 / 12, no trial at this rate adds to it); planned for, the trial shrank
    # the rest 3x and the interval T_a reports 2 %. The plan reports the intervals as the
    # fit does (that spread included) and aims at one a trial shrinks
    rng = np.random.default_rng(86782)
    truth = {"m_a": 0.2, "T_a": 0.04, "D0": 0.25}
    trials = step_trials("viscous", truth, [0.5, -1.0], 0.05, rng, seconds=4.0)
    result = fit(trials, model="viscous", profile=False)
    t_a = result.match.parameters["T_a"]
    assert t_a.phase_se > 0.9 * t_a.stderr  # the premise: T_a's error is that spread
    design = plan(result, count=1, separate=False).design
    for name, half in design.now.items():
        assert half == pytest.approx(1.96 * result.match.parameters[name].stderr, rel=0.02)
    q = design.proposals[0]
    assert q.target != "T_a" and q.after[q.target] < 0.9 * q.before[q.target]
    assert q.after["T_a"] >= 1.96 * t_a.phase_se


def test_a_light_carts_plan_predicts_the_floor_its_trial_leaves():
    # a 0.2 kg cart at 200 Hz: most of m_a's interval is where the steps fell between
    # samples, and a strong, short step widens that part (m_a moves more per second of
    # its timing); predicted as constant, the plan chose a 3 N step predicted to give
    # 0.83 mg that gave 0.97 (a random trial did as well). The floor is now predicted
    # with each trial, the recorded trial gives its prediction, and the plan says no
    # trial at this rate does much better
    truth = {"m_a": 0.2, "T_a": 0.04, "D0": 0.25}
    rng = np.random.default_rng(86782)
    trials = step_trials("viscous", truth, [0.5, -1.0], 0.05, rng, seconds=4.0)
    result = fit(trials, model="viscous", profile=False)
    p = plan(result, separate=False, count=1)
    q = p.design.proposals[0]
    assert q.target == "m_a" and q.floor["m_a"] > 0.7 * q.after["m_a"]
    assert "no trial does much better" in p.summary()
    inp = q.candidate.trial_input()
    (sim,) = simulate_many(parse_model("viscous"), truth, [inp])
    new = TrialData(
        9, q.candidate.thrust_N, q.candidate.direction, q.candidate.rest_s, inp,
        sim.accel + rng.normal(0, 0.05, inp.time.size),
    )
    again = fit([*trials, new], model="viscous", profile=False)
    achieved = 1.96 * again.match.parameters["m_a"].stderr
    assert achieved == pytest.approx(q.after["m_a"], rel=0.08)
    assert achieved < 0.95 * p.design.now["m_a"]
