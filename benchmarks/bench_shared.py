"""Fits that share across logs (issue 33): a plant of one balancer type, payloads differing.

Each case is a plant of 4 to 20 logs of one ``variable_viscosity`` balancer type at one of
three scales (1.5, 15 and 300 kg; thrusts, D0 and A scaled alike), each log its own
payload (m_a from -20 % to +40 % of the type's) and its own sensor mounting, noise seed
and set of steps (4 to 6 of +-1, 2, 3 x the type's thrust unit). A quarter of the cases
are controls: every log the same payload. Each plant is fitted once with
``fit(logs, per_log=["m_a"])`` and scored:

* per-log m_a within the fit tolerance of ``bench_fit.py`` (2 %) of the truth;
* the shared parameters' standard errors against the number of logs: ``se * sqrt(n)``
  stays about constant when they fall as ``1/sqrt(n)`` (shown per n, relative to the
  mean over all n, per scale);
* the model choice: "partly shared" for differing payloads, "all shared" for the
  controls (wanted right in >= 90 %).

Fresh cases every run (the seed is printed; ``--seed`` repeats a run).

    python benchmarks/bench_shared.py --cases 12 [--logs 4,8,12,20] [--seed N] [--held-out]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from balancer_id.identify.api import fit
from balancer_id.model import parse_model
from balancer_id.simulation.synth import SensorSettings, write_synthetic_log

MODEL = parse_model("variable_viscosity")
PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
#: Scales: mass (kg) -> (drive lag T_a in s, accelerometer noise in m/s^2).
SCALES = {1.5: (0.12, 0.03), 15.1: (0.33, 0.03), 300.0: (0.5, 0.01)}
TOLERANCE = 0.02
SHARED = ("T_a", "D0", "A")


def run_case(n_logs: int, mass: float, control: bool, seed: int, folder: Path,
             held_out: bool) -> dict[str, object]:
    """Simulate one plant, fit it with m_a per log, score it."""
    rng = np.random.default_rng(seed)
    k = mass / PAPER["m_a"]
    lag, noise = SCALES[mass]
    common = {"T_a": lag, "D0": PAPER["D0"] * k, "A": PAPER["A"] / k}
    masses = [mass] * n_logs if control else list(mass * (1 + rng.uniform(-0.2, 0.4, n_logs)))
    paths = []
    for j, m_a in enumerate(masses):
        steps = int(rng.integers(4, 7))
        thrusts = [
            float(rng.choice([1, 2, 3])) * 2.45 * k * (1 if i % 2 == 0 else -1)
            for i in range(steps)
        ]
        if len({abs(x) for x in thrusts}) < 2:
            thrusts[1] = -thrusts[0] * 2 if abs(thrusts[0]) < 7 * k else -thrusts[0] / 3
        path = folder / f"plant_{seed}_{j}.csv"
        write_synthetic_log(
            path, MODEL, {"m_a": m_a, **common}, thrusts,
            sensor=SensorSettings(accel_noise=noise, force_noise=0.01 * k,
                                  tilt_deg=float(rng.uniform(2, 25))),
            seed=int(rng.integers(2**31)), overwrite=True,
        )
        paths.append(str(path))
    t0 = time.perf_counter()
    result = fit(paths, per_log=["m_a"], held_out=held_out, profile=False)
    seconds = time.perf_counter() - t0
    errors = [own["m_a"].value / m - 1 for own, m in zip(result.own, masses, strict=True)]
    want = "all shared" if control else "partly shared"
    return {
        "n": n_logs,
        "mass": mass,
        "control": control,
        "within": float(np.mean(np.abs(errors) <= TOLERANCE)),
        "worst": float(np.max(np.abs(errors))),
        "se": {p: result.shared[p].stderr / abs(common[p]) for p in SHARED
               if result.shared[p].stderr is not None},
        "supported": result.supported,
        "right": result.supported == want,
        "held": {k2: s.held_out_rmse for k2, s in result.scores.items()},
        "seconds": seconds,
    }


def main() -> None:
    """Run the benchmark; one line per case, then the summary tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=8)
    parser.add_argument("--logs", default="4,8,12,20", help="plant sizes drawn from")
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--held-out", action="store_true", help="also score held-out halves")
    args = parser.parse_args()
    seed = args.seed if args.seed is not None else int(np.random.SeedSequence().entropy % 2**31)
    print(f"seed {seed} (repeat with --seed {seed})")
    rng = np.random.default_rng(seed)
    sizes = [int(x) for x in args.logs.split(",")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for c in range(args.cases):
            n = sizes[c % len(sizes)]  # every size in turn, so each n is seen
            mass = float(rng.choice(list(SCALES)))
            control = c % 4 == 3
            row = run_case(n, mass, control, int(rng.integers(2**31)), Path(tmp), args.held_out)
            rows.append(row)
            se = ", ".join(f"{p} {v:.2%}" for p, v in row["se"].items())
            print(
                f"{n:>2} logs, {mass:g} kg, {'control' if control else 'payloads differ'}: "
                f"m_a within 2 %: {row['within']:.0%} (worst {row['worst']:.2%}); "
                f"shared rel. se {se}; supported: {row['supported']} "
                f"({'right' if row['right'] else 'WRONG'}); {row['seconds']:.1f} s",
                flush=True,
            )
    differ = [r for r in rows if not r["control"]]
    print()
    print("| measure | value | wanted |")
    print("|---|---|---|")
    if differ:
        print(f"| per-log m_a within 2 % (all logs of {len(differ)} plants) | "
              f"{np.mean([r['within'] for r in differ]):.1%} | within the fit tolerance |")
    print(f"| model choice right ({len(rows)} plants: {len(differ)} differing, "
          f"{len(rows) - len(differ)} controls) | {np.mean([r['right'] for r in rows]):.0%} | "
          ">= 90 % |")
    print(f"| seconds per plant fit (median, max) | {np.median([r['seconds'] for r in rows]):.1f},"
          f" {np.max([r['seconds'] for r in rows]):.1f} | |")
    print()
    print("Shared standard error x sqrt(logs), relative to its mean over the plant sizes of "
          "the same scale (1.00 everywhere = falling exactly as 1/sqrt(logs)):")
    print()
    print("| logs | " + " | ".join(SHARED) + " | plants |")
    print("|---" * (len(SHARED) + 2) + "|")
    by: dict[tuple[float, int], list[dict]] = defaultdict(list)
    for r in rows:
        by[(r["mass"], r["n"])].append(r)
    scaled: dict[int, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for mass in {r["mass"] for r in rows}:
        cells = {n: by[(mass, n)] for n in sizes if by[(mass, n)]}
        if len(cells) < 2:
            continue
        for p in SHARED:
            vals = {n: np.median([r["se"][p] for r in rs if p in r["se"]]) * np.sqrt(n)
                    for n, rs in cells.items()}
            mean = float(np.mean(list(vals.values())))
            for n, v in vals.items():
                scaled[n][p].append(v / mean)
    for n in sizes:
        if n in scaled:
            count = sum(len(by[(m, n)]) for m in SCALES)
            print(f"| {n} | " + " | ".join(f"{np.mean(scaled[n][p]):.2f}" for p in SHARED)
                  + f" | {count} |")
    if args.held_out:
        print()
        right = [r for r in rows
                 if min(r["held"], key=lambda k: r["held"][k] or np.inf) == r["supported"]]
        print(f"held-out halves rank the supported sharing first in {len(right)} of {len(rows)}")


if __name__ == "__main__":
    main()
