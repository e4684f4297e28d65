"""Segmentation: vertical motion, thrust steps and the step trials of a log.

The names below load on first use (PEP 562), so importing :class:`Trial` alone (what
:mod:`balancer_id.trials` does) does not import the detectors and ``scipy.ndimage``:
a process that only hands logs to others (``batch``'s parent) starts without them.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from balancer_id.segment.find import find_trials
    from balancer_id.segment.gravity import VerticalMotion, vertical_motion
    from balancer_id.segment.trial import Trial

__all__ = ["Trial", "VerticalMotion", "find_trials", "vertical_motion"]

_WHERE = {
    "Trial": "balancer_id.segment.trial",
    "VerticalMotion": "balancer_id.segment.gravity",
    "find_trials": "balancer_id.segment.find",
    "vertical_motion": "balancer_id.segment.gravity",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        value = getattr(import_module(_WHERE[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'balancer_id.segment' has no attribute {name!r}")
