"""Batch identification throughput (issue: batch).

N simulated 6-trial logs (thrusts ±2.45, ±4.9, ±7.35 N, 6 s after each step, noise
0.03 m/s^2, m_a spread over 10-20 kg) are identified with ``run_batch``: once in this
process (``jobs=1``) and once with one worker process per CPU. The parallel run is
timed twice: the first pays for starting the fork server and each worker's first log,
the second reuses the fork server (a notebook or a long-lived service sees this).
Imports and the kernel's compilation are paid before any timing; the in-process and
the warm parallel runs are the best of ``--repeat``, as other work on the machine
skews single timings.

A fresh ``python`` process running the batch (what the ``batch`` command costs, with
its imports and its fork server's start) is timed too, for ``jobs=1`` and ``jobs=J``.

The ceiling: the same ``jobs`` processes spinning a pure-Python loop, against one
process doing the same work in turn. On an idle machine it equals ``jobs``; a machine
shared with other work shows less, and the batch's speed-up is bounded by it.

Run: ``python benchmarks/bench_batch.py [--logs N] [--jobs J] [--repeat R]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from balancer_id.batch import BatchResult, run_batch, warm_kernel
from balancer_id.model import parse_model
from balancer_id.simulation.synth import SensorSettings, write_synthetic_log

TRUTH = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
THRUSTS = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)


def make_logs(folder: Path, n: int) -> list[Path]:
    """Write ``n`` seeded logs with different masses; returns their paths."""
    model = parse_model("variable_viscosity")
    masses = np.linspace(10.0, 20.0, n)
    paths = []
    for k, m_a in enumerate(masses):
        path = folder / f"log_{k:03d}.csv"
        write_synthetic_log(
            path,
            model,
            {**TRUTH, "m_a": float(m_a)},
            THRUSTS,
            sensor=SensorSettings(tilt_deg=5.0 + k % 20),
            duration_s=6.0,
            seed=k,
        )
        paths.append(path)
    return paths


def timed(paths: list[Path], out: Path, jobs: int, repeat: int = 1) -> tuple[float, BatchResult]:
    """Best wall time of ``repeat`` batches, and the last result."""
    best = float("inf")
    for k in range(repeat):
        t0 = time.perf_counter()
        result = run_batch(paths, out / str(k), jobs=jobs)
        best = min(best, time.perf_counter() - t0)
    return best, result


def whole_process(folder: Path, out: Path, jobs: int) -> float:
    """Wall time of a fresh interpreter importing balancer-id and running the batch."""
    code = (
        "import sys; from balancer_id.batch import run_batch; "
        f"sys.exit(run_batch([{str(folder)!r}], {str(out)!r}, jobs={jobs}).exit_code)"
    )
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True)
    return time.perf_counter() - t0


def spin(n: int) -> float:
    """Pure-Python CPU work; returns its wall time."""
    t0 = time.perf_counter()
    x = 0
    for i in range(n):
        x += i * i
    return time.perf_counter() - t0


def ceiling(jobs: int, n: int = 4_000_000) -> float:
    """Speed-up of ``jobs`` processes over one on pure CPU work, on this machine now."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    t0 = time.perf_counter()
    for _ in range(jobs):
        spin(n)
    serial = time.perf_counter() - t0
    with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        list(pool.map(spin, [1000] * jobs))  # processes up
        t0 = time.perf_counter()
        list(pool.map(spin, [n] * jobs))
        parallel = time.perf_counter() - t0
    return serial / parallel


def check(result: BatchResult, masses: np.ndarray) -> str:
    """Worst relative m_a error over the batch, and the failures."""
    got = np.array([row.parameters.get("m_a", {}).get("value") or np.nan for row in result.rows])
    worst = np.nanmax(np.abs(got / masses - 1)) * 100
    return f"{result.n_ok} ok, {result.n_failed} failed, worst m_a error {worst:.2f} %"


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--logs", type=int, default=12)
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    from balancer_id.identify.api import fit  # imports and compilation before any timing

    warm_kernel(parse_model("variable_viscosity"))
    masses = np.linspace(10.0, 20.0, args.logs)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "logs"
        folder.mkdir()
        paths = make_logs(folder, args.logs)
        fit(paths[:1])  # this process's first fit (lazy imports, kernel load)
        load = ", ".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
        print(
            f"{args.logs} logs of {len(THRUSTS)} trials; {os.cpu_count()} CPUs; "
            f"load average {load} (other work on the machine skews the speed-up)"
        )
        serial, res1 = timed(paths, Path(tmp) / "serial", 1, args.repeat)
        print(
            f"jobs=1:  {serial:6.2f} s  {args.logs / serial:5.2f} logs/s  ({check(res1, masses)})"
        )
        cold, res2 = timed(paths, Path(tmp) / "cold", args.jobs)
        print(
            f"jobs={args.jobs}:  {cold:6.2f} s  {args.logs / cold:5.2f} logs/s  "
            f"speed-up {serial / cold:.2f}x  (first pool: fork server starts; "
            f"{check(res2, masses)})"
        )
        warm, res3 = timed(paths, Path(tmp) / "warm", args.jobs, args.repeat)
        print(
            f"jobs={args.jobs}:  {warm:6.2f} s  {args.logs / warm:5.2f} logs/s  "
            f"speed-up {serial / warm:.2f}x  (fork server running; {check(res3, masses)})"
        )
        one = whole_process(folder, Path(tmp) / "proc1", 1)
        many = whole_process(folder, Path(tmp) / "procN", args.jobs)
        print(
            f"fresh process: jobs=1 {one:.2f} s, jobs={args.jobs} {many:.2f} s, "
            f"speed-up {one / many:.2f}x"
        )
        print(f"ceiling: {args.jobs} processes on pure CPU work: {ceiling(args.jobs):.2f}x")
        fits = [row.seconds for row in res1.rows if row.seconds is not None]
        print(f"one fit in this process: median {np.median(fits):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
