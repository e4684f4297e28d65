"""Read the 52 real exports of ``../shared/real_logs`` and count the outcomes.

Run with ``python benchmarks/bench_real_logs.py [--root PATH] [--code DIR] [--verbose]``;
``--code`` judges another checkout's ``balancer_id`` (e.g. ``--code /work/main`` for the
counts before a change) with this checkout's expectations. Each file is
judged by ``tests/test_real_logs_public.py``'s :func:`judge` against
``tests/golden/real_logs_public.json``: read as it is, then with the column map a user
passes when the tool asks for ``--columns``. Prints one line per file with ``--verbose``
and the counts: right / clear refusal / unhelpful refusal / misread, and the slowest read.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _code_dir() -> Path:
    """The checkout whose ``balancer_id`` is judged (``--code``, read before argparse)."""
    if "--code" in sys.argv[:-1]:
        return Path(sys.argv[sys.argv.index("--code") + 1]).resolve()
    return ROOT


sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(_code_dir()))

from test_real_logs_public import OUTCOMES, REAL_LOGS, expectations, judge  # noqa: E402


def main() -> int:
    """Judge every file and print the counts."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=REAL_LOGS, help="the real_logs folder")
    parser.add_argument("--verbose", action="store_true", help="one line per file")
    parser.add_argument("--code", type=Path, default=ROOT, help="the checkout judged")
    args = parser.parse_args()
    if not args.root.is_dir():
        print(f"no real_logs folder at {args.root}")
        return 1
    counts = dict.fromkeys(OUTCOMES, 0)
    slowest = (0.0, "")
    for name, exp in sorted(expectations().items()):
        path = args.root / name
        if not path.is_file():
            print(f"missing: {name}")
            continue
        start = time.perf_counter()
        outcome, detail = judge(path, exp)
        elapsed = time.perf_counter() - start
        slowest = max(slowest, (elapsed, name))
        counts[outcome] += 1
        if args.verbose or outcome in ("unhelpful", "misread"):
            print(f"{outcome:9s} {name}: {detail[:300]}")
    import balancer_id

    print(f"code judged: {Path(balancer_id.__file__).parent}")
    total = sum(counts.values())
    print(
        f"{total} files: right {counts['right']}, clear refusal {counts['clear']}, "
        f"unhelpful refusal {counts['unhelpful']}, misread {counts['misread']}"
    )
    print(f"slowest read: {slowest[0]:.2f} s ({slowest[1]})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
