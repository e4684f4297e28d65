"""Candidate refits in threads against one by one (issue 12, item 2).

``diagnose`` refits each candidate effect; the refits are independent and the compiled
kernels release the GIL, so they run in threads on every core. This times the candidate
phase of ``diagnose`` on the README's logs, one by one (``threads=1``) and on all cores,
in alternating runs of the same process, and checks that both rank the same suggestions
with the same numbers.

Run: ``python benchmarks/bench_diagnose_threads.py [--runs N]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import balancer_id as bid

ROOT = Path(__file__).resolve().parents[1]
LOGS = {
    "paper_balancer": ROOT / "sample_logs" / "paper_balancer.csv",
    "hose_walkthrough": ROOT / "sample_logs" / "hose_walkthrough.csv",
}


def timed(fit: bid.FitResult, threads: int | None) -> tuple[float, list[tuple[str, float]]]:
    """Wall seconds of one diagnosis and its ranking."""
    t0 = time.perf_counter()
    found = bid.diagnose(fit) if threads is None else _serial(fit)
    return time.perf_counter() - t0, [(s.effect, s.delta_bic) for s in found.suggestions]


def _serial(fit: bid.FitResult):
    from balancer_id.diagnostics.diagnosis import diagnose

    return diagnose(fit, threads=1)


def main() -> None:
    """Print the median wall time of each way and their ratio, per log."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    print(f"{os.cpu_count()} cores; medians of {args.runs} alternating runs")
    for name, path in LOGS.items():
        fit = bid.fit(str(path))
        bid.diagnose(fit)  # per-trial fits, kernels: computed once, outside the timing
        one, many = [], []
        for _ in range(args.runs):
            t1, rank1 = timed(fit, 1)
            tn, rankn = timed(fit, None)
            assert rank1 == rankn, (rank1, rankn)
            one.append(t1)
            many.append(tn)
        a, b = statistics.median(one), statistics.median(many)
        print(f"{name:18s} one by one {a:6.2f} s   threads {b:6.2f} s   speed-up {a / b:.2f}x")


if __name__ == "__main__":
    main()
