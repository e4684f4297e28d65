"""Identification accuracy and speed (issue: fit).

Accuracy: 50 seeds of simulated 6-trial logs (thrusts ±2.45, ±4.9, ±7.35 N, acceleration
noise 0.03 m/s^2, force noise 0.03 N, sensor tilted 5-25 degrees), each segmented from
the raw 3-axis signals and fitted with ``variable_viscosity``. Per parameter: bias,
spread, the share of seeds inside the tolerance (m_a 2 %, T_a 5 %, D0 8 %, A 15 %), the
spread over the Cramer-Rao bound (from the Jacobian at the truth) and the mean reported
standard error over the observed spread.

Speed (issue 12 targets), each also as a ratio to the script a user would otherwise write
(solve_ivp inside lmfit, ``benchmarks/baseline_solve_ivp.py``) in the same run: the core
fit of one 6-trial log (median over seeds, wall and CPU time; target <= 10 ms) against the
script's core fit of the same trials (``--pairs`` alternating pairs, median ratio, wall and
CPU), and the whole ``fit --no-cache`` command against the whole script (median of
``--runs`` alternating runs; target >= 10x).

Run: ``python benchmarks/bench_fit.py [--seeds N] [--pairs N] [--runs N] [--no-baseline]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from balancer_id.identify.data import FitData, TrialData
from balancer_id.identify.matching import match_trials
from balancer_id.model import parse_model
from balancer_id.read.recording import Log
from balancer_id.segment import find_trials
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings, write_synthetic_log

TRUTH = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
TOLERANCE = {"m_a": 0.02, "T_a": 0.05, "D0": 0.08, "A": 0.15}
THRUSTS = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)
NOISE = 0.03


def make_trials(model, seed: int) -> list[TrialData]:
    """Simulate, record with a tilted noisy sensor, segment: the trials a user would get."""
    rng = np.random.default_rng(seed)
    sensor = SensorSettings(tilt_deg=float(rng.uniform(5, 25)), accel_noise=NOISE, force_noise=0.03)
    recs = synthetic_recordings(model, TRUTH, THRUSTS, sensor=sensor, seed=seed)
    trials = find_trials(Log(Path(f"seed{seed}"), "pasco-capstone", recs))
    return [TrialData.from_trial(t) for t in trials]


def crlb(model, trials: list[TrialData]) -> dict[str, float]:
    """Cramer-Rao standard deviations at the truth for white noise of NOISE."""
    data = FitData.build(trials)
    p0 = np.asarray(model.vector(TRUTH))
    cols = []
    for i in range(p0.size):
        h = 1e-6 * max(abs(p0[i]), 1e-3)
        up, dn = p0.copy(), p0.copy()
        up[i] += h
        dn[i] -= h
        cols.append((data.packed.run(model, up)[:, 0] - data.packed.run(model, dn)[:, 0]) / (2 * h))
    jac = np.column_stack(cols)
    cov = NOISE**2 * np.linalg.inv(jac.T @ jac)
    return dict(zip(model.param_names, np.sqrt(np.diag(cov)), strict=True))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--runs", type=int, default=3, help="runs of each whole command (0: none)")
    parser.add_argument("--pairs", type=int, default=3, help="script/core fit pairs for the ratio")
    parser.add_argument("--no-baseline", action="store_true")
    args = parser.parse_args()
    model = parse_model("variable_viscosity")
    est = {n: [] for n in model.param_names}
    err = {n: [] for n in model.param_names}
    bound = {n: [] for n in model.param_names}
    core_times = []
    core_cpu = []
    nfev = []
    for seed in range(args.seeds):
        trials = make_trials(model, seed)
        if len(trials) != 6:
            print(f"seed {seed}: {len(trials)} trials found (expected 6)")
        start = {"m_a": 15.0, "T_a": 0.3}
        t0 = time.perf_counter()
        c0 = time.process_time()
        res = match_trials(model, trials, start=start)
        core_times.append(time.perf_counter() - t0)
        core_cpu.append(time.process_time() - c0)
        nfev.append(res.nfev)
        for n, p in res.parameters.items():
            est[n].append(p.value)
            err[n].append(p.stderr if p.stderr is not None else np.nan)
        if seed < 10:
            for n, s in crlb(model, trials).items():
                bound[n].append(s)
    print(f"accuracy over {args.seeds} seeds (noise {NOISE} m/s^2, tilt 5-25 deg, 6 trials)")
    print(
        f"{'param':6} {'truth':>7} {'bias %':>8} {'spread %':>9} {'in tol':>8} {'tol':>5} "
        f"{'spread/CRLB':>12} {'stderr/spread':>14}"
    )
    for n in model.param_names:
        x = np.asarray(est[n])
        truth = TRUTH[n]
        inside = np.mean(np.abs(x / truth - 1) <= TOLERANCE[n]) * 100
        spread = np.std(x, ddof=1)
        print(
            f"{n:6} {truth:7.3f} {100 * (x.mean() / truth - 1):8.3f} {100 * spread / truth:9.3f} "
            f"{inside:7.0f}% {100 * TOLERANCE[n]:4.0f}% {spread / np.mean(bound[n]):12.2f} "
            f"{np.nanmean(err[n]) / spread:14.2f}"
        )
    core = float(np.median(core_times[1:] if len(core_times) > 1 else core_times))
    cpu = float(np.median(core_cpu[1:] if len(core_cpu) > 1 else core_cpu))
    print(
        f"core fit of 6 trials, 4 parameters (median over seeds): {core * 1e3:.1f} ms wall, "
        f"{cpu * 1e3:.1f} ms CPU, {np.median(nfev):.0f} simulations with sensitivities "
        f"(median; {min(nfev)}-{max(nfev)})  (target <= 10 ms)"
    )
    if args.no_baseline:
        return
    from baseline_solve_ivp import fit_script

    trials = make_trials(model, 0)
    start = {"m_a": 15.0, "T_a": 0.3}
    pairs = []  # (script wall, script CPU, ours wall, ours CPU), alternating
    for _ in range(max(args.pairs, 1)):
        t0, c0 = time.perf_counter(), time.process_time()
        fit_script(trials, start)
        base = (time.perf_counter() - t0, time.process_time() - c0)
        fast = []
        for _ in range(5):
            t0, c0 = time.perf_counter(), time.process_time()
            match_trials(model, trials, start=start)
            fast.append((time.perf_counter() - t0, time.process_time() - c0))
        ours = np.median(np.asarray(fast), axis=0)
        pairs.append((*base, *ours))
    arr = np.asarray(pairs)
    wall_ratio = arr[:, 0] / arr[:, 2]
    cpu_ratio = arr[:, 1] / arr[:, 3]
    print(
        f"script's core fit (solve_ivp inside lmfit), same trials: {np.median(arr[:, 0]):.2f} s "
        f"wall, {np.median(arr[:, 1]):.2f} s CPU; ours {np.median(arr[:, 2]) * 1e3:.1f} ms wall, "
        f"{np.median(arr[:, 3]) * 1e3:.1f} ms CPU; ratio {np.median(wall_ratio):.0f}x wall, "
        f"{np.median(cpu_ratio):.0f}x CPU (median of {len(pairs)} pairs: "
        f"{', '.join(f'{r:.0f}' for r in wall_ratio)})"
    )
    if args.runs < 1:
        return
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "six_trials.csv"
        write_synthetic_log(log, model, TRUTH, THRUSTS, sensor=SensorSettings(tilt_deg=12.0))
        fit_cmd = ["balancer-id", "fit", str(log), "--json", "--no-cache"]
        script = [sys.executable, str(Path(__file__).with_name("baseline_solve_ivp.py")), str(log)]
        subprocess.run(fit_cmd, capture_output=True, check=True)  # kernels compiled/loaded
        ours, theirs = [], []
        for _ in range(args.runs):
            for cmd, into in ((fit_cmd, ours), (script, theirs)):
                t0 = time.perf_counter()
                subprocess.run(cmd, capture_output=True, check=True)
                into.append(time.perf_counter() - t0)
    ratios = np.asarray(theirs) / np.asarray(ours)
    print(
        f"whole 'fit --no-cache' command: {np.median(ours):.2f} s; the whole script: "
        f"{np.median(theirs):.1f} s; ratio {np.median(ratios):.1f}x "
        f"(runs {', '.join(f'{r:.1f}' for r in ratios)}; target >= 10x)"
    )


if __name__ == "__main__":
    sys.exit(main())
