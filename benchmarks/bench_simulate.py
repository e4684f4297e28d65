"""Simulator speed: one 10 s trial at 200 Hz of variable_viscosity+karnopp+speed_limit+dead_time.

Prints the compiled simulation time (after compilation), the same trial through
``scipy.integrate.solve_ivp`` at ``max_step = 0.01 s`` and their ratio, and the time a
fresh process needs to get the compiled kernel from the on-disk cache.

Run: ``python benchmarks/bench_simulate.py`` (targets: <= 200 us, >= 200x solve_ivp).
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from balancer_id.model import parse_model
from balancer_id.simulation import Thrust, TrialInput
from balancer_id.simulation.engine import PackedTrials
from balancer_id.simulation.kernel import get_kernel

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' simlib

from simlib.reference import simulate_reference

SPEC = "variable_viscosity+karnopp+speed_limit+dead_time"
PARAMS = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4, "f_s": 0.98, "v_max": 0.5, "tau_d": 0.05}


def best_time(func, repeat: int, number: int) -> float:
    """Best mean time of ``number`` calls over ``repeat`` rounds (s)."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            func()
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def main() -> None:
    model = parse_model(SPEC)
    t = np.arange(0.0, 10.0, 0.005)
    trial = TrialInput(t, Thrust.step(1.0, 4.9))
    packed = PackedTrials.pack([trial])
    pvec = np.asarray(model.vector(PARAMS))
    t0 = time.perf_counter()
    get_kernel(model)
    packed.run(model, pvec)
    first = time.perf_counter() - t0
    fast = best_time(lambda: packed.run(model, pvec), repeat=7, number=300)
    cols = list(range(pvec.size))
    packed.run_sens(model, pvec, cols)
    sens = best_time(lambda: packed.run_sens(model, pvec, cols), repeat=7, number=50)
    ref = best_time(lambda: simulate_reference(model, PARAMS, trial, max_step=0.01), 3, 1)
    code = (
        "import time; t0 = time.perf_counter();"
        "from balancer_id.model import parse_model;"
        "from balancer_id.simulation.kernel import get_kernel;"
        f"get_kernel(parse_model('{SPEC}')); print(time.perf_counter() - t0)"
    )
    cold = float(
        subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True
        ).stdout
    )
    print(f"model: {SPEC}; one trial of {t.size} samples (10 s at 200 Hz)")
    print(f"first call in this process (load or compile): {first:.2f} s")
    print(f"new process, kernel from the disk cache:     {cold:.2f} s")
    print(f"compiled simulator:                          {fast * 1e6:.0f} us  (target <= 200 us)")
    print(
        f"with forward sensitivities ({len(cols)} parameters):  {sens * 1e6:.0f} us "
        f"({sens / fast:.1f}x one simulation; finite differences cost {len(cols) + 1}x)"
    )
    print(f"solve_ivp (DOP853, max_step=0.01 s):         {ref * 1e3:.0f} ms")
    print(f"ratio:                                       {ref / fast:.0f}x  (target >= 200x)")


if __name__ == "__main__":
    main()
