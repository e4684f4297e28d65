"""One contract for every registered effect, built in or user-supplied.

For each effect: simulate seeded trials with its example values, recover the effect's own
parameters from that simulation (the base held at the truth), and refuse bad settings.
A new effect needs no new test code: it is picked up from the registry.

An effect is simulated on the paper's model with its viscosity held at zero (``D0 = 0``:
the viscosity's force ``-D0 exp(-A|h|) v`` is exactly zero), so its equations are those of
the effect alone, and its kernel is one the suite compiles anyway (diagnosis candidates),
not one more compiled for this test only.
"""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest
from conftest import EXAMPLES

from balancer_id.errors import ModelSpecError
from balancer_id.identify.data import TrialData
from balancer_id.identify.matching import match_trials
from balancer_id.model import Effect, parse_model
from balancer_id.model.registry import Registry, default_registry
from balancer_id.simulation import Thrust, Trapezoid, TrialInput, simulate_many

NOISE = 0.01  # m/s^2; the tolerances below are ~10x the Cramer-Rao spread at this noise
THRUSTS = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)
BASE_TRUTH = {"m_a": 15.1, "T_a": 0.33}
#: The paper's viscosity, held off: ``D0 = 0`` makes its force exactly zero.
NO_VISCOSITY = {"D0": 0.0, "A": 0.0}


def contract_registry() -> Registry:
    registry = default_registry([EXAMPLES / "effects" / "hose_spring.py"])
    return registry


EFFECTS = list(contract_registry())


def contract_model(cls: type[Effect], registry: Registry):
    """``cls`` on the paper's model (its viscosity held off by :data:`NO_VISCOSITY`), or
    alone when it cannot be added to it (a viscosity itself, or an effect excluding it)."""
    if cls.name not in ("viscous", "variable_viscosity"):
        try:
            return parse_model(f"variable_viscosity+{cls.name}", registry)
        except ModelSpecError:
            pass
    return parse_model(cls.name, registry)


def truth_of(cls: type[Effect]) -> dict[str, float]:
    return {p.name: float(cls.example.get(p.name, p.value)) for p in cls.parameters}


def trials_for(cls: type[Effect], model, values, rng) -> list[TrialData]:
    t = np.arange(0.0, 7.0, 0.005)
    ref = Trapezoid(0.2, 0.1, 0.5, start=1.5) if "operating_force" in cls.hooks() else None
    inputs = []
    for f_in in THRUSTS:
        z_ref = v_ref = None
        if ref is not None:
            z_ref, v_ref = ref.evaluate(t)
            z_ref, v_ref = math.copysign(1, f_in) * z_ref, math.copysign(1, f_in) * v_ref
        inputs.append(TrialInput(t, Thrust.step(1.0, f_in), z_ref, v_ref))
    sims = simulate_many(model, values, inputs)
    return [
        TrialData(
            k,
            inp.thrust.values[0],
            "up" if inp.thrust.values[0] > 0 else "down",
            1.0,
            inp,
            sim.accel + rng.normal(0.0, NOISE, sim.accel.size),
        )
        for k, (inp, sim) in enumerate(zip(inputs, sims, strict=True))
    ]


@pytest.mark.parametrize("cls", EFFECTS, ids=[e.name for e in EFFECTS])
def test_effect_recovers_its_own_parameters(cls):
    registry = contract_registry()
    model = contract_model(cls, registry)
    own = truth_of(cls)
    base = {**BASE_TRUTH, **NO_VISCOSITY}
    truth = {**{k: v for k, v in base.items() if k in model.param_names}, **own}
    rng = np.random.default_rng(zlib.crc32(cls.name.encode()))
    trials = trials_for(cls, model, truth, rng)
    held = {k: v for k, v in truth.items() if k not in own}
    start = {p.name: p.value for p in cls.parameters}
    result = match_trials(model, trials, start=start, fixed=held)
    for name, value in own.items():
        got = result.parameters[name]
        tol = max(0.05 * abs(value), 0.01 * (abs(cls.parameters[0].value) + 1e-3))
        assert abs(got.value - value) <= tol, (name, got.value, value)
        if got.stderr is not None:
            assert abs(got.value - value) <= 6 * got.stderr + 1e-9, (name, got.value, got.stderr)


@pytest.mark.parametrize("cls", EFFECTS, ids=[e.name for e in EFFECTS])
def test_effect_refuses_bad_settings(cls):
    model = parse_model(cls.name, contract_registry())
    for p in cls.parameters:
        for bad in (p.min - 1.0 - abs(p.min), p.max + 1.0 + abs(p.max), float("nan")):
            with pytest.raises(ModelSpecError, match=p.name):
                model.resolve({p.name: bad})


@pytest.mark.parametrize("cls", EFFECTS, ids=[e.name for e in EFFECTS])
def test_effect_is_documented(cls):
    assert cls.__doc__ and len(cls.__doc__.strip()) > 40, "state the equation in the docstring"
    assert cls.summary and cls.parameters
    for p in cls.parameters:
        assert p.unit and p.description and p.min <= p.value <= p.max
