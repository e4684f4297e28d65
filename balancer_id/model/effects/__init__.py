"""The built-in effects, one module each, listed once in :data:`BUILTIN_EFFECTS`.

A module holds the effect's class: its parameters, its hooks and the ``signature(ctx)``
check that tells the diagnosis how the effect's absence shows in a residual. A new
built-in effect is its module, one line here and a test (MODEL.md, "Residual
signatures").
"""

from __future__ import annotations

from balancer_id.model.effect import Effect
from balancer_id.model.effects.asymmetric_lag import AsymmetricLag
from balancer_id.model.effects.base_model import Base
from balancer_id.model.effects.bias import Bias
from balancer_id.model.effects.dead_time import DeadTime
from balancer_id.model.effects.karnopp import Karnopp
from balancer_id.model.effects.servo import Servo
from balancer_id.model.effects.speed_limit import SpeedLimit
from balancer_id.model.effects.variable_viscosity import VariableViscosity
from balancer_id.model.effects.viscous import Viscous

#: Every built-in effect by spec name (the base is implied in every model).
BUILTIN_EFFECTS: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (
        Viscous,
        VariableViscosity,
        Karnopp,
        SpeedLimit,
        DeadTime,
        Bias,
        AsymmetricLag,
        Servo,
    )
}

__all__ = ["BUILTIN_EFFECTS", "Base"]
