"""The compiled first-order lag against its analytic step response."""

from __future__ import annotations

import numpy as np

from balancer_id.simulation.filters import first_order_lag


def test_first_order_lag_of_a_step_is_the_sampled_exponential():
    dt, lag = 0.005, 0.3
    alpha = np.exp(-dt / lag)
    y = first_order_lag(np.ones(400), alpha)
    k = np.arange(400)
    # y[k] = 1 - alpha**k: the step response of T dy/dt = u - y sampled at t = k dt
    np.testing.assert_allclose(y, 1.0 - np.exp(-k * dt / lag), atol=1e-12)
