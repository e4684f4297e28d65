"""A new model's first use: compile time with an empty kernel cache (issue 20, item 7).

Each command runs as a fresh process with ``BALANCER_ID_CACHE`` pointing at a new empty
folder, so every simulation kernel it needs is generated and compiled by numba (the
package's own cached numba functions, e.g. the filters, stay warm: they are compiled once
per install). Measured, each as the median of ``--runs`` runs, wall and CPU seconds
(CPU: user + system of the process and its compiling helpers, from ``wait4``):

* ``improve sample_logs/paper_balancer.csv --start viscous`` cold: 12 kernels, in two
  rounds of candidates (target: under 20 s);
* ``fit sample_logs/paper_balancer.csv --model variable_viscosity+karnopp --no-cache``
  cold: one new model's first fit (its candidates' kernels are compiled too, as the
  command does before fitting: ``--no-diagnose`` is not an option of ``fit``);
* one kernel compiled in-process (``variable_viscosity+karnopp``, state and sensitivity
  kernels) after numba's own warm-up, the per-model cost;
* the same ``improve`` with the cache warm, the floor the cold run tends to.

Run: ``python benchmarks/bench_first_use.py [--runs N] [--only improve,fit,kernel,warm]``.
The machine should be otherwise idle: compilation is CPU-bound and uses every core.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOG = ROOT / "sample_logs" / "paper_balancer.csv"
PY = sys.executable
IMPROVE = [PY, "-m", "balancer_id", "improve", str(LOG), "--start", "viscous"]
FIT = [PY, "-m", "balancer_id", "fit", str(LOG), "--model", "variable_viscosity+karnopp"]
FIT += ["--no-cache"]

_ONE_KERNEL = """
import sys, time
import numpy as np
from balancer_id.model.spec import resolve_model
from balancer_id.simulation import kernel as K

def compile_one(spec):
    m = resolve_model(spec)
    k = K._build(m)
    p = np.array([q.value for q in m.params])
    t0, c0 = time.perf_counter(), time.process_time()
    K._run_tiny(k.simulate_batch, p)
    K._run_tiny_sens(k.simulate_batch_sens, p)
    return time.perf_counter() - t0, time.process_time() - c0

compile_one("viscous+bias")  # numba's own first-use work (overloads, typing context)
print(*compile_one(sys.argv[1]))
"""


def run(cmd: list[str], cache: str | None) -> tuple[float, float]:
    """Wall and CPU seconds of one finished process (and the helpers it waited for)."""
    env = dict(os.environ, BALANCER_ID_QUIET="1")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    if cache is not None:
        env["BALANCER_ID_CACHE"] = cache
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT, env=env
    )
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if status != 0:
        raise SystemExit(f"{' '.join(cmd)} failed (status {status})")
    return wall, usage.ru_utime + usage.ru_stime


def cold(cmd: list[str]) -> tuple[float, float]:
    """``cmd`` with a new, empty kernel cache."""
    folder = tempfile.mkdtemp(prefix="bid-cold-")
    try:
        return run(cmd, folder)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def one_kernel(spec: str) -> tuple[float, float]:
    """Wall and CPU seconds compiling one model's two kernels in a warmed-up process."""
    folder = tempfile.mkdtemp(prefix="bid-cold-")
    try:
        env = dict(os.environ, BALANCER_ID_CACHE=folder, BALANCER_ID_QUIET="1")
        env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
        out = subprocess.run(
            [PY, "-c", _ONE_KERNEL, spec], env=env, cwd=ROOT, capture_output=True, text=True
        )
        if out.returncode != 0:
            raise SystemExit(out.stderr)
        wall, cpu = (float(x) for x in out.stdout.split())
        return wall, cpu
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def report(name: str, samples: list[tuple[float, float]]) -> None:
    walls = [w for w, _ in samples]
    cpus = [c for _, c in samples]
    print(
        f"{name:<46} wall median {statistics.median(walls):6.2f} s "
        f"(min {min(walls):.2f}, max {max(walls):.2f}), CPU median {statistics.median(cpus):6.2f} s"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--only", default="improve,fit,kernel,warm")
    args = ap.parse_args()
    only = set(args.only.split(","))
    print(f"{os.cpu_count()} CPUs; median of {args.runs} runs, each with an empty kernel cache")
    if "improve" in only:
        report("improve --start viscous, cold", [cold(IMPROVE) for _ in range(args.runs)])
    if "fit" in only:
        report(
            "fit --model variable_viscosity+karnopp, cold", [cold(FIT) for _ in range(args.runs)]
        )
    if "kernel" in only:
        samples = [one_kernel("variable_viscosity+karnopp") for _ in range(args.runs)]
        report("one kernel (variable_viscosity+karnopp)", samples)
    if "warm" in only:
        folder = tempfile.mkdtemp(prefix="bid-warm-")
        try:
            run(IMPROVE, folder)  # fills the cache
            report(
                "improve --start viscous, warm", [run(IMPROVE, folder) for _ in range(args.runs)]
            )
        finally:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
