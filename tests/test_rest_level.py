"""An accelerometer that does not read g at rest is named by the fit (issue 31.4): its
gain (or zero) with the correction, before the balancer is blamed."""

from __future__ import annotations

import re

import pandas as pd
import pytest
from conftest import SAMPLE_LOGS

from balancer_id.identify.api import fit


def test_a_hot_accelerometer_leads_the_fit_s_distrust(tmp_path) -> None:
    # two runs of the paper balancer's log with its accelerometer reading 4 % high: at
    # rest it reads 0.04 g (0.39 m/s^2) off, far beyond the noise of its mean over the rests
    gain = 1.04
    df = pd.read_csv(SAMPLE_LOGS / "paper_balancer.csv")
    df = df[[c for c in df.columns if c.endswith(("Run #1", "Run #2"))]].dropna(how="all")
    for col in [c for c in df.columns if c.startswith("Acceleration")]:
        df[col] = df[col] * gain
    path = tmp_path / "hot.csv"
    df.to_csv(path, index=False)
    result = fit(str(path))
    assert not result.trusted
    why = result.untrusted_because[0]  # the sensor leads
    m = re.search(r"a gain of (\d\.\d+)", why)
    assert m, why
    # the resting magnitude's mean over the rests: within 0.5 % of the gain applied
    # (local g and the sensor's own calibration in the sample log are within that)
    assert float(m.group(1)) == pytest.approx(gain, abs=0.005)
    assert f"divide the acceleration by {m.group(1)}" in why
    assert "fit.rest_level" in {n.code for n in result.all_notes if hasattr(n, "code")}
