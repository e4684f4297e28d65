"""A new model's first use: compile time with an empty kernel cache (issue 20, item 7).

Each command runs as a fresh process with ``BALANCER_ID_CACHE`` pointing at a new empty
folder, so every simulation kernel it needs is generated and compiled by numba (the
package's own cached numba functions, e.g. the filters, stay warm: they are compiled once
per install). Each row is run under both kernel policies (``BALANCER_ID_KERNELS``):

* ``shared``: every model of built-in effects runs on the one kernel they share, compiled
  once. This is what a first command does by default (``auto``), minus the background
  process that then compiles each model's own kernel for the next command (left out here
  so that it does not take the cores from the next run);
* ``own``: each model compiles its own kernel before its first use (the behaviour before
  the shared kernel; ``auto`` once the own kernels are cached).

Measured, each as the median of ``--runs`` runs, wall and CPU seconds (CPU: user + system
of the process and its compiling helpers, from ``wait4``):

* ``improve sample_logs/paper_balancer.csv --start viscous`` cold (target: under 20 s);
* ``fit sample_logs/paper_balancer.csv --model variable_viscosity+karnopp --no-cache``
  cold: one new model's first fit (its candidates' kernels are compiled too, as the
  command does before fitting);
* one kernel compiled in-process (``variable_viscosity+karnopp``'s own, and the shared
  one), state and sensitivity kernels, after numba's own warm-up;
* the same ``improve`` with the cache warm, the floor the cold run tends to (``own``: the
  own kernels, what ``auto`` uses once they are compiled).

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
import os, sys, time
import numpy as np
from balancer_id.model.spec import resolve_model
from balancer_id.simulation import kernel as K
from balancer_id.simulation import kernel_cache as KCache

def compile_one(spec):
    m = resolve_model(spec)
    k = K._build(m)
    p = k.parameters([q.value for q in m.params])
    t0, c0 = time.perf_counter(), time.process_time()
    K._run_tiny(k.simulate_batch, p)
    K._run_tiny_sens(k.simulate_batch_sens, p)
    return time.perf_counter() - t0, time.process_time() - c0

policy = os.environ["BALANCER_ID_KERNELS"]
os.environ["BALANCER_ID_KERNELS"] = "own"
compile_one("viscous+bias")  # numba's own first-use work (overloads, typing context)
os.environ["BALANCER_ID_KERNELS"] = policy
KCache._CHOSEN.clear()
print(*compile_one(sys.argv[1]))
"""


def run(cmd: list[str], cache: str | None, policy: str) -> tuple[float, float]:
    """Wall and CPU seconds of one finished process (and the helpers it waited for)."""
    env = dict(os.environ, BALANCER_ID_QUIET="1", BALANCER_ID_KERNELS=policy)
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


def cold(cmd: list[str], policy: str) -> tuple[float, float]:
    """``cmd`` with a new, empty kernel cache."""
    folder = tempfile.mkdtemp(prefix="bid-cold-")
    try:
        return run(cmd, folder, policy)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def one_kernel(spec: str, policy: str) -> tuple[float, float]:
    """Wall and CPU seconds compiling one model's two kernels in a warmed-up process."""
    folder = tempfile.mkdtemp(prefix="bid-cold-")
    try:
        env = dict(
            os.environ, BALANCER_ID_CACHE=folder, BALANCER_ID_QUIET="1", BALANCER_ID_KERNELS=policy
        )
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
    for policy in ("shared", "own"):
        if "improve" in only:
            samples = [cold(IMPROVE, policy) for _ in range(args.runs)]
            report(f"improve --start viscous, cold, {policy}", samples)
        if "fit" in only:
            samples = [cold(FIT, policy) for _ in range(args.runs)]
            report(f"fit --model variable_viscosity+karnopp, cold, {policy}", samples)
        if "kernel" in only:
            samples = [one_kernel("variable_viscosity+karnopp", policy) for _ in range(args.runs)]
            report(f"one kernel (variable_viscosity+karnopp), {policy}", samples)
        if "warm" in only:
            folder = tempfile.mkdtemp(prefix="bid-warm-")
            try:
                run(IMPROVE, folder, policy)  # fills the cache
                samples = [run(IMPROVE, folder, policy) for _ in range(args.runs)]
                report(f"improve --start viscous, warm, {policy}", samples)
            finally:
                shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
