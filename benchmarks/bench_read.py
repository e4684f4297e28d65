"""Time ``read_log`` on a one-hour 200 Hz PASCO Capstone log (720,000 rows).

Run with ``python benchmarks/bench_read.py``. The log (time, force, three accelerations)
is written to a temporary folder with :func:`balancer_id.read.write_log`; the figure
printed is the best of three reads. The target is under 2 s.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from balancer_id.read import Recording, read_log, write_log

RATE_HZ = 200.0
DURATION_S = 3600.0
REPEATS = 3
TARGET_S = 2.0


def make_recording(seed: int = 0) -> Recording:
    """Return a one-hour 200 Hz recording with noisy force and with-g acceleration."""
    rng = np.random.default_rng(seed)
    n = int(RATE_HZ * DURATION_S)
    t = np.arange(n) / RATE_HZ
    force = np.round(2.45 * (np.sin(t / 7.0) > 0) + rng.normal(0.0, 0.03, n), 2)
    accel = np.round(np.array([0.1, -0.2, 9.8]) + rng.normal(0.0, 0.2, (n, 3)), 1)
    return Recording(name="Run #1", time=t, force=force, accel=accel)


def main() -> int:
    """Write the log, time three reads, print the best."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "capstone_1h_200Hz.csv"
        write_log(path, [make_recording()], "pasco-capstone")
        size_mb = path.stat().st_size / 1e6
        times = []
        for _ in range(REPEATS):
            start = time.perf_counter()
            log = read_log(path)
            times.append(time.perf_counter() - start)
        best = min(times)
    n = log.n_samples
    verdict = "OK" if best < TARGET_S else "SLOW"
    print(
        f"read_log: {n} rows ({size_mb:.1f} MB, {log.format}) best of {REPEATS}: "
        f"{best:.3f} s (target < {TARGET_S:.0f} s) {verdict}"
    )
    return 0 if best < TARGET_S else 1


if __name__ == "__main__":
    raise SystemExit(main())
