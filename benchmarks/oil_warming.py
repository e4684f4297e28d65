"""The oil-warming case of issue 33: one continuous 10-minute Capstone run, a thrust change
every 8 s, D0 falling 8 -> 4 kg/s linearly in time (the paper's balancer otherwise).

    python benchmarks/oil_warming.py oil.csv [--seed N]
    balancer-id fit oil.csv --track D0 --report oil.html

Writes the log (never over an existing file) and prints the commands that show it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from balancer_id.model import parse_model

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' simlib

from simlib.drift import alternating_levels, record_drifting
from simlib.sessions import session_thrust, write_recordings

TRUTH = {"m_a": 15.1, "T_a": 0.33, "A": 0.4}
DURATION_S = 600.0
HOLD_S = 8.0


def d0_at(t: float) -> float:
    """The true D0 (kg/s) at time ``t`` (s): 8 falling linearly to 4."""
    return 8.0 - 4.0 * t / DURATION_S


def main() -> None:
    """Write the log."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    levels = alternating_levels(int((DURATION_S - 2) / HOLD_S), rng)
    rec = record_drifting(
        parse_model("variable_viscosity"),
        lambda t: {**TRUTH, "D0": d0_at(t)},
        session_thrust(levels, HOLD_S),
        DURATION_S,
        seed=args.seed + 1,
    )
    write_recordings(args.out, [rec])
    print(f"wrote {args.out}: {len(levels)} thrust changes, D0 8 -> 4 kg/s over 10 min")
    print(f"balancer-id fit {args.out} --track D0 --report {args.out.with_suffix('.html')}")


if __name__ == "__main__":
    main()
