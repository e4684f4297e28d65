"""Do the reported standard errors hold? Coverage of the 95 % intervals under coloured noise.

Seeded 6-trial logs of the paper balancer (thrusts ±2.45, ±4.9, ±7.35 N, acceleration noise
0.03 m/s^2, a sensor tilted 5-25 degrees), with AR(1) acceleration noise of lag-one
correlation ``r`` (0: white; 0.5; 0.8: a sensor's low-pass or a phone's filter, correlation
time 9 samples), segmented and fitted with ``variable_viscosity``. Per parameter: the spread
of the estimates over the mean reported standard error (1 when the errors are right), and
the share of seeds whose Wald 95 % interval holds the truth (95 % when right). The fits'
median residual correlation time (``metrics.residual_tau``) by which the errors are widened.

Run: ``python benchmarks/bench_uncertainty.py [--seeds N] [--rho 0,0.5,0.8]``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' simlib

from simlib.noisy_fits import fit_noisy_logs

TRUTH = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
THRUSTS = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)


def run(rho: float, seeds: int) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """Estimates, standard errors and residual correlation times over the seeds."""
    est, se, taus = [], [], []
    for m in fit_noisy_logs(TRUTH, THRUSTS, rho, seeds):
        est.append([m.parameters[k].value for k in TRUTH])
        se.append([m.parameters[k].stderr for k in TRUTH])
        taus.append(float(m.metrics["residual_tau"]))
    return np.array(est), np.array(se, float), taus


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--rho", default="0,0.5,0.8")
    args = ap.parse_args()
    print("| r | tau (median) | parameter | spread / mean SE | 95 % interval holds the truth |")
    print("|---|---|---|---|---|")
    for rho in (float(x) for x in args.rho.split(",")):
        est, se, taus = run(rho, args.seeds)
        for j, k in enumerate(TRUTH):
            ratio = est[:, j].std(ddof=1) / se[:, j].mean()
            cover = np.mean(np.abs(est[:, j] - TRUTH[k]) < 1.96 * se[:, j])
            print(f"| {rho:g} | {np.median(taus):.1f} | {k} | {ratio:.2f} | {100 * cover:.0f} % |")


if __name__ == "__main__":
    main()
