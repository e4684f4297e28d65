"""Different drive lags for upward and downward motion."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param


class AsymmetricLag(Effect):
    """The drive lag depends on the direction the drive force moves (paper Fig. 8)::

        T = T_up    if h - f >= 0 (drive force rising: upward push)
        T = T_down  otherwise

    Replaces the base ``T_a``.
    """

    name = "asymmetric_lag"
    summary = "separate drive lags T_up and T_down for upward and downward pushes (Fig. 8)"
    source = "paper III.A, Fig. 8"
    replaces = ("T_a",)
    example = {"T_up": 0.3, "T_down": 0.38}
    parameters = (
        Param("T_up", 0.3, 0.0005, 10.0, "s", "drive lag while the drive force rises", True),
        Param("T_down", 0.3, 0.0005, 10.0, "s", "drive lag while the drive force falls", True),
    )

    @staticmethod
    def time_constant(h: float, f: float, T_up: float, T_down: float) -> float:
        return T_up if h - f >= 0.0 else T_down
