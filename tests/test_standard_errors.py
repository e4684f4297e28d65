"""Standard errors that hold: the truth inside the reported intervals as often as they say.

Sixteen seeded logs of the paper balancer (six trials, a tilted sensor) are fitted with
its model, once with white acceleration noise and once with AR(1) noise of lag-one
correlation 0.8 (a sensor's low-pass or a phone's filtering: correlation time 9 samples).
The estimates' errors over their reported standard errors, pooled over the four
parameters, must have an RMS near 1. Without the widening for the residual's correlation
the coloured case gave 3.2 (95 % intervals covering the truth in 37-57 % of the logs).
With 64 errors (four per log, correlated within a log) the RMS is known to about
+-15 %; the bounds 0.7-1.6 leave that twice, and the white case sits at 1.1 (m_a's
interval is a little narrow: the segmentation's own errors are not in the Jacobian).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import PAPER, PAPER_THRUSTS
from simlib.noisy_fits import fit_noisy_logs

from balancer_id.identify.metrics import correlation_time

SEEDS = 16


def standardized_errors(rho: float) -> tuple[np.ndarray, list[float]]:
    """(estimate - truth) / stderr for every parameter of every seed, and the fits' tau."""
    z, taus = [], []
    for m in fit_noisy_logs(PAPER, PAPER_THRUSTS, rho, SEEDS):
        z.extend((m.parameters[k].value - PAPER[k]) / m.parameters[k].stderr for k in PAPER)
        taus.append(m.metrics["residual_tau"])
    return np.array(z), taus


@pytest.mark.parametrize(("rho", "tau_range"), [(0.0, (1.0, 1.5)), (0.8, (6.0, 13.0))])
def test_reported_standard_errors_match_the_spread_of_the_estimates(rho, tau_range):
    z, taus = standardized_errors(rho)
    rms = float(np.sqrt(np.mean(z**2)))
    assert 0.7 < rms < 1.6, rms
    # the residual's correlation time is the noise's, (1 + r) / (1 - r) = 9 for r = 0.8
    assert tau_range[0] <= np.median(taus) <= tau_range[1]


def test_correlation_time_of_exponentially_correlated_noise():
    """AR(1) noise of lag-one correlation r has tau = (1 + r) / (1 - r) (analytic)."""
    rng = np.random.default_rng(5)
    for r in (0.0, 0.5, 0.8):
        e = rng.normal(size=(20, 2000))
        x = np.zeros_like(e)
        x[:, 0] = e[:, 0] / np.sqrt(1 - r * r)
        for i in range(1, e.shape[1]):
            x[:, i] = r * x[:, i - 1] + e[:, i]
        tau = correlation_time(list(x), removed=0)
        assert tau == pytest.approx((1 + r) / (1 - r), rel=0.1)
