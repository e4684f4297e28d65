"""The fault suite's CI part (benchmarks/faults.py --quick): each case as a test.

The whole suite (bad files x every command, option values, output safety, hostile and
special input) runs with ``python benchmarks/faults.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import faults

QUICK = [c for c in faults.cases() if c.quick]


@pytest.mark.parametrize("case", QUICK, ids=[f"{c.kind}: {c.name}" for c in QUICK])
def test_fault_case_behaves_as_promised(case, tmp_path):
    ok, why = faults.run_case(case, tmp_path)
    assert ok, why
