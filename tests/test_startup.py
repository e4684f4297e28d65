"""Start-up: a command imports only what it uses, with the same results."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from balancer_id.segment.robust import find_peaks, level

SAMPLE_LOGS = Path(__file__).resolve().parents[1] / "sample_logs"


def test_find_peaks_is_scipys():
    from scipy.signal import find_peaks as scipy_find_peaks

    rng = np.random.default_rng(7)
    for k in range(400):
        n = int(rng.integers(0, 400))
        x = rng.normal(size=n)
        x = np.round(x.cumsum() if k % 2 else x, int(rng.integers(0, 3)))  # plateaus, ties
        height, distance = float(rng.normal()), int(rng.integers(1, 40))
        want = scipy_find_peaks(x, height=height, distance=distance)[0]
        assert np.array_equal(find_peaks(x, height, distance), want), k


@pytest.mark.parametrize("n", [1, 2, 4, 5, 9, 10, 11, 1001])
def test_level_is_the_20_percent_trimmed_mean(n):
    from scipy.stats import trim_mean

    x = np.random.default_rng(n).standard_cauchy(n)
    assert level(x) == pytest.approx(trim_mean(x, 0.2), rel=1e-12, abs=1e-15)


def test_fitting_imports_neither_scipy_stats_nor_matplotlib_nor_lmfit():
    code = (
        "import sys\n"
        "import balancer_id.identify.api, balancer_id.segment, balancer_id.identify.matching\n"
        "bad = [m for m in ('scipy.stats', 'scipy.signal', 'matplotlib', 'lmfit') "
        "if m in sys.modules]\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_reading_and_segmenting_a_200_hz_log_imports_neither_scipy_stats_nor_plots():
    code = (
        "import sys\n"
        "from balancer_id.identify.api import trial_data\n"
        "from balancer_id.trials import load_trials\n"
        f"trials = trial_data(load_trials({str(SAMPLE_LOGS / 'paper_balancer.csv')!r}))\n"
        "assert trials\n"
        "bad = [m for m in ('scipy.stats', 'scipy.signal', 'matplotlib', 'lmfit') "
        "if m in sys.modules]\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
