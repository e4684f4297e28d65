"""Discovery of a missing force (issue 18): hidden forces found, clean logs left alone.

Every case simulates six step trials (three thrust levels, up and down) of a balancer at
one of three scales (light: m_a ~ 0.3 kg, paper-sized: ~15 kg, heavy: ~2000 kg; thrusts
and viscosity scaled alike, A scaled inversely; T_a in 0.15-0.5 s, noise 0.015-0.05
m/s^2, a tilted sensor), read back through the segmentation, fitted with the paper's
model (``variable_viscosity``) and diagnosed with discovery. The hidden forces, each on
top of the paper model:

- ``drag``: ``-c v|v|`` (15-35 % of the largest thrust at the top speed);
- ``spring``: ``-k z`` (15-35 % of the largest thrust at the farthest position);
- ``sine``: ``a sin(2 pi z / p)`` (10-25 % of the largest thrust; 3-6 periods visited);
- ``cubic``: ``-c v^3`` (15-35 % of the largest thrust at the top speed);
- ``stribeck``: ``-(F_c + F_s exp(-|v|/v_s)) sign(v)`` (F_c 5-12 % of the largest thrust,
  F_s 50-100 % of F_c, v_s 3-15 % of the top speed), dry friction as it is: a load at rest
  sticks while the other forces stay below F_c + F_s;
- ``clean-white`` and ``clean-coloured`` (AR(1) noise, lag-one 0.5-0.85): nothing hidden.

The hidden forces are simulated with the discovery's own library effect (its kernel is
compiled once), the true force is computed here from its formula. Per case: whether a
force was discovered, its normalized RMS error against the true force over the states the
log visited (the refit's simulated states), whether the final model is at the noise floor
(error above the known noise < 0.3x the noise), and the time of the ``diagnose`` with
discovery.

Run: ``python benchmarks/bench_discover.py [--seeds N] [--jobs N] [--forces a,b]``.
Targets: within 25 % in >= 90 % of the seeds per force (the table gives the term alone
and the model's force, see :func:`force_errors`); 0 false discoveries over the
clean logs (24 with ``--seeds 4``); a 6-trial diagnose with discovery <= 10 s.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
import zlib
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

SCALES = {"light": 0.3 / 15.1, "paper": 1.0, "heavy": 2000.0 / 15.1}
PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
LEVELS = (2.45, 4.9, 7.35)
FORCES = ("drag", "spring", "sine", "cubic", "stribeck", "clean-white", "clean-coloured")
TOLERANCE = 0.25
FLOOR = 0.3


@dataclass(frozen=True)
class Case:
    """One hidden force at one scale and seed."""

    force: str
    scale: str
    seed: int

    @property
    def rng_seed(self) -> int:
        """The case's own seed."""
        return zlib.crc32(f"{self.force}|{self.scale}|{self.seed}".encode())


@dataclass
class Outcome:
    """What the diagnosis found for one case."""

    case: Case
    discovered: bool = False
    library: str = ""
    formula: str = ""
    nrms: float = math.nan
    #: The same for the force of everything the refit moved (viscosity and the term).
    nrms_model: float = math.nan
    at_floor: bool = False
    verdict: str = ""
    seconds: float = 0.0
    n_trials: int = 0
    error: str = ""
    truth: dict[str, float] = field(default_factory=dict)


def true_force(force: str, p: dict[str, float], v: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The hidden force at the states (N), from its formula."""
    sign = np.sign(v)
    if force == "drag":
        return -p["c"] * v * np.abs(v)
    if force == "spring":
        return -p["k"] * z
    if force == "sine":
        return p["a"] * np.sin(2 * np.pi * z / p["p"])
    if force == "cubic":
        return -p["c"] * v**3
    if force == "stribeck":
        return -(p["F_c"] + p["F_s"] * np.exp(-np.abs(v) / p["v_s"])) * sign
    return np.zeros_like(v)


def force_errors(
    truth_f: np.ndarray,
    got: np.ndarray,
    values: dict[str, float],
    base: dict[str, float],
    v: np.ndarray,
    h: np.ndarray,
) -> tuple[float, float]:
    """Normalized RMS errors of the found force against the hidden one: the term alone,
    and the model's force (the viscosity the refit moved plus the term) against the true
    one (the true viscosity plus the hidden force), both over the hidden force's RMS.

    The second is what the log can tell: a Coulomb level and a viscosity that falls with
    the thrust trade against each other at the steady speeds of a few thrust levels.
    """
    scale = float(np.sqrt(np.mean(truth_f**2)))
    if scale <= 0:
        return math.nan, math.nan
    model = -values["D0"] * np.exp(-values["A"] * np.abs(h)) * v + got
    true = -base["D0"] * np.exp(-base["A"] * np.abs(h)) * v + truth_f
    term = float(np.sqrt(np.mean((got - truth_f) ** 2))) / scale
    return term, float(np.sqrt(np.mean((model - true) ** 2))) / scale


def simulate(case: Case):
    """The trials of a case, its true hidden-force parameters and the noise."""
    from balancer_id.diagnostics import discover as discovery
    from balancer_id.model import Registry, parse_model
    from balancer_id.read.recording import Log
    from balancer_id.segment import find_trials
    from balancer_id.simulation.engine import simulate
    from balancer_id.simulation.inputs import Thrust
    from balancer_id.simulation.synth import SensorSettings, synthetic_recordings
    from balancer_id.trials import LoadedLog, TrialSet

    rng = np.random.default_rng(case.rng_seed)
    s = SCALES[case.scale]
    base = {
        "m_a": PAPER["m_a"] * s * float(rng.uniform(0.7, 1.3)),
        "T_a": float(rng.uniform(0.15, 0.5)),
        "D0": PAPER["D0"] * s * float(rng.uniform(0.7, 1.3)),
        "A": float(rng.uniform(0.2, 0.6)) / s,
    }
    levels = list(LEVELS)
    rng.shuffle(levels)
    thrusts = [sgn * u * s for u in levels for sgn in (1.0, -1.0)]
    u_max = max(abs(u) for u in thrusts)
    terms = discovery.default_terms(1.0, None)
    lib = discovery.library_effect(terms, stick=True)  # dry friction sticks at rest
    registry = Registry()
    registry.add(lib)
    model = parse_model(f"variable_viscosity+{lib.name}", registry)
    # the top speed and the farthest position of the trials without the hidden force
    t = np.arange(0.0, 10.0, 0.005)
    sim = simulate(model, base, t, Thrust.step(2.0, u_max))
    v_top, z_top = float(np.max(np.abs(sim.velocity))), float(np.max(np.abs(sim.position)))
    noise = float(rng.uniform(0.015, 0.05))
    rho = float(rng.uniform(0.5, 0.85)) if case.force == "clean-coloured" else 0.0
    index = {t.name: j for j, t in enumerate(terms)}
    q = dict.fromkeys((f"q{j}" for j in range(len(terms))), 0.0)
    shapes = {key: val for t in terms for key, val in t.shapes}
    truth: dict[str, float] = {}
    if case.force == "drag":
        truth["c"] = u_max * float(rng.uniform(0.15, 0.35)) / v_top**2
        q[f"q{index['c_vv']}"] = -truth["c"]
    elif case.force == "spring":
        truth["k"] = u_max * float(rng.uniform(0.15, 0.35)) / z_top
        q[f"q{index['k_z']}"] = -truth["k"]
    elif case.force == "sine":
        truth["a"] = u_max * float(rng.uniform(0.1, 0.25)) * float(rng.choice([-1, 1]))
        truth["p"] = z_top / float(rng.uniform(3.0, 6.0))
        q[f"q{index['a_sin']}"] = truth["a"]
        shapes["p_z"] = truth["p"]
    elif case.force == "cubic":
        truth["c"] = u_max * float(rng.uniform(0.15, 0.35)) / v_top**3
        q[f"q{index['c_v3']}"] = -truth["c"]
    elif case.force == "stribeck":
        truth["F_c"] = u_max * float(rng.uniform(0.05, 0.12))
        truth["F_s"] = truth["F_c"] * float(rng.uniform(0.5, 1.0))
        truth["v_s"] = v_top * float(rng.uniform(0.03, 0.15))
        q[f"q{index['f_c']}"] = -truth["F_c"]
        q[f"q{index['f_st1']}"] = -truth["F_s"]
        shapes["v_s1"] = truth["v_s"]
    values = {**base, **q, **shapes}
    sensor = SensorSettings(
        tilt_deg=float(rng.uniform(5, 25)),
        tilt_azimuth_deg=float(rng.uniform(0, 360)),
        accel_noise=noise,
        noise_correlation=rho,
        force_noise=0.005 * u_max,
    )
    recs = synthetic_recordings(
        model,
        values,
        thrusts,
        sensor=sensor,
        rest_s=2.0,
        duration_s=8.0,
        seed=int(rng.integers(2**31)),
    )
    log = Log(Path(f"{case.force}_{case.scale}_{case.seed}.csv"), "pasco-capstone", recs)
    found = find_trials(log, min_step_N=0.4 * min(abs(u) for u in thrusts))
    return TrialSet([LoadedLog(log, found)]), truth, noise, base


def run_case(case: Case) -> Outcome:
    """Simulate, fit and diagnose one case; never raises."""
    from balancer_id.diagnostics.diagnosis import diagnose
    from balancer_id.identify.api import fit as run_fit
    from balancer_id.identify.api import trial_data

    out = Outcome(case)
    try:
        trials, truth, noise, base = simulate(case)
        out.truth = truth
        out.n_trials = len(trial_data(trials))
        # what `balancer-id fit` does (the starts from the data), without the profile
        fit = run_fit(trials, model="variable_viscosity", profile=False)
        match = fit.match
        t0 = time.perf_counter()
        d = diagnose(fit)
        out.seconds = time.perf_counter() - t0
        out.verdict = d.verdict
        found = d.discovery
        rmse = float(match.metrics["rmse"])
        if found is not None:
            out.discovered = True
            out.formula = found.formula
            st = found.states
            moving = st["t"] > 0
            v, z = st["v"][moving], st["z"][moving]
            f, h = st["f"][moving], st["h"][moving]
            truth_f = true_force(case.force, truth, v, z)
            got = found.force(f, v, z, h)
            out.nrms, out.nrms_model = force_errors(truth_f, got, found.refit.values(), base, v, h)
            rmse = found.rmse
        elif d.verdict != "adequate" and d.explanations:
            rmse = min(rmse, d.explanations[0].rmse)
            # the verdict's first suggestion (a pair listed above it did not beat its
            # parts by the threshold, so it is not the verdict)
            first = d.suggestions[0] if d.suggestions else None
            refit = first.refit if first is not None and first.effect == "karnopp" else None
            if refit is not None:
                # the library's Coulomb friction explains it: its force against the truth
                values = refit.values()
                pvec = np.array([values[n] for n in refit.model.param_names])
                sim = refit.data.packed.run(refit.model, pvec)
                t = np.concatenate([td.time - td.t_step for td in refit.data.trials])
                v, z = sim[t > 0, 1], sim[t > 0, 2]
                truth_f = true_force(case.force, truth, v, z)
                got = -values["f_s"] * np.sign(v)
                h = sim[t > 0, 4]
                out.nrms, out.nrms_model = force_errors(truth_f, got, values, base, v, h)
                out.library = "karnopp"
        out.at_floor = math.sqrt(max(rmse**2 - noise**2, 0.0)) < FLOOR * noise
    except Exception as exc:  # a benchmark reports every failure and goes on
        out.error = f"{type(exc).__name__}: {exc}"
    return out


def main() -> None:
    """Run the cases and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--forces", default=",".join(FORCES))
    parser.add_argument("--scales", default=",".join(SCALES))
    args = parser.parse_args()
    cases = [
        Case(force, scale, seed)
        for force in args.forces.split(",")
        for scale in args.scales.split(",")
        for seed in range(args.seeds)
    ]
    outcomes: list[Outcome] = []
    t0 = time.perf_counter()

    def log(o: Outcome) -> None:
        c = o.case
        print(
            f"  {len(outcomes)}/{len(cases)} {c.force} {c.scale} s{c.seed}: "
            f"{o.formula or o.library or '-'} nrms {o.nrms:.3f} model {o.nrms_model:.3f} "
            f"floor {o.at_floor} {o.verdict} "
            f"({o.seconds:.1f} s) {o.error}",
            flush=True,
        )

    if args.jobs <= 1:
        for c in cases:
            outcomes.append(run_case(c))
            log(outcomes[-1])
    else:
        with ProcessPoolExecutor(max_workers=args.jobs) as pool:
            futures = [pool.submit(run_case, c) for c in cases]
            for fut in as_completed(futures):
                outcomes.append(fut.result())
                log(outcomes[-1])
    by = defaultdict(list)
    for o in outcomes:
        by[o.case.force].append(o)
    print()
    print(f"{len(cases)} cases, {time.perf_counter() - t0:.0f} s, {args.jobs} job(s)")
    print(
        "| hidden force | cases | discovered | library effect | term within 25 % | median nRMS "
        "| model force within 25 % | median nRMS | of the discovered: term / model within 25 % "
        "| adequate (absorbed) | at noise floor | errors |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for force in args.forces.split(","):
        rows = by[force]
        n = len(rows)
        disc = sum(o.discovered for o in rows)
        lib = sum(bool(o.library) for o in rows)
        within = sum((o.discovered or bool(o.library)) and o.nrms <= TOLERANCE for o in rows)
        med = np.nanmedian([o.nrms for o in rows]) if disc or lib else math.nan
        within_m = sum(
            (o.discovered or bool(o.library)) and o.nrms_model <= TOLERANCE for o in rows
        )
        med_m = np.nanmedian([o.nrms_model for o in rows]) if disc or lib else math.nan
        absorbed = sum(o.verdict == "adequate" for o in rows)
        floor = sum(o.at_floor for o in rows)
        errs = sum(bool(o.error) for o in rows)
        if force.startswith("clean"):
            print(
                f"| {force} | {n} | {disc} (false) | - | - | - | - | - | - | {absorbed}/{n} | "
                f"{floor}/{n} | {errs} |"
            )
        else:
            seen = n - absorbed
            # where a library law (Karnopp) stood at the noise floor, the discovery had to
            # beat it by CHALLENGE_BIC: these columns judge the discovered forces alone
            d_term = sum(o.discovered and o.nrms <= TOLERANCE for o in rows)
            d_model = sum(o.discovered and o.nrms_model <= TOLERANCE for o in rows)
            print(
                f"| {force} | {n} | {disc}/{n} | {lib} | {within}/{n} "
                f"({within / max(seen, 1):.0%} of the {seen} not absorbed) | "
                f"{med:.3f} | {within_m}/{n} ({within_m / max(seen, 1):.0%}) | {med_m:.3f} | "
                f"{d_term}/{disc} / {d_model}/{disc} | "
                f"{absorbed}/{n} | {floor}/{n} | {errs} |"
            )
    clean = [o for o in outcomes if o.case.force.startswith("clean")]
    if clean:
        print(f"false discoveries on clean logs: {sum(o.discovered for o in clean)}/{len(clean)}")
    six = [o.seconds for o in outcomes if o.n_trials == 6 and o.seconds > 0]
    hidden = [o.seconds for o in outcomes if o.discovered and o.n_trials == 6]
    if six:
        print(
            f"diagnose time (6 trials): median {np.median(six):.1f} s, max {max(six):.1f} s; "
            + (
                f"with a discovery: median {np.median(hidden):.1f} s, max {max(hidden):.1f} s"
                if hidden
                else ""
            )
        )
    for o in outcomes:
        if o.error:
            print(f"error {o.case}: {o.error}")


if __name__ == "__main__":
    main()
