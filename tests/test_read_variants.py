"""Every class of export variant is read right or refused in one true line (issue 32).

A few seeded variants of each class of :mod:`simlib.export_variants` (the known layouts
crossed with separators, languages, units, time units, no header, renamed/reordered/extra
channels, gravity in or out, event-timed channels, values at no scale, clipping, repeated
values); ``benchmarks/bench_layouts.py`` draws many more, with fresh seeds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from simlib.export_variants import CLASSES, judge

PER_CLASS = 3


@pytest.mark.parametrize("cls", sorted(CLASSES))
def test_variants_are_read_right_or_refused_naming_the_cause(cls: str, tmp_path: Path) -> None:
    rng = np.random.default_rng(sorted(CLASSES).index(cls) + 32)
    for i in range(PER_CLASS):
        variant = CLASSES[cls](rng)
        outcome, detail = judge(variant, tmp_path / str(i))
        wanted = "right" if variant.expect == "read" else "clear"
        assert outcome == wanted, f"{variant.name}: {detail}"


def test_the_judge_catches_a_misread(tmp_path: Path) -> None:
    """A variant whose truth is altered (gravity flag, values) is judged misread."""
    variant = CLASSES["gravity in/out"](np.random.default_rng(3))
    variant.truth.gravity = not variant.truth.gravity
    outcome, detail = judge(variant, tmp_path)
    assert outcome == "misread" and "includes gravity" in detail
