"""Robot-log identification over seeds (issue 9): accuracy of k_r, c_r and the coupled mode,
and the time of a fit. Run by hand: ``python benchmarks/bench_robot.py [N_SEEDS]``."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from balancer_id.fit import fit, resolve_model
from balancer_id.fit.coupling import coupling_of
from balancer_id.pipeline import read
from balancer_id.segment.move import find_moves
from balancer_id.simulate.inputs import Trapezoid
from balancer_id.simulate.synth import SensorSettings, write_synthetic_log

PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
MODEL = "variable_viscosity+servo"
MOVE = Trapezoid(0.2, 0.1, 0.5, start=2.0)
FOUND = Trapezoid(0.2, 0.1, 0.5)
SERVOS = [{"k_r": 150.0, "c_r": 100.0}, {"k_r": 400.0, "c_r": 180.0}]


def main(n_seeds: int) -> None:
    """Print one line per case and seed, then the worst errors."""
    worst: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for servo in SERVOS:
            truth = coupling_of({**PAPER, **servo})
            for seed in range(n_seeds):
                path = Path(tmp) / f"r{seed}.csv"
                write_synthetic_log(
                    path, resolve_model(MODEL), {**PAPER, **servo}, [0.0],
                    sensor=SensorSettings(accel_noise=0.03, force_noise=0.03),
                    duration_s=10.0, trajectory=MOVE, seed=100 + seed, overwrite=True,
                )  # fmt: skip
                log = read(path)
                noforce = find_moves(log, FOUND)
                for t in noforce:
                    t.force = None
                cases = {
                    "held": ([path], PAPER),
                    "held, no force": (noforce, PAPER),
                    "joint": ([path], {"A": 0.4}),
                }
                for name, (src, fixed) in cases.items():
                    t0 = time.perf_counter()
                    r = fit(src, model=MODEL, fixed=fixed, trajectory=FOUND)
                    dt = time.perf_counter() - t0
                    ek = r.values["k_r"] / servo["k_r"] - 1
                    ec = r.values["c_r"] / servo["c_r"] - 1
                    ef = r.coupling.oscillation_hz / truth.oscillation_hz - 1
                    key = f"{servo['k_r']:g}/{servo['c_r']:g} {name}"
                    print(
                        f"{key:28s} seed {seed}: k_r {100 * ek:+6.2f} %  c_r {100 * ec:+6.2f} %"
                        f"  f {100 * ef:+6.2f} %  {dt:5.2f} s"
                    )
                    worst[key] = max(worst.get(key, 0.0), abs(ek), abs(ec), abs(ef))
    for key, w in worst.items():
        print(f"worst |error| {key}: {100 * w:.2f} %")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
