"""The paper's per-trial first-order fit (variable projection) against truth and a
general least-squares solver."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from balancer_id.identify.classic import T_BOUNDS, fit_first_order


def _step(t: np.ndarray, a_zc: float, T: float) -> np.ndarray:
    return a_zc * -np.expm1(-t / T)


def _stderr(t: np.ndarray, a_zc: float, T: float, sigma: float) -> np.ndarray:
    """Asymptotic standard errors of (a_zc, T) for white noise ``sigma`` (Cramér-Rao)."""
    e = np.exp(-t / T)
    jac = np.column_stack([1 - e, -a_zc * t / T**2 * e])
    return sigma * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))


@pytest.mark.parametrize(
    ("rate", "a_zc", "T", "sigma"),
    [
        (200.0, 0.33, 0.33, 0.03),  # the PASCO sensor, a typical step
        (20.0, -0.5, 0.6, 0.05),  # a slow SPARKvue log, a step down
        (100.0, 0.15, 0.08, 0.02),  # a fast drive
        (500.0, 1.2, 1.5, 0.2),  # slow drive, noisy, still within the 2 s window
    ],
)
def test_recovers_the_step_within_the_noise(rate, a_zc, T, sigma):
    rng = np.random.default_rng(int(rate))
    t = np.arange(int(2.0 * rate) + 1) / rate
    se = _stderr(t, a_zc, T, sigma)
    misses = []
    for _ in range(20):
        got = fit_first_order(t, _step(t, a_zc, T) + rng.normal(0.0, sigma, t.size))
        misses.append((np.array(got) - (a_zc, T)) / se)
    # each estimate within 4.5 standard errors (20 draws: a miss has p < 1e-4 each)
    assert np.max(np.abs(misses)) < 4.5
    # and the spread is the Cramér-Rao one (no bias, no lost efficiency), within sampling
    assert np.std(np.array(misses), axis=0) == pytest.approx([1.0, 1.0], abs=0.5)


def test_matches_a_general_solver():
    """Never a worse fit than least_squares from the old start; the same answer where the
    solver converges (agreement to 1e-4, well inside the noise's 1e-2)."""
    rng = np.random.default_rng(7)
    for _ in range(40):
        rate = rng.choice([20.0, 50.0, 200.0])
        t = np.arange(int(2.0 * rate) + 1) / rate
        a = _step(t, rng.uniform(-1, 1), 10 ** rng.uniform(-1.3, 0.0))
        a = a + rng.normal(0.0, 0.02, t.size)
        ref = least_squares(
            lambda x, t=t, a=a: _step(t, x[0], x[1]) - a,
            x0=[np.mean(a[t > 1.2]), 0.3],
            bounds=([-np.inf, T_BOUNDS[0]], [np.inf, T_BOUNDS[1]]),
            xtol=1e-12,
            ftol=1e-12,
        )
        got = fit_first_order(t, a)
        cost = 0.5 * np.sum((_step(t, *got) - a) ** 2)
        assert cost <= ref.cost * (1 + 1e-9)
        assert got == pytest.approx(tuple(ref.x), rel=1e-4)


def test_bounds_and_degenerate_windows():
    t = np.arange(401) / 200.0
    a_zc, T = fit_first_order(t, _step(t, 0.4, 0.001))  # faster than the lower bound
    assert T == pytest.approx(T_BOUNDS[0], rel=1e-6)
    assert a_zc == pytest.approx(0.4, rel=0.01)
    a_zc, T = fit_first_order(t, 0.05 * t)  # a ramp: the slowest lag allowed
    assert T == pytest.approx(T_BOUNDS[1], rel=1e-6)
    a_zc, T = fit_first_order(t, np.zeros_like(t))  # no motion
    assert a_zc == 0.0
    assert T_BOUNDS[0] <= T <= T_BOUNDS[1]
