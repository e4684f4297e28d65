"""Parameters in, Parameters out: a fit as lmfit.Parameters and back (issue 20.4)."""

from __future__ import annotations

import lmfit
import pytest
from conftest import SAMPLE_LOGS

import balancer_id as bid
from balancer_id.errors import UsageError

LOG = SAMPLE_LOGS / "paper_balancer.csv"


@pytest.fixture(scope="module")
def fitted():
    return bid.fit(LOG, model="viscous")


def test_a_fit_gives_lmfit_parameters(fitted):
    params = fitted.params
    assert isinstance(params, lmfit.Parameters)
    assert list(params) == list(fitted.values)
    for name, est in fitted.match.parameters.items():
        assert params[name].value == est.value and params[name].stderr == est.stderr
        assert params[name].vary
    # the correlations the fit reports, without the diagonal
    assert params["m_a"].correl["T_a"] == pytest.approx(fitted.match.correlations["m_a"]["T_a"])
    assert "m_a" not in params["m_a"].correl


def test_parameters_go_back_in_as_starts_held_values_and_bounds(fitted):
    params = fitted.params
    params["T_a"].set(value=0.30, vary=False)  # a nameplate lag, held
    params["m_a"].set(min=10.0, max=15.0)  # a bound the data would cross (truth 15.1 kg)
    again = bid.fit(LOG, model="viscous", params=params)
    assert again.values["T_a"] == 0.30 and not again.match.parameters["T_a"].vary
    assert 10.0 <= again.values["m_a"] <= 15.0
    assert again.params["T_a"].vary is False


def test_parameters_of_another_model_are_refused(fitted):
    params = fitted.params
    params.add("k_h", value=1.0)
    with pytest.raises(UsageError, match="k_h is not a parameter of 'viscous'"):
        bid.fit(LOG, model="viscous", params=params)
