"""Time and peak memory of long sessions: inspect, fit and diagnose against the log's length.

A session as a shift records it: one run at 200 Hz, the thrust changed every 5 s while the
load moves (+-2.45, +-4.9, +-7.35 N in turn; the paper's balancer, ``variable_viscosity``,
noise 0.03 m/s^2 and 0.03 N, tilt 10 deg). Each command runs in a child process that reports
its own peak RSS (VmHWM; ``ru_maxrss`` would carry this parent's over ``exec``); the
numeric data is rows x 5 columns x 8 bytes.

Run by hand (the 8-hour log is ~320 MB of CSV and takes minutes to write)::

    python benchmarks/bench_scale.py                    # 0.25, 1, 4 and 8 hours
    python benchmarks/bench_scale.py --hours 0.25 1     # some lengths
    python benchmarks/bench_scale.py --diagnose 1       # diagnose up to 1 hour too

Targets (issue 21): one hour: fit <= 1 GB and <= 15 s, diagnose <= 60 s; eight hours:
inspect <= 60 s, fit <= 2 min, each peak <= 2x the numeric data + 300 MB.
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # simlib

from simlib.sessions import record, session_thrust, write_recordings

from balancer_id.model.spec import parse_model

PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
CYCLE = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)
HOLD_S = 5.0


def write_session(path: Path, hours: float, seed: int = 1) -> int:
    """Write a session of ``hours`` at 200 Hz; return its number of rows."""
    n_levels = int(hours * 3600 / HOLD_S) - 1
    levels = [CYCLE[i % len(CYCLE)] for i in range(n_levels)]
    thrust = session_thrust(levels, HOLD_S, rest_s=2.0)
    rec = record(parse_model("variable_viscosity"), PAPER, thrust, hours * 3600, seed=seed)
    write_recordings(path, [rec])
    return int(rec.time.size)


_CHILD = """
import atexit, os, runpy, sys
def hwm():
    with open("/proc/self/status") as status:
        line = next(x for x in status if x.startswith("VmHWM:"))
    with open(os.environ["BENCH_HWM_FILE"], "w") as out:
        out.write(str(int(line.split()[1]) / 1024))
atexit.register(hwm)
sys.argv = ["balancer-id", *sys.argv[1:]]
runpy.run_module("balancer_id", run_name="__main__")
"""


def run(args: list[str], hwm_file: Path) -> tuple[float, float, int]:
    """Run ``balancer-id args``; return wall time (s), its own peak RSS (MB), exit code."""
    start = time.perf_counter()
    env = {**os.environ, "BENCH_HWM_FILE": str(hwm_file)}
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
        check=False,
    )
    seconds = time.perf_counter() - start
    return seconds, float(hwm_file.read_text()), proc.returncode


def main() -> None:
    """Print the scale table and the slopes of time and memory against the length."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, nargs="+", default=[0.25, 1.0, 4.0, 8.0])
    parser.add_argument("--diagnose", type=float, default=0.0, help="diagnose up to these hours")
    parser.add_argument("--dir", type=Path, default=None, help="where to write the logs")
    parser.add_argument(
        "--keep", type=Path, default=None, help="keep the logs in this folder and reuse them"
    )
    args = parser.parse_args()
    rows: list[tuple[float, int, float, str, float, float, int]] = []
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        for hours in args.hours:
            log = (args.keep or Path(tmp)) / f"session_{hours:g}h.csv"
            if args.keep is not None and log.exists():
                n = sum(1 for _ in log.open()) - 1  # the header line
            else:
                if args.keep is not None:
                    args.keep.mkdir(parents=True, exist_ok=True)
                n = write_session(log, hours)
            data_mb = n * 5 * 8 / 1e6
            commands = {"inspect": ["inspect"], "fit": ["fit", "--no-cache"]}
            if hours <= args.diagnose:
                commands["diagnose"] = ["diagnose"]
            for name, cmd in commands.items():
                seconds, peak, code = run([*cmd, str(log)], Path(tmp) / "hwm")
                rows.append((hours, n, data_mb, name, seconds, peak, code))
                print(
                    f"{hours:6.2f} h {n:>9,} rows ({data_mb:7.1f} MB numeric) {name:8s} "
                    f"{seconds:7.1f} s  peak {peak:7.0f} MB  exit {code}",
                    flush=True,
                )
            if args.keep is None:
                log.unlink()
    print("\n| hours | rows | numeric MB | command | seconds | peak MB | peak / budget |")
    print("|---:|---:|---:|---|---:|---:|---:|")
    for hours, n, data_mb, name, seconds, peak, code in rows:
        budget = 2 * data_mb + 300
        flag = "" if code == 0 else f" (exit {code})"
        print(
            f"| {hours:g} | {n:,} | {data_mb:.1f} | {name}{flag} | {seconds:.1f} | {peak:.0f} "
            f"| {peak / budget:.2f} |"
        )
    for name in ("inspect", "fit", "diagnose"):
        pts = [(r[1], r[4], r[5]) for r in rows if r[3] == name]
        if len(pts) >= 2:
            n_rows, secs, peaks = (np.array(c, dtype=float) for c in zip(*pts, strict=True))
            t_slope = np.polyfit(n_rows / 1e6, secs, 1)[0]
            m_slope = np.polyfit(n_rows / 1e6, peaks, 1)[0]
            print(f"{name}: {t_slope:.1f} s and {m_slope:.0f} MB per million rows")


if __name__ == "__main__":
    main()
