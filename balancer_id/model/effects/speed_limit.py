"""Saturation of the winding speed."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param


class SpeedLimit(Effect):
    """The drum's winding speed saturates at ``v_max`` (specification: 500 mm/s).

    While the net force pushes outward, with ``x = (v_max - |v|) / (2 |a| tau)`` and
    ``tau = 20 ms`` (the drive's speed loop), the acceleration ``a`` becomes
    ``a x (2 - x)`` for ``x < 1``: unchanged far from the limit, ``(v_max - |v|) / tau``
    close to it, zero at it. The measured acceleration drops to
    zero within a few samples and the speed plateaus at the same value in every long
    trial.
    """

    name = "speed_limit"
    summary = "winding speed saturates at v_max (spec 0.5 m/s); acceleration drops to 0"
    source = "paper Table III (maximum winding speed 500 mm/s)"
    example = {"v_max": 0.5}
    parameters = (Param("v_max", 0.5, 0.01, 5.0, "m/s", "maximum winding speed"),)

    @staticmethod
    def speed_limit(v_max: float) -> float:
        return v_max
