"""Transport delay between the thrust and the drive."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param


class DeadTime(Effect):
    """A pure delay ``tau_d`` between the thrust and the drive: ``u(t) -> u(t - tau_d)``.

    The simulator shifts the thrust's breakpoints by ``tau_d`` exactly (not rounded to a
    sample), so the response moves smoothly with ``tau_d``. Source: wireless link and
    motor controller latency (MODEL.md).
    """

    name = "dead_time"
    summary = "transport delay tau_d between thrust and drive (wireless link, motor)"
    source = "MODEL.md"
    example = {"tau_d": 0.08}
    parameters = (Param("tau_d", 0.05, 0.0, 1.0, "s", "dead time"),)

    @staticmethod
    def input_delay(tau_d: float) -> float:
        return tau_d
