"""A gain and a zero offset fit alike from one orientation (issue 31): the gain's fit
starts from the offset's, rescaled, so that it is as good and the sensor is named."""

from __future__ import annotations

import numpy as np
import pytest

from balancer_id.diagnostics.explanations.sensor_gain import _offset_as_gain


def test_an_offset_fit_is_the_same_output_as_a_gain_with_mass_and_viscosity_scaled() -> None:
    g = 9.8
    b = 0.245  # an accelerometer 2.5 % hot reads 0.245 m/s^2 at rest
    k, values = _offset_as_gain({"m_a": 10.0, "T_a": 0.3, "D0": 20.0, "A": 0.1, "b": b}, g)
    assert k == pytest.approx(1.025)
    assert values == pytest.approx({"m_a": 10.25, "T_a": 0.3, "D0": 20.5, "A": 0.1})
    # a first-order viscous balancer's response a(t) to a step: the offset's output
    # a + b equals the gain's k a' + (k - 1) g, a' from the scaled mass and viscosity
    t = np.linspace(0, 3, 50)
    u = 5.0

    def accel(m: float, d: float) -> np.ndarray:
        return u / m * np.exp(-d / m * t)

    assert np.allclose(accel(10.0, 20.0) + b, k * accel(values["m_a"], values["D0"]) + (k - 1) * g)
    assert _offset_as_gain({"m_a": 1.0}, g) is None  # no offset fitted
    assert _offset_as_gain(None, g) is None
