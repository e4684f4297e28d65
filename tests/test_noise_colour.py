"""The sensor's own colour, against which the residual's whiteness is judged (issue 31):
read from short rests without their mean's pull, or from the residual's differences
where the trials hold too little rest (a session's one rest, a 50 Hz log)."""

from __future__ import annotations

import numpy as np
import pytest

from balancer_id.diagnostics.adequacy import _mean_acf, _unbiased
from balancer_id.diagnostics.context import difference_colour
from balancer_id.identify.metrics import correlation_time
from balancer_id.simulation.synth import ar1_noise


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.85])
def test_the_colour_from_differences_ignores_a_smooth_misfit(rho) -> None:
    # 8 trials of 600 samples: AR(1) noise plus a misfit as large as the noise, slow
    # against the samples (a drive lag's transient of 50 samples)
    rng = np.random.default_rng(7)
    t = np.arange(600.0)
    misfit = 0.02 * np.exp(-t / 50.0)
    parts = [misfit + ar1_noise(rng, 0.02, rho, (600,)) for _ in range(8)]
    # the lag-one correlation of differences of 4800 samples: standard error about 0.03
    # in r (twice that of the differences' own correlation); 3 of them
    assert difference_colour(parts) == pytest.approx(rho, abs=0.1)


def test_short_rests_read_the_noise_colour_without_their_means_pull() -> None:
    # forty rests of 50 samples (0.5 s at 100 Hz) of a strongly coloured noise: each
    # rest's mean removed pulls its autocorrelation down by about tau / 50 (a quarter)
    rng = np.random.default_rng(3)
    rho = 0.8
    rests = [ar1_noise(rng, 1.0, rho, (50,)) for _ in range(40)]
    rests = [r - r.mean() for r in rests]
    raw, _, length = _mean_acf(rests, 10, shortest=10)
    tau = correlation_time(rests, removed=1)
    fixed = _unbiased(raw, tau, length)
    truth = rho ** np.arange(1, 6)
    # 2000 samples of tau ~ 9: the mean over lags 1-5 varies by about 0.03, and tau from
    # short rests comes out a little low, so the pull is undone to within about 0.05
    assert np.mean(truth - raw[:5]) > 0.12  # the pull the colour test used to read as misfit
    assert np.mean(fixed[:5]) == pytest.approx(np.mean(truth), abs=0.1)


def test_consistency_alone_is_a_missing_effect_only_when_its_refit_stands() -> None:
    """The per-run test's claim is refitted per run on the whole data: consistency failing
    alone, with no split or drift standing, is the per-trial fits' scatter (adequate);
    with another test failing, or nothing refitted per run, it is still a failure."""
    from balancer_id.diagnostics.explanations.base import Explanation
    from balancer_id.diagnostics.verdict import _uncorroborated

    consistency = {"name": "consistency", "passed": False, "text": "D0 differs"}
    level = {"name": "level", "passed": False, "text": "above the noise"}
    split = Explanation("split", "D0 changes after run 2", 6.6, 0.01, parameters=["D0"])
    effect = Explanation("effect", "+bias", 27.9, 0.01, effects=["bias"])
    assert _uncorroborated([consistency], [effect, split])
    assert not _uncorroborated([consistency, level], [split])
    assert not _uncorroborated([consistency], [effect])  # its claim was never refitted
    assert not _uncorroborated([], [split])


def test_a_low_pass_is_tried_from_the_response_only_where_the_acceleration_lags() -> None:
    """Without the resting noise's roll-off (noise that enters after the filter), a
    low-pass is tried only where the fit's timing test finds the acceleration clearly
    late, started at the cut-off whose lag that is."""
    from types import SimpleNamespace

    from balancer_id.diagnostics.explanations.sensor_lowpass import _lag_cutoff

    def inp(lead: float, se: float) -> SimpleNamespace:
        trial = SimpleNamespace(time=np.arange(0.0, 5.0, 0.01))  # 100 Hz
        match = SimpleNamespace(metrics={"timing_lead_s": lead, "timing_lead_stderr_s": se})
        return SimpleNamespace(match=match, trials=[trial])

    # 9 ms late at 3 standard errors: the 2nd-order filter of that lag, sqrt(2)/(2 pi d)
    assert _lag_cutoff(inp(-0.009, 0.003)) == pytest.approx(np.sqrt(2) / (2 * np.pi * 0.009))
    assert _lag_cutoff(inp(-0.004, 0.003)) is None  # not clearly late
    assert _lag_cutoff(inp(+0.020, 0.003)) is None  # early: a late force channel, no filter
    assert _lag_cutoff(inp(-0.0005, 0.0001)) == pytest.approx(40.0)  # at most 0.4 fs
