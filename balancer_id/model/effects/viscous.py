"""Constant velocity viscosity."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param


class Viscous(Effect):
    """Constant viscosity ``D = D0``: a force ``-D0 v`` on the load.

    After the lag has settled, the acceleration decays as ``exp(-D0 t / m_a)``.
    Source: paper section III.B with ``A = 0``.
    """

    name = "viscous"
    summary = "constant velocity viscosity, force -D0*v"
    source = "paper III.B (A = 0)"
    excludes = ("variable_viscosity",)
    example = {"D0": 6.0}
    parameters = (Param("D0", 3.0, 0.0, 1e6, "kg/s", "velocity viscosity coefficient"),)

    @staticmethod
    def force(f: float, v: float, z: float, h: float, D0: float) -> float:
        return -D0 * v
