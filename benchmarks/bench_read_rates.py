"""Read and segment logs of 14 s at 20 Hz to 10 kHz: time linear in the number of samples.

Run with ``python benchmarks/bench_read_rates.py``. For each rate, generic CSVs are
written to a temporary folder (``time,force`` and ``time,ax,ay,az``: two thrust steps
from rest, each caught by hand, sensor noise and a tilted sensor), then

* in this process: ``read`` + ``segment`` of the pipeline, best of three (seconds);
* for 10 kHz: ``balancer-id inspect LOG --thrust 4.9,-4.9`` as a child process, its wall
  time and peak RSS (the whole command: interpreter start and imports included).

Targets (issue 8): 10 kHz x 14 s through ``inspect`` in < 2 s and < 500 MB, and the
in-process time per sample flat over the rates. On a shared machine the wall time of the
command grows with the load; its CPU time (user + system) is printed too.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from balancer_id.pipeline import ReadOptions, read, segment

RATES_HZ = (20.0, 200.0, 1000.0, 5000.0, 10000.0)
DURATION_S = 14.0
REPEATS = 3
TARGET_S, TARGET_MB = 2.0, 500.0
THRUSTS = (4.9, -4.9)

_CHILD = """
import resource, subprocess, sys, time
start = time.perf_counter()
done = subprocess.run(sys.argv[1:], capture_output=True)
wall = time.perf_counter() - start
use = resource.getrusage(resource.RUSAGE_CHILDREN)
print(wall, use.ru_maxrss / 1024, done.returncode, use.ru_utime + use.ru_stime)
"""


def motion(rate: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return time, force (N) and with-g acceleration (n, 3) of two caught steps."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(DURATION_S * rate)) / rate
    m_a, t_a = 15.1, 0.33
    force = np.zeros(t.size)
    a_up = np.zeros(t.size)
    for t0, f in zip((2.0, 9.0), THRUSTS, strict=True):
        on = (t >= t0) & (t < t0 + 4.0)
        force[on] += f
        a_up[on] += f / m_a * -np.expm1(-(t[on] - t0) / t_a)
        catch = (t >= t0 + 4.0) & (t < t0 + 4.4)
        a_up[catch] -= 2.0 * np.sign(f)
    tilt = np.radians(10.0)
    up = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    accel = (9.8 + a_up)[:, None] * up[None, :] + rng.normal(0.0, 0.05, (t.size, 3))
    force = force + rng.normal(0.0, 0.03, t.size)
    return t, force, accel


def write_logs(folder: Path, rate: float) -> dict[str, Path]:
    """Write the force-only and the acceleration-only CSV at ``rate``; return their paths."""
    t, force, accel = motion(rate)
    paths = {"force": folder / f"force_{rate:g}Hz.csv", "accel": folder / f"accel_{rate:g}Hz.csv"}
    np.savetxt(
        paths["force"],
        np.column_stack([t, force]),
        delimiter=",",
        fmt="%.6g",
        header="time,force",
        comments="",
    )
    np.savetxt(
        paths["accel"],
        np.column_stack([t, accel]),
        delimiter=",",
        fmt="%.6g",
        header="time,ax,ay,az",
        comments="",
    )
    return paths


def in_process(path: Path) -> tuple[float, int, int]:
    """Best-of-three seconds of read + segment, the samples and the trials found."""
    options = ReadOptions(thrusts=list(THRUSTS))
    best, n, found = np.inf, 0, 0
    for _ in range(REPEATS):
        start = time.perf_counter()
        log = read(path, options)
        trials = segment(log, options)
        best = min(best, time.perf_counter() - start)
        n, found = log.n_samples, len(trials)
    return best, n, found


def inspect_child(path: Path) -> tuple[float, float, int, float]:
    """Wall time (s), peak RSS (MB), exit code and CPU time (s) of ``inspect`` on ``path``."""
    exe = Path(sys.executable).with_name("balancer-id")
    cmd = [
        str(exe),
        "inspect",
        str(path),
        "--json",
        "--thrust",
        ",".join(f"{f:g}" for f in THRUSTS),
    ]
    out = subprocess.run([sys.executable, "-c", _CHILD, *cmd], capture_output=True, text=True)
    wall, rss, code, cpu = out.stdout.split()
    return float(wall), float(rss), int(code), float(cpu)


def main() -> int:
    """Print the table and the 10 kHz ``inspect`` figures; exit 1 when a target is missed."""
    ok = True
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for rate in RATES_HZ:
            paths = write_logs(Path(folder), rate)
            for kind, path in paths.items():
                seconds, n, found = in_process(path)
                rows.append((rate, kind, n, seconds, found))
                print(
                    f"{rate:>7g} Hz {kind:<5} {n:>7} samples  read+segment {seconds:6.3f} s  "
                    f"{1e6 * seconds / n:6.2f} us/sample  trials {found}"
                )
        for kind in ("force", "accel"):
            path = Path(folder) / f"{kind}_{RATES_HZ[-1]:g}Hz.csv"
            wall, rss, code, cpu = inspect_child(path)
            good = wall < TARGET_S and rss < TARGET_MB and code == 0
            ok &= good
            print(
                f"inspect {path.name}: {wall:.2f} s wall ({cpu:.2f} s CPU), "
                f"peak RSS {rss:.0f} MB, exit {code} "
                f"(target < {TARGET_S:g} s, < {TARGET_MB:g} MB) {'OK' if good else 'MISSED'}"
            )
    print(json.dumps({"rows": rows}))
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
