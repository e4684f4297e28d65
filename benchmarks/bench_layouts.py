"""Read random export variants of every class and count the outcomes (issue 32).

Run with ``python benchmarks/bench_layouts.py [--n N] [--seed S] [--verbose]``. Each
class of ``tests/simlib/export_variants.py`` draws ``N`` variants (a known layout crossed
with separators, decimal commas, header languages, units, time units, no header,
renamed/reordered/extra channels, gravity in or out, event-timed channels, values at no
scale, clipping, repeated values); each is written, read as a user would, and judged
right / clear refusal / unhelpful / misread. Prints one row per class, the totals, the
seed (``--seed`` repeats a run) and the slowest read. Targets: 0 misread, 0 unhelpful.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from simlib.export_variants import CLASSES, OUTCOMES, judge  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    """Judge the variants and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20, help="variants per class")
    parser.add_argument("--seed", type=int, default=None, help="repeat a run")
    parser.add_argument("--verbose", action="store_true", help="one line per variant")
    args = parser.parse_args(argv)
    seed = args.seed if args.seed is not None else int(np.random.SeedSequence().entropy % 2**32)
    print(f"seed {seed} ({args.n} variants per class)")
    rng = np.random.default_rng(seed)
    totals = dict.fromkeys(OUTCOMES, 0)
    slowest = (0.0, "")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, (cls, draw) in enumerate(CLASSES.items()):
            counts = dict.fromkeys(OUTCOMES, 0)
            for i in range(args.n):
                variant = draw(rng)
                start = time.perf_counter()
                outcome, detail = judge(variant, Path(tmp) / f"{k}_{i}")
                elapsed = time.perf_counter() - start
                slowest = max(slowest, (elapsed, f"{cls}: {variant.name}"))
                counts[outcome] += 1
                if args.verbose or outcome in ("unhelpful", "misread"):
                    print(f"  {outcome:9s} {cls}: {variant.name}: {detail[:300]}")
            rows.append((cls, counts))
            for key in OUTCOMES:
                totals[key] += counts[key]
    width = max(len(c) for c, _ in rows)
    print(f"{'class':{width}s}  right  clear  unhelpful  misread")
    for cls, c in [*rows, ("total", totals)]:
        print(
            f"{cls:{width}s}  {c['right']:5d}  {c['clear']:5d}  {c['unhelpful']:9d}  "
            f"{c['misread']:7d}"
        )
    print(f"slowest read: {slowest[0]:.2f} s ({slowest[1]})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
