"""Whole commands against the script a user would otherwise write (issue 12's targets).

Each command runs as a fresh process, in turn with the solve_ivp-inside-lmfit script
(``benchmarks/baseline_solve_ivp.py``) on the same log, so that a ratio holds when the
shared machine's speed drifts: A B A B ... after one warm-up of each, the ratio taken
pair by pair, the median quoted. Wall time and peak memory come from the operating
system's accounting of each finished child (``wait4``), like ``/usr/bin/time -v``.

Targets: ``diagnose`` >= 5x faster than the script's single fit; full ``report`` >= 3x;
``improve`` on the README's hose example <= 2x the time of ``diagnose`` on it.
The batch's target (>= 20 logs/s on 2 cores, memory flat in the number of logs) is
measured by ``bench_batch.py``.

Run: ``python benchmarks/bench_commands.py [--runs N] [--only diagnose,report,improve]``
(the kernels must be compiled once before: run any ``balancer-id diagnose`` first).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOG = ROOT / "sample_logs" / "paper_balancer.csv"
HOSE = ROOT / "sample_logs" / "hose_walkthrough.csv"
EFFECT = ROOT / "examples" / "effects" / "hose_spring.py"
PY = sys.executable


def run(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak resident memory (MiB) of one finished process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    return wall, usage.ru_maxrss / 1024.0


def pair(a: list[str], b: list[str], runs: int) -> dict[str, float]:
    """A and B in turn after one warm-up each; medians and the median ratio A/B."""
    run(a)
    run(b)
    wa, wb, ma = [], [], []
    for _ in range(runs):
        t, m = run(a)
        wa.append(t)
        ma.append(m)
        wb.append(run(b)[0])
    return {
        "a_s": statistics.median(wa),
        "b_s": statistics.median(wb),
        "ratio": statistics.median(x / y for x, y in zip(wa, wb, strict=True)),
        "a_mib": statistics.median(ma),
    }


def main() -> None:
    """Print each target's figure: absolute medians and the ratio in the same run."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--only", default="diagnose,report,improve")
    args = parser.parse_args()
    cli = [PY, "-m", "balancer_id"]
    script = [PY, str(ROOT / "benchmarks" / "baseline_solve_ivp.py"), str(LOG)]
    wanted = args.only.split(",")
    with tempfile.TemporaryDirectory() as tmp:
        report = str(Path(tmp) / "r.html")
        cases = {
            "diagnose": (
                [*cli, "diagnose", str(LOG)],
                script,
                "script / diagnose >= 5",
            ),
            "report": (
                [*cli, "report", str(LOG), "--out", report, "--overwrite"],
                script,
                "script / report >= 3",
            ),
            "improve": (
                [*cli, "improve", str(HOSE), "--effects-file", str(EFFECT)],
                [*cli, "diagnose", str(HOSE), "--effects-file", str(EFFECT)],
                "improve / diagnose <= 2",
            ),
        }
        for name in wanted:
            a, b, target = cases[name]
            got = pair(a, b, args.runs)
            shown = 1.0 / got["ratio"] if name != "improve" else got["ratio"]
            print(
                f"{name:9s} {got['a_s']:6.2f} s (peak {got['a_mib']:.0f} MiB)  "
                f"vs {got['b_s']:6.2f} s  ->  {shown:.2f} ({target})",
                flush=True,
            )


if __name__ == "__main__":
    main()
