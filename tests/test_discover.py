"""Discovery of a missing force (issue 18): seeded logs with a hidden spring or drag.

The hidden forces are simulated with the discovery's own library effect (every term at 0
but the hidden one), so no extra kernel is compiled; the search is not told which.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import EXAMPLES, PAPER, PAPER_THRUSTS

from balancer_id.diagnostics import discover as discovery
from balancer_id.diagnostics.diagnosis import diagnose
from balancer_id.diagnostics.improve import improve
from balancer_id.errors import OutputExistsError
from balancer_id.identify.api import fit as identify_fit
from balancer_id.identify.api import trial_data
from balancer_id.identify.matching import match_trials
from balancer_id.identify.result import FitResult, fit_match
from balancer_id.model import Registry, parse_model
from balancer_id.model.registry import default_registry
from balancer_id.read.recording import Log
from balancer_id.segment import find_trials
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings
from balancer_id.trials import LoadedLog, TrialSet

NOISE = 0.03


def hidden_force(
    term: str, coefficient: float, seed: int, rho: float = 0.0, thrusts=PAPER_THRUSTS
) -> TrialSet:
    """Paper trials (the six unless ``thrusts``) with one library term hidden at
    ``coefficient``, read back."""
    terms = discovery.default_terms(0.3, None)
    lib = discovery.library_effect(terms)
    registry = Registry()
    registry.add(lib)
    model = parse_model(f"variable_viscosity+{lib.name}", registry)
    truth = {k: v for k, v in PAPER.items() if k in model.param_names}
    truth.update({key: val for t in terms for key, val in t.shapes})
    for j, t in enumerate(terms):
        truth[f"q{j}"] = coefficient if t.expression == term else 0.0
    sensor = SensorSettings(
        tilt_deg=15.0, accel_noise=NOISE, force_noise=0.03, noise_correlation=rho
    )
    recs = synthetic_recordings(model, truth, thrusts, sensor=sensor, seed=seed)
    log = Log(Path(f"hidden_{seed}.csv"), "pasco-capstone", recs)
    return TrialSet([LoadedLog(log, find_trials(log))])


def fit_paper_model(trials: TrialSet) -> FitResult:
    match = match_trials(parse_model(), trial_data(trials), start={"m_a": 15.0, "T_a": 0.3})
    return fit_match(match, trials)


@pytest.fixture(scope="module")
def spring():
    """A hidden spring ``-4 z`` (the README's hose) and the diagnosis of the paper model.

    Three trials (a quarter of the six's time): the paper model, bent by the spring it
    lacks, ends in another basin (m_a 4.0 kg, T_a 0.92 s against 15.1 and 0.33), which
    the discovery must leave (before its refits also started at the data's own scale, it
    kept m_a 4.0 and found -1.5 z, leaving 5 times the noise; 2 of 8 seeds did so)."""
    start = fit_paper_model(hidden_force("z", -4.0, seed=35, thrusts=(2.45, -4.9, 7.35)))
    assert start.values["m_a"] < 10  # the wrong basin this case is about
    return start, diagnose(start)


def test_a_hidden_spring_is_discovered_with_its_stiffness(spring):
    _, d = spring
    found = d.discovery
    assert found is not None and d.verdict == "effect missing"
    assert [t.expression for t in found.terms] == ["z"]
    term = found.terms[0]
    # the stiffness's standard error at 0.03 m/s^2 noise is ~0.02 N/m: 5 % is > 8 of them
    assert term.coefficient == pytest.approx(-4.0, rel=0.05)
    assert term.stderr is not None and 0 < term.stderr < 0.1
    assert term.term.unit == "N/m" and term.inclusion >= 0.9
    # the whole model was refitted with it: the other parameters moved back to the truth
    values = found.refit.values()
    assert values["m_a"] == pytest.approx(PAPER["m_a"], rel=0.03)
    assert found.rmse < 1.15 * NOISE
    out = d.to_dict()
    json.dumps(out, allow_nan=False)
    rec = out["discovery"]
    assert rec["formula"] == f"F = {term.coefficient:.4g}*z"
    assert rec["terms"][0]["expression"] == "z" and rec["bic_drop"] > 1000
    assert "--discover --effects-out" in rec["command"]
    assert out["explanations"][0]["kind"] == "discovered"
    assert "diagnose.discovered" in {n["code"] for n in out["notes"]}


def test_a_hidden_quadratic_drag_is_discovered():
    # c = 8 N s^2/m^2: at the top speed (~0.45 m/s) about 1.6 N, a third of the viscous force
    d = diagnose(fit_paper_model(hidden_force("v*abs(v)", -8.0, seed=32)))
    found = d.discovery
    assert found is not None
    assert [t.expression for t in found.terms] == ["v*abs(v)"]
    # standard error ~0.3 at this noise; 15 % of 8 is 1.2, about 4 of them
    assert found.terms[0].coefficient == pytest.approx(-8.0, rel=0.15)
    assert found.terms[0].term.unit == "N s^2/m^2"


def test_a_clean_log_discovers_nothing_even_when_forced_to_search(monkeypatch):
    # the arena says adequate, so the search is not tried; forced, it must find nothing
    start = fit_paper_model(hidden_force("z", 0.0, seed=33, rho=0.5))
    assert diagnose(start).discovery is None
    monkeypatch.setattr(discovery, "should_try", lambda *a: True)
    d = diagnose(start)
    assert d.discovery is None and d.verdict == "adequate"
    assert d.to_dict()["discovery"] is None


def test_the_written_effect_loads_as_an_effects_file_and_lowers_the_error(spring, tmp_path):
    start, d = spring
    path, name = discovery.write_effect(d.discovery, tmp_path / "hose_found.py")
    text = path.read_text()
    assert name == "hose_found" and text.startswith(discovery.MARKER)
    assert "F = k_z*z" in text and "Param(" in text and '"N/m"' in text
    registry = default_registry([path])  # what --effects-file does
    model = parse_model("variable_viscosity+hose_found", registry)
    # written with 6 significant digits: a rounding of at most 5e-6 of the value
    assert model.param("k_z").value == pytest.approx(d.discovery.terms[0].coefficient, rel=5e-6)
    # as `fit --model variable_viscosity+hose_found --effects-file hose_found.py` fits it
    refit = identify_fit(start.trial_set, model=model, profile=False, held_out=False)
    assert refit.values["k_z"] == pytest.approx(-4.0, rel=0.05)
    assert refit.match.metrics["rmse"] < 0.5 * start.match.metrics["rmse"]
    # never over a file of the user's; a file it wrote only with overwrite
    with pytest.raises(OutputExistsError, match="exists already"):
        discovery.write_effect(d.discovery, path)
    discovery.write_effect(d.discovery, path, overwrite=True)
    mine = tmp_path / "mine.py"
    mine.write_text((EXAMPLES / "effects" / "hose_spring.py").read_text())
    with pytest.raises(OutputExistsError, match="not written by balancer-id"):
        discovery.write_effect(d.discovery, mine, overwrite=True)
    assert mine.read_text() == (EXAMPLES / "effects" / "hose_spring.py").read_text()


def test_improve_discover_on_a_clean_log_writes_no_file(tmp_path):
    start = fit_paper_model(hidden_force("z", 0.0, seed=34))
    out = tmp_path / "found.py"
    result = improve(start, max_steps=1, discover_to=out)
    assert not out.exists()
    assert result.discovered is None
    assert result.discovery_note is not None and result.discovery_note.code == (
        "improve.no_discovery"
    )
    assert "no effect file written" in result.to_dict()["discovery_note"]["text"]
    assert [s.model for s in result.steps] == ["variable_viscosity"]


def test_a_user_term_joins_the_library():
    t = discovery.Term("z*abs(v)", "N s/m^2", "c_zabsv")
    assert t.evaluate(np.zeros(2), np.array([1.0, -2.0]), np.array([0.5, 0.5]), np.zeros(2))[
        1
    ] == pytest.approx(1.0)
    # a sign term on numpy states (its bool arithmetic needs Python floats)
    coulomb = next(x for x in discovery.default_terms(0.3, None) if x.name == "f_c")
    got = coulomb.evaluate(np.zeros(3), np.array([-0.2, 0.0, 0.3]), np.zeros(3), np.zeros(3))
    assert got.tolist() == [-1.0, 0.0, 1.0]
    src = discovery.library_source([*discovery.default_terms(0.3, None), t])
    assert "z*abs(v)" in src and "q13 * (z*abs(v))" in src


def test_improve_discover_options_are_checked_before_any_work(cli, tmp_path):
    log = str(Path(__file__).parent.parent / "sample_logs" / "hose_walkthrough.csv")
    code, _, err = cli("improve", log, "--discover")
    assert code == 2 and "--discover and --effects-out" in err
    mine = tmp_path / "mine.py"
    mine.write_text("# my effect\n")
    code, _, err = cli("improve", log, "--discover", "--effects-out", mine, "--overwrite")
    assert code == 2 and "not written by balancer-id" in err and "mine.py" in err
    assert mine.read_text() == "# my effect\n"
    code, _, err = cli("improve", log, "--discover", "--effects-out", tmp_path / "x.txt")
    assert code == 2 and ".py" in err


def test_discovered_dry_friction_sticks_below_its_static_level_in_the_written_file(tmp_path):
    """Coulomb and Stribeck terms, written for a model without a friction effect, act as
    dry friction: a thrust below the level at v = 0 (F_c + F_s) moves nothing; above it
    the load slides to the speed where the thrust balances viscosity plus the sliding
    friction (first-order analytic steady state)."""
    from balancer_id.model.registry import load_effects_file
    from balancer_id.simulation.engine import simulate
    from balancer_id.simulation.inputs import Thrust

    terms = {t.name: t for t in discovery.default_terms(1.0, None)}
    f_c, f_s = 0.5, 0.3
    stribeck = discovery.Term(
        "((v > 0.0) - (v < 0.0))*math.exp(-abs(v)/v_s1)",
        "N",
        "f_st1",
        (("v_s1", 0.05),),
        "math.exp(-abs(v)/v_s1)",
    )
    found = discovery.Discovery(
        terms=[
            discovery.DiscoveredTerm(terms["f_c"], -f_c, 0.01, 1.0),
            discovery.DiscoveredTerm(stribeck, -f_s, 0.01, 1.0),
        ],
        delta_bic=100.0,
        rmse=0.03,
        command="",
        refit=None,  # type: ignore[arg-type]
        stick=True,
    )
    source = found.effect_source("dry")
    assert "def friction(v, F, f_c, f_st1):" in source
    path = tmp_path / "dry.py"
    path.write_text(source, encoding="utf-8")
    (cls,) = load_effects_file(path)
    registry = Registry(list(default_registry()))
    registry.add(cls)
    model = parse_model("viscous+dry", registry)
    values = {"m_a": 2.0, "T_a": 0.05, "D0": 4.0, "f_c": -f_c, "f_st1": -f_s}
    t = np.arange(0.0, 8.0, 0.005)
    below = simulate(model, values, t, Thrust.step(0.5, 0.9 * (f_c + f_s)))
    assert np.max(np.abs(below.velocity)) == 0.0
    above = simulate(model, values, t, Thrust.step(0.5, 2.5))
    v_end = float(above.velocity[-1])
    # v = (u - f_c - f_s exp(-v/v_s)) / D0; at v ~ 0.5 m/s the Stribeck part is e^-10
    assert v_end == pytest.approx((2.5 - f_c) / 4.0, rel=1e-3)


def test_the_sparse_selection_finds_a_known_support_and_resamples_by_gram_sums():
    """A linear problem with nuisance parameter columns and a sparse truth: the residual
    is 3 q2 - 2 q5 plus parameter columns plus unit noise (4 trials x 500 rows). The
    selection projects the parameters out and finds {2, 5}; a resample naming a trial
    twice equals the rows stacked twice."""
    rng = np.random.default_rng(5)
    r, p, q = [], [], []
    for _ in range(4):
        pi = rng.normal(size=(500, 3))
        qi = rng.normal(size=(500, 8)) + 0.3 * pi[:, :1]  # terms correlated with a parameter
        r.append(3.0 * qi[:, 2] - 2.0 * qi[:, 5] + pi @ [1.0, -4.0, 2.0] + rng.normal(size=500))
        p.append(pi)
        q.append(qi)
    lin = discovery._Linear(r, p, q)
    assert sorted(discovery.select(lin, range(4), range(8))) == [2, 5]
    g, n = lin.gram([0, 1, 1, 3])
    a = np.vstack([np.hstack([p[i], q[i], r[i][:, None]]) for i in (0, 1, 1, 3)])
    assert n == 2000
    assert np.allclose(g, a.T @ a)


def test_a_stribeck_law_is_told_from_karnopp_on_a_heavy_balancer():
    """A 1.6 t balancer with Coulomb-with-Stribeck friction (F_c 101 N, F_s 87 N, v_s 0.23
    m/s; the static level is 8-58 % of the thrusts). Karnopp's constant level reaches the
    noise floor too, with the viscosity bent: its force is 0.34 of the friction's RMS off.
    The discovered law must win with its Coulomb level (a Stribeck term alone, the
    Coulomb level left to the viscosity, was 0.66 off and m_a 13 % high), and its force
    over the visited states within 25 % of the truth's RMS: it is 0.19 off, most of it
    the Coulomb level trading with D(h) at three steady speeds, not the noise."""
    terms = discovery.default_terms(1.0, None)
    lib = discovery.library_effect(terms, stick=True)
    registry = Registry()
    registry.add(lib)
    model = parse_model(f"variable_viscosity+{lib.name}", registry)
    index = {t.name: j for j, t in enumerate(terms)}
    f_c, f_s, v_s = 101.2, 87.0, 0.227
    truth = {"m_a": 1631.0, "T_a": 0.476, "D0": 865.0, "A": 0.002335}
    truth.update({key: val for t in terms for key, val in t.shapes})
    truth.update({f"q{j}": 0.0 for j in range(len(terms))})
    truth.update({f"q{index['f_c']}": -f_c, f"q{index['f_st1']}": -f_s, "v_s1": v_s})
    thrusts = [s * u * 2000.0 / 15.1 for u in (4.9, 7.35, 2.45) for s in (1.0, -1.0)]
    sensor = SensorSettings(tilt_deg=12.0, accel_noise=0.041, force_noise=5.0)
    recs = synthetic_recordings(
        model, truth, thrusts, sensor=sensor, rest_s=2.0, duration_s=8.0, seed=41
    )
    log = Log(Path("stribeck_heavy.csv"), "pasco-capstone", recs)
    trials = TrialSet([LoadedLog(log, find_trials(log, min_step_N=0.4 * 324.0))])
    d = diagnose(identify_fit(trials, model="variable_viscosity", profile=False))
    found = d.discovery
    assert found is not None and d.verdict == "effect missing"
    names = {t.term.name for t in found.terms}
    assert "f_c" in names and any(n.startswith("f_st") for n in names)
    assert found.refit.values()["m_a"] == pytest.approx(1631.0, rel=0.08)
    assert found.explanation().delta_bic > max(
        e.delta_bic for e in d.explanations if e.kind == "effect"
    )
    st = found.states
    moving = st["t"] > 0
    v = st["v"][moving]
    true_force = -(f_c + f_s * np.exp(-np.abs(v) / v_s)) * np.sign(v)
    got = found.force(st["f"][moving], v, st["z"][moving], st["h"][moving])
    nrms = np.sqrt(np.mean((got - true_force) ** 2)) / np.sqrt(np.mean(true_force**2))
    assert nrms < 0.25
