"""Models: effects (one small class each), their registry and spec strings."""

from balancer_id.model.effect import HOOKS, Effect, Param
from balancer_id.model.registry import Registry, default_registry
from balancer_id.model.spec import DEFAULT_SPEC, Model, parse_model, resolve_model

__all__ = [
    "DEFAULT_SPEC",
    "HOOKS",
    "Effect",
    "Model",
    "Param",
    "Registry",
    "default_registry",
    "parse_model",
    "resolve_model",
]
