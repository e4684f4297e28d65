"""Notes read as numbers a person can act on: no 1e302 "standard errors", and a refusal
that names the sensor's calibration when the rest says it is off."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from balancer_id.identify import matching


def _outcome(x, chisqr):
    return matching._Outcome(
        x=np.asarray(x, float),
        residual=np.full(100, np.sqrt(chisqr / 100)),
        jtj=np.eye(len(x)),
        success=True,
        message="",
        nfev=1,
    )


def _result(stderr):
    params = {"m_a": SimpleNamespace(stderr=stderr), "D0": SimpleNamespace(stderr=stderr)}
    return SimpleNamespace(y=np.zeros(100), parameters=params, metrics={"residual_tau": 1.0})


def test_two_optima_with_an_undefined_standard_error_say_so_not_a_huge_number():
    best, other = _outcome([10.0, 40.0], 1.0), _outcome([10.0, 400.0], 1.001)
    note = matching._starts_disagree(_result(0.0), best, [best, other], ["m_a", "D0"])
    assert note is not None and note.code == "fit.starts_disagree"
    assert "D0 40 and 400, its standard error undefined" in note.text
    assert "e+" not in note.text and len(note.text) < 400


def test_two_optima_with_a_standard_error_give_how_many_apart():
    best, other = _outcome([10.0, 40.0], 1.0), _outcome([10.0, 400.0], 1.001)
    note = matching._starts_disagree(_result(2.0), best, [best, other], ["m_a", "D0"])
    assert "D0 40 and 400, 180 standard errors apart" in note.text


def _refusal(monkeypatch, offset):
    from balancer_id.errors import IdentificationError
    from balancer_id.identify import api
    from balancer_id.model import parse_model

    mass = SimpleNamespace(vary=True, at_bound="max", value=1e5)
    ended = SimpleNamespace(success=True, parameters={"m_a": mass})
    monkeypatch.setattr(api, "match_trials", lambda *a, **k: ended)
    monkeypatch.setattr(api, "_on_a_bound", lambda *a: False)
    monkeypatch.setattr(api, "resting_offset", lambda match, ts: offset)
    model = parse_model("variable_viscosity")
    try:
        api._settled_match(model, [], {}, None, None, 0, 10, None, SimpleNamespace())
    except IdentificationError as exc:
        return str(exc)
    raise AssertionError("a mass on its bound was not refused")


def test_a_refusal_names_the_accelerometers_calibration_when_the_rest_is_off(monkeypatch):
    text = _refusal(monkeypatch, (0.449, 0.002, 9.8))
    assert text.startswith("nothing identified: the accelerometer reads 10.249 m/s^2 at rest")
    assert "a gain of 1.046" in text and "divide the acceleration by 1.046" in text
    assert "--model variable_viscosity+bias" in text and "maximum bound" in text
    assert _refusal(monkeypatch, None).startswith("nothing identified: m_a ended at its maximum")
