"""The numpy Welch spectrum and peak prominence against scipy.signal (ground truth)."""

import numpy as np
import pytest
from scipy import signal

from balancer_id.diagnostics.spectra import prominences, prominent_peaks, welch_psd


@pytest.mark.parametrize(("n", "nperseg"), [(1000, 256), (1001, 255), (300, 128), (256, 256)])
def test_welch_matches_scipy(n: int, nperseg: int) -> None:
    rng = np.random.default_rng(3)
    t = np.arange(n) / 200.0
    x = 0.3 * np.sin(2 * np.pi * 11.0 * t) + 0.05 * t + rng.normal(0, 0.1, n)
    f_ref, p_ref = signal.welch(x, fs=200.0, nperseg=nperseg, detrend="linear")
    f, p = welch_psd(x, 200.0, nperseg)
    np.testing.assert_allclose(f, f_ref)
    np.testing.assert_allclose(p, p_ref, rtol=1e-10, atol=1e-15)
    assert abs(f[np.argmax(p)] - 11.0) < 200.0 / nperseg  # the tone is the peak


def test_prominent_peaks_match_scipy() -> None:
    rng = np.random.default_rng(5)
    for _ in range(20):
        x = np.cumsum(rng.normal(size=129)) ** 2 + rng.random(129)
        height, prom = float(np.median(x)), float(np.std(x)) / 2
        ref, props = signal.find_peaks(x, height=height, prominence=prom)
        np.testing.assert_array_equal(prominent_peaks(x, height, prom), ref)
        np.testing.assert_allclose(prominences(x, ref), props["prominences"])
