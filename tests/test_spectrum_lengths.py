"""The residual spectrum over trials of different lengths (a regression: e28aee7)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from balancer_id.diagnostics.context import DiagnosisContext


def test_a_peak_is_placed_at_its_frequency_when_a_shorter_trial_follows():
    # a long trial carries an 80 Hz line (Welch bin ~102 of 129); a shorter one after it has
    # another segment length (76 bins) and is left out of the average. Its frequencies once
    # replaced the kept spectra's, so the peak's bin fell off their end (IndexError).
    rng = np.random.default_rng(3)
    fs = 200.0
    t = np.arange(2000) / fs
    long = rng.normal(0.0, 0.01, t.size) + 0.05 * np.sin(2 * np.pi * 80.0 * t)
    short = rng.normal(0.0, 0.01, 150)
    context = SimpleNamespace(
        dt=1.0 / fs, trials=[SimpleNamespace(residual=long), SimpleNamespace(residual=short)]
    )
    found = DiagnosisContext.spectrum_peaks(context)  # type: ignore[arg-type]
    assert len(found["frequency_hz"]) == len(found["psd"]) == 129
    assert found["peaks"][0]["frequency_hz"] == pytest.approx(80.0, abs=fs / 256)
