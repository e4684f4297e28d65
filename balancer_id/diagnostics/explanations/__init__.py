"""The kinds of explanation the arena fits, listed once.

A new kind is its module (an :class:`~balancer_id.diagnostics.explanations.base.ExplanationKind`
subclass: how it is proposed, fitted, scored and named, its verdict, what it mimics and
the trial that separates it), one line in :data:`KINDS` and its test.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Stage,
    Verdict,
    kind_of,
    register,
)
from balancer_id.diagnostics.explanations.discovered import Discovered
from balancer_id.diagnostics.explanations.drift import Drift
from balancer_id.diagnostics.explanations.effect import LibraryEffect
from balancer_id.diagnostics.explanations.force_delay import ForceDelay
from balancer_id.diagnostics.explanations.pair import Pair
from balancer_id.diagnostics.explanations.sensor_clipping import SensorClipping
from balancer_id.diagnostics.explanations.sensor_gain import SensorGain
from balancer_id.diagnostics.explanations.sensor_lowpass import SensorLowpass
from balancer_id.diagnostics.explanations.servo_delay import ServoDelay
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
    ServoDelay(),
    Pair(),
    Discovered(),
)

register(KINDS)

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput


def run_arena(inp: ArenaInput) -> list[Explanation]:
    """Every kind's explanations, stage by stage, best first.

    The kinds of a stage see the explanations of the stages before (``inp.found``); a
    kind whose fit fails is named in ``inp.failures`` and the others go on.

    Parameters
    ----------
    inp : ArenaInput

    Returns
    -------
    list of Explanation
    """
    for stage in Stage:
        for kind in (k for k in KINDS if k.stage == stage):
            try:
                new = kind.propose(inp)
            except Exception as exc:  # one kind must not stop the others
                inp.failures.append(f"explanations of {kind.key} failed: {exc!r}")
                continue
            inp.found.extend(inp.polish(e) for e in new)
        inp.found.sort(key=lambda e: -e.delta_bic)
    return inp.found


__all__ = [
    "KINDS", "Explanation", "ExplanationKind", "Stage", "Verdict", "kind_of", "run_arena",
]
