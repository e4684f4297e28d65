"""Do the credible intervals hold where Wald's fail? Coverage over seeds (issue 34.2).

Recordings where the Wald interval is known to fail, each over fresh seeds:

* **near a bound**: a balancer with almost no viscosity (D0 = 0.2 kg/s, bound 0), two
  short steps (2.5 s), noise 0.05 m/s^2: D0's Wald interval crosses zero;
* **short log**: the paper's balancer (``variable_viscosity``), 1.5 s after each step,
  noise 0.05, six steps (±2.45, ±4.9, ±7.35 N) or two thrust levels (2.45, -4.9 N): D0
  and A barely in the data, the cost far from quadratic (with two levels a ridge, D0 and
  A both large, fits about as well as the truth);
* **light cart**: 0.2 kg (``variable_viscosity``, T_a 0.04 s), four 1 s steps (±0.5, ±1 N),
  each step anywhere between two samples at 200 Hz (the trial told the sample before):
  T_a's standard error is mostly the steps' places and the trials' scatter, which the
  likelihood lacks (``--likelihood-only`` measures the credible intervals without the
  spread added for them).

Per case and parameter: the share of seeds whose 95 % interval holds the truth for the
Wald interval, the interval the fit reports (profile where Wald crosses a bound) and the
posterior's credible interval (``fit(..., posterior=True)``), equal-tailed and
highest-density (the one reported) from the same samples, each share with Wilson's 95 %
binomial interval; the median width of the credible interval over the Wald one. Per case:
the share of chains that converged, their autocorrelation times, acceptance and CPU.

Run: ``python benchmarks/bench_posterior.py [--seeds N] [--seed S] [--case TEXT]
[--likelihood-only]`` (a
fresh seed is drawn and printed unless ``--seed`` repeats one; ``--case "2 levels"`` runs
only the cases whose name holds the text).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from balancer_id.identify.api import fit
from balancer_id.identify.data import TrialData
from balancer_id.model import parse_model
from balancer_id.simulation.engine import TrialInput, simulate_many
from balancer_id.simulation.inputs import Thrust

CASES = {
    "near a bound (D0 = 0.2)": (
        "viscous",
        {"m_a": 15.1, "T_a": 0.33, "D0": 0.2},
        (2.45, -4.9),
        2.5,
        0.05,
    ),
    "short log (6 steps of 1.5 s)": (
        "variable_viscosity",
        {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4},
        (2.45, -2.45, 4.9, -4.9, 7.35, -7.35),
        1.5,
        0.05,
    ),
    "short log (1.5 s, 2 levels)": (
        "variable_viscosity",
        {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4},
        (2.45, -4.9),
        1.5,
        0.05,
    ),
    "light cart (0.2 kg, steps between samples)": (
        "variable_viscosity",
        {"m_a": 0.2, "T_a": 0.04, "D0": 0.25, "A": 0.5},
        (0.5, -0.5, 1.0, -1.0),
        1.0,
        0.05,
    ),
}
#: Cases whose steps fall anywhere between two samples (the trial told the sample
#: before): T_a's standard error is then mostly that spread on a light cart.
BETWEEN = {"light cart (0.2 kg, steps between samples)"}


def step_trials(
    spec, truth, thrusts, seconds, noise, rng, between: bool = False
) -> list[TrialData]:
    """Step trials of ``truth`` with white noise (1 s rest before each step, 200 Hz); with
    ``between`` each step lies uniformly between two samples, the trial told the one
    before."""
    model = parse_model(spec)
    t = np.arange(0.0, 1.0 + seconds, 0.005)
    offsets = rng.uniform(0.0, 0.005, len(thrusts)) if between else np.zeros(len(thrusts))
    inputs = [TrialInput(t, Thrust.step(1.0 + o, f)) for f, o in zip(thrusts, offsets, strict=True)]
    told = [TrialInput(t, Thrust.step(1.0, f)) for f in thrusts]
    sims = simulate_many(model, truth, inputs)
    return [
        TrialData(k, f, "up" if f > 0 else "down", 1.0, inp, s.accel + rng.normal(0, noise, t.size))
        for k, (f, inp, s) in enumerate(zip(thrusts, told, sims, strict=True))
    ]


def inside(iv, value: float) -> bool:
    """Whether ``value`` lies in the interval ``iv`` (None: no interval, counted a miss)."""
    return iv is not None and iv[0] <= value <= iv[1]


def wilson(hits: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson's 95 % interval of a binomial share (``hits`` of ``n``), in per cent."""
    if n == 0:
        return float("nan"), float("nan")
    p = hits / n
    mid = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return 100 * max(0.0, mid - half), 100 * min(1.0, mid + half)


def share(hits: int, n: int) -> str:
    """``hits`` of ``n`` in per cent with Wilson's interval."""
    lo, hi = wilson(hits, n)
    return f"{100 * hits / n:.0f} % ({lo:.0f}-{hi:.0f})"


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--seed", type=int, default=None, help="repeat a run (default: fresh)")
    ap.add_argument("--case", default="", help="only the cases whose name holds this text")
    ap.add_argument(
        "--likelihood-only",
        action="store_true",
        help="credible intervals from the likelihood alone (before the spread of the steps' "
        "places and the trials' scatter was added to the samples)",
    )
    args = ap.parse_args()
    if args.likelihood_only:
        import balancer_id.identify.posterior as posterior

        posterior.unmodelled_spread = lambda match, names: dict.fromkeys(names, 0.0)
    seed0 = int(args.seed if args.seed is not None else np.random.SeedSequence().entropy % 10**6)
    print(
        f"seed {seed0} (repeat with --seed {seed0}); {args.seeds} seeds per case"
        + ("; likelihood only" if args.likelihood_only else "")
    )
    print(
        "| recording | parameter | Wald holds truth | reported (profile where Wald "
        "crosses a bound) | credible (equal-tailed) holds truth | credible (highest "
        "density) holds truth (misses below / above) | credible / Wald width |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    summary = []
    for case, (spec, truth, thrusts, seconds, noise) in CASES.items():
        if args.case not in case:
            continue
        hits = {k: np.zeros(4, int) for k in truth}
        below = {k: 0 for k in truth}  # credible misses with the truth below the interval
        widths: dict[str, list[float]] = {k: [] for k in truth}
        conv = 0
        taus, accs, ratios = [], [], []
        took = cpu = 0.0
        for s in range(args.seeds):
            rng = np.random.default_rng(seed0 + s)
            trials = step_trials(spec, truth, thrusts, seconds, noise, rng, case in BETWEEN)
            start, start_cpu = time.perf_counter(), time.process_time()
            result = fit(trials, model=spec, posterior=True, seed=seed0 + s)
            took += time.perf_counter() - start
            cpu += time.process_time() - start_cpu
            post = result.posterior
            conv += post.converged
            longest = max(post.tau.values())
            taus.append(longest)
            accs.append(post.acceptance)
            ratios.append(post.n_steps / longest if np.isfinite(longest) else float("nan"))
            equal, cred = post.credible(kind="equal"), post.credible()
            for k, value in truth.items():
                est = result.match.parameters[k]
                hits[k] += [
                    inside(est.wald_ci95, value),
                    inside(est.ci95, value),
                    inside(equal.get(k), value),
                    inside(cred.get(k), value),
                ]
                below[k] += bool(k in cred and value < cred[k][0])
                if est.wald_ci95 is not None:
                    w = est.wald_ci95[1] - est.wald_ci95[0]
                    widths[k].append((cred[k][1] - cred[k][0]) / w)
            missed = [k for k in truth if not inside(cred.get(k), truth[k])]
            print(
                f"<!-- {case}, seed {seed0 + s}: credible misses {', '.join(missed) or 'none'}; "
                f"valleys {[round(float(m['weight']), 2) for m in post.modes]}; "
                f"{post.diagnostics_text()} -->",
                flush=True,
            )
        n = args.seeds
        for k in truth:
            ratio = np.median(widths[k]) if widths[k] else float("nan")
            misses = n - int(hits[k][3])
            print(
                f"| {case} | {k} | {share(hits[k][0], n)} | {share(hits[k][1], n)} | "
                f"{share(hits[k][2], n)} | {share(hits[k][3], n)} ({below[k]} / "
                f"{misses - below[k]}) | {ratio:.2f} |"
            )
        summary.append(
            f"| {case} | {share(conv, n)} | {np.median(taus):.0f} ({np.max(taus):.0f}) | "
            f"{np.median(accs):.2f} ({np.min(accs):.2f}) | {np.nanmin(ratios):.0f} | "
            f"{cpu / n:.1f} s ({took / n:.1f} s) |"
        )
    print()
    print(
        "| recording | converged | autocorrelation time, median (longest) | acceptance, "
        "median (lowest) | fewest autocorrelation times run | CPU per fit (wall) |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    print("\n".join(summary))
    print(
        "(Wilson's 95 % interval of each share in brackets; the wall time depends on the "
        "machine's load, the samples do not)"
    )


if __name__ == "__main__":
    main()
