"""The verdicts of ``diagnose``, one enum (a light module: reports and batches read it)."""

from __future__ import annotations

from enum import StrEnum

__all__ = ["Verdict"]


class Verdict(StrEnum):
    """The verdicts of ``diagnose`` (CONTRACT.md: the string values are the contract)."""

    ADEQUATE = "adequate"
    EFFECT_MISSING = "effect missing"
    PARAMETER_CHANGED = "parameter changed"
    PARAMETER_DRIFT = "parameter drift"
    SENSOR_EFFECT = "sensor effect"
    AMBIGUOUS = "ambiguous"
