"""Batch throughput: ``balancer-id batch`` as a user runs it, logs per second and memory.

N simulated 6-trial logs (thrusts ±2.45, ±4.9, ±7.35 N, 6 s after each step, noise
0.03 m/s^2, tilts 5-24 degrees, m_a spread over 10-20 kg) are identified by a fresh
``python -m balancer_id batch DIR --out OUT --jobs J --overwrite`` process, for N = 21
and N = 84 (``--logs``), each ``--repeat`` times; the figures are medians.

For each run, the process tree (the command, its fork server, the workers) is sampled
every 20 ms from ``/proc`` (Linux): peak memory is the largest ``VmHWM`` (peak resident
set) of any one process, and CPU is the sum of each process's user+system time. Printed:

* ``wall``: the whole command, start-up included, and ``logs/s`` = N / wall;
* ``steady``: logs per second between the first result and the last (start-up excluded);
* ``cpu/log``: CPU seconds of the whole tree per log, and ``cpu-bound``: the rate J
  cores would give if the tree had them to itself (N / (CPU / J)); on a machine shared
  with other work the wall figures fall, this one much less; the CPU of the command's
  own process (start-up, writing results) is given apart;
* ``peak RSS``: the largest process; flat in N means a batch's memory does not grow
  with the number of logs.

The load average is printed before each figure, as other work on the machine skews
the wall figures. The kernel is compiled (into the disk cache) before any timing.

Run: ``python benchmarks/bench_batch.py [--logs 21 84] [--jobs 2] [--repeat 3]``. To
compare with another version under the same load, run it again with that version first
on the path: ``git archive REV balancer_id | tar -x -C /tmp/old`` then
``PYTHONPATH=/tmp/old python benchmarks/bench_batch.py`` (the batch command and its
workers then run the old code).

Target (issue 12): >= 20 logs/s at 2 jobs with peak memory flat in N. A cold command
cannot reach it at N = 21: its start (the CLI's imports, then the fork server's imports
of numpy, scipy.optimize, scipy.ndimage, pandas and numba and its kernel load, about
1.7 s of CPU before the first worker exists) alone is longer than 21 / 20 s.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from balancer_id.model import parse_model
from balancer_id.simulation.synth import SensorSettings, write_synthetic_log

TRUTH = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
THRUSTS = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)
_TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


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


def _children() -> dict[int, list[int]]:
    """Parent pid -> child pids, of every process now."""
    tree: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        tree.setdefault(int(fields[1]), []).append(int(entry))
    return tree


def _sample(pid: int) -> tuple[float, int] | None:
    """(CPU seconds, peak RSS in kB) of one process, or None when it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
        with open(f"/proc/{pid}/status") as fh:
            hwm = next((int(line.split()[1]) for line in fh if line.startswith("VmHWM")), 0)
    except (OSError, StopIteration, ValueError):
        return None
    return (int(fields[11]) + int(fields[12])) / _TICK, hwm


@dataclass
class Run:
    """One batch command's figures."""

    wall: float
    steady: float
    cpu: float
    parent_cpu: float
    peak_kb: int
    n_ok: int


def run_batch_command(folder: Path, out: Path, jobs: int) -> Run:
    """Run the batch command on ``folder``; sample its process tree while it runs."""
    cmd = [sys.executable, "-m", "balancer_id", "batch", str(folder), "--out", str(out)]
    cmd += ["--jobs", str(jobs), "--overwrite"]
    seen: dict[int, tuple[float, int]] = {}
    stamps: list[float] = []
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)

    def read_stderr() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            if line.startswith("["):  # "[k/N] log: ok ..." as each log settles
                stamps.append(time.perf_counter())

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    while proc.poll() is None:
        tree = _children()
        todo = [proc.pid]
        while todo:
            pid = todo.pop()
            todo += tree.get(pid, [])
            got = _sample(pid)
            if got is not None:
                seen[pid] = got
        time.sleep(0.02)
    wall = time.perf_counter() - t0
    reader.join(timeout=5)
    n = len(stamps)
    steady = (n - 1) / (stamps[-1] - stamps[0]) if n > 1 and stamps[-1] > stamps[0] else 0.0
    cpu = sum(c for c, _ in seen.values())
    peak = max((m for _, m in seen.values()), default=0)
    ok = sum(1 for _ in out.glob("*.json"))
    parent = seen.get(proc.pid, (0.0, 0))[0]
    return Run(wall, steady, cpu, parent, peak, ok)


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


def _load() -> str:
    return ", ".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--logs", type=int, nargs="+", default=[21, 84])
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    if not Path("/proc/self/stat").exists():
        print("this benchmark samples /proc: run it on Linux")
        return 1
    from balancer_id.batch import warm_kernel

    warm_kernel(parse_model("variable_viscosity"))  # the disk cache holds the kernel
    print(
        f"balancer-id batch, {len(THRUSTS)}-trial logs, --jobs {args.jobs}; "
        f"{os.cpu_count()} CPUs; medians of {args.repeat} runs"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.logs:
            folder = Path(tmp) / f"logs{n}"
            folder.mkdir()
            make_logs(folder, n)
            load = _load()
            runs = [
                run_batch_command(folder, Path(tmp) / f"out{n}_{k}", args.jobs)
                for k in range(args.repeat)
            ]
            wall = statistics.median(r.wall for r in runs)
            steady = statistics.median(r.steady for r in runs)
            cpu = statistics.median(r.cpu for r in runs) / n
            parent = statistics.median(r.parent_cpu for r in runs)
            peak = max(r.peak_kb for r in runs) / 1024
            print(
                f"N={n:3d}: wall {wall:5.2f} s = {n / wall:5.1f} logs/s | steady "
                f"{steady:5.1f} logs/s | cpu/log {cpu * 1e3:4.0f} ms, cpu-bound "
                f"{args.jobs / cpu:5.1f} logs/s (command's own process {parent:.1f} s) | "
                f"peak RSS {peak:4.0f} MB (largest "
                f"process) | {min(r.n_ok for r in runs)}/{n} results | load {load}"
            )
    print(f"ceiling: {args.jobs} processes on pure CPU work: {ceiling(args.jobs):.2f}x (now)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
