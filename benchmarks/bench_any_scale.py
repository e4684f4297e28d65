"""Any scale (issue 17.5): light, paper-sized and heavy balancers identified from their logs.

Simulated logs (``viscous``, four steps each, seeded noise) of a 0.25 kg lab cart, the
paper's 15 kg balancer and a 2000 kg hoist, each fitted with the default bounds and the
starts from the data; prints the error of each parameter per seed and the share of
fits within the tolerances (3 % m_a, 6 % T_a, 10 % D0) and trusted.

    python benchmarks/bench_any_scale.py --seeds 10
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from balancer_id.identify import fit
from balancer_id.model import parse_model
from balancer_id.simulation.synth import SensorSettings, write_synthetic_log

TOL = {"m_a": 0.03, "T_a": 0.06, "D0": 0.10}
CASES = {
    "cart 0.25 kg": (
        {"m_a": 0.25, "T_a": 0.04, "D0": 0.3},
        [1.2, -1.2, 2.4, -2.4],
        SensorSettings(accel_noise=0.05, force_noise=0.02),
    ),
    "paper 15 kg": (
        {"m_a": 15.1, "T_a": 0.33, "D0": 6.0},
        [2.45, -2.45, 4.9, -4.9],
        SensorSettings(),
    ),
    "hoist 2000 kg": (
        {"m_a": 2000.0, "T_a": 0.6, "D0": 150.0},
        [200.0, -200.0, 400.0, -400.0],
        SensorSettings(accel_noise=0.01, force_noise=0.5),
    ),
}


def main() -> None:
    """Run the benchmark and print one line per case."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    model = parse_model("viscous")
    with tempfile.TemporaryDirectory() as tmp:
        for name, (truth, thrusts, sensor) in CASES.items():
            ok = 0
            worst = dict.fromkeys(TOL, 0.0)
            for seed in range(args.seeds):
                path = Path(tmp) / f"log_{seed}.csv"
                write_synthetic_log(
                    path, model, truth, thrusts, sensor=sensor, seed=seed, overwrite=True
                )
                result = fit(str(path), model="viscous", profile=False)
                errs = {k: result.values[k] / truth[k] - 1 for k in TOL}
                for k, e in errs.items():
                    worst[k] = max(worst[k], abs(e))
                ok += result.trusted and all(abs(errs[k]) <= TOL[k] for k in TOL)
            print(
                f"{name:14s} within tolerances and trusted: {ok}/{args.seeds}; worst error "
                + ", ".join(f"{k} {100 * v:.2f} %" for k, v in worst.items())
            )


if __name__ == "__main__":
    main()
