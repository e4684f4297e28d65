"""The kinds of explanation the arena fits, listed once.

A new kind is its module (an :class:`~balancer_id.diagnostics.explanations.base.ExplanationKind`
subclass: how it is proposed, fitted, scored and named, its verdict, what it mimics and
the trial that separates it), one line in :data:`KINDS` and its test.
"""

from __future__ import annotations

from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Stage,
    Verdict,
)
from balancer_id.diagnostics.explanations.discovered import Discovered
from balancer_id.diagnostics.explanations.drift import Drift
from balancer_id.diagnostics.explanations.effect import LibraryEffect
from balancer_id.diagnostics.explanations.force_delay import ForceDelay
from balancer_id.diagnostics.explanations.pair import Pair
from balancer_id.diagnostics.explanations.sensor_clipping import SensorClipping
from balancer_id.diagnostics.explanations.sensor_gain import SensorGain
from balancer_id.diagnostics.explanations.sensor_lowpass import SensorLowpass
from balancer_id.diagnostics.explanations.split import Split
from balancer_id.diagnostics.explanations.time_trend import TimeTrend

#: Every kind, in the order the arena fits them within a stage.
KINDS: tuple[ExplanationKind, ...] = (
    LibraryEffect(),
    Split(),
    Drift(),
    TimeTrend(),
    SensorLowpass(),
    SensorClipping(),
    SensorGain(),
    ForceDelay(),
    Pair(),
    Discovered(),
)

_BY_KEY = {k.key: k for k in KINDS}
if len(_BY_KEY) != len(KINDS):
    raise RuntimeError("two explanation kinds share a key")


def kind_of(key: str) -> ExplanationKind:
    """The kind registered under ``key`` (an unknown key: a plain missing effect).

    Parameters
    ----------
    key : str

    Returns
    -------
    ExplanationKind
    """
    return _BY_KEY.get(key) or _BY_KEY["effect"]


__all__ = ["KINDS", "Explanation", "ExplanationKind", "Stage", "Verdict", "kind_of"]
