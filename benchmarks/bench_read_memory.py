"""Peak memory of reading a big log, against the size of its numeric data (issue 13).

Run by hand (it writes a 1.5 GB file and needs ~4 GB of free memory)::

    python benchmarks/bench_read_memory.py            # 1.5 GB in a temporary folder
    python benchmarks/bench_read_memory.py 0.3        # another size, in GB
    python benchmarks/bench_read_memory.py 1.5 /big   # write the log in /big

The log is a PASCO Capstone CSV (time, force, three accelerations at 1 kHz, one run),
written in chunks. ``read_log`` then runs in a child process, whose peak RSS is compared
with the numeric data (rows x 5 columns x 8 bytes) and with the file's size. The target
is a peak of at most ~2x the numeric data.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

RATE_HZ = 1000.0
CHUNK_ROWS = 1_000_000
HEADER = (
    "Time (s) Run #1,Force (N) Run #1,Acceleration x (m/s²) Run #1,"
    "Acceleration y (m/s²) Run #1,Acceleration z (m/s²) Run #1\n"
)

_CHILD = """
import sys, time
sys.path.insert(0, sys.argv[2])
def hwm():  # VmHWM: this process's peak RSS (ru_maxrss would carry the parent's over exec)
    with open("/proc/self/status") as status:
        line = next(x for x in status if x.startswith("VmHWM:"))
    return int(line.split()[1]) / 1024
import pandas  # noqa: F401 - the parser's library counts in the base, not in the reading
from balancer_id.read import read_log
base = hwm()
start = time.perf_counter()
log = read_log(sys.argv[1])
seconds = time.perf_counter() - start
print(log.n_samples, seconds, base, hwm(), len(log.warnings))
"""


def write_log(path: Path, size_gb: float) -> int:
    """Write a Capstone CSV of about ``size_gb`` GB; return its number of rows.

    One block of force and acceleration cells is drawn and reused under an ever
    increasing time column (writing fresh random text for 1.5 GB takes many minutes).
    """
    rng = np.random.default_rng(0)
    t = np.arange(CHUNK_ROWS) / RATE_HZ
    force = 2.45 * (np.sin(t / 7.0) > 0) + rng.normal(0, 0.03, CHUNK_ROWS)
    accel = rng.normal([0.1, -0.2, 9.8], 0.05, (CHUNK_ROWS, 3))
    rest = [
        f",{f:.4f},{x:.4f},{y:.4f},{z:.4f}\n" for f, x, y, z in zip(force, *accel.T, strict=True)
    ]
    rows = 0
    with path.open("w", encoding="utf-8", newline="\n") as out:
        out.write(HEADER)
        while out.tell() < size_gb * 1e9:
            out.write("".join(f"{(rows + k) / RATE_HZ:.3f}{cells}" for k, cells in enumerate(rest)))
            rows += CHUNK_ROWS
    return rows


def main() -> int:
    """Write the log, read it in a child process, print time and peak memory."""
    size_gb = float(sys.argv[1]) if len(sys.argv) > 1 else 1.5
    folder = Path(sys.argv[2]) if len(sys.argv) > 2 else None
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        path = Path(tmp) / "big_capstone.csv"
        start = time.perf_counter()
        rows = write_log(path, size_gb)
        size = path.stat().st_size
        print(f"wrote {rows} rows, {size / 1e9:.2f} GB in {time.perf_counter() - start:.0f} s")
        repo = str(Path(__file__).resolve().parents[1])
        out = subprocess.run(
            [sys.executable, "-c", _CHILD, str(path), repo], capture_output=True, text=True
        )
        if out.returncode:
            print(out.stderr.strip().splitlines()[-1])
            return 1
        n, seconds, base, peak = (float(x) for x in out.stdout.split()[:4])
    numeric_mb = n * 5 * 8 / 1e6
    used = peak - base
    print(
        f"read_log: {int(n)} samples in {seconds:.1f} s; peak RSS {peak:.0f} MB "
        f"({used:.0f} MB above the {base:.0f} MB of the interpreter and imports); numeric data "
        f"{numeric_mb:.0f} MB; file {size / 1e6:.0f} MB; peak/numeric {used / numeric_mb:.2f} "
        f"(target <= ~2)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
