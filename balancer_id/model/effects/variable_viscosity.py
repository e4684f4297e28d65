"""Operating-force dependent viscosity (the paper's model)."""

from __future__ import annotations

import math

from balancer_id.model.effect import Effect, Param


class VariableViscosity(Effect):
    """Viscosity that falls with the operating force, paper eq. (2)::

        D(h) = D0 * exp(-A * |h|),   force = -D(h) * v

    ``h`` is the operating force (the thrust). ``A`` is only identifiable from trials at
    two or more thrust levels. Reference values: D0 in 0..10 kg/s, A = 0.4 1/N.
    """

    name = "variable_viscosity"
    summary = "viscosity D0*exp(-A|h|) that falls with the operating force h (paper eq. 2)"
    source = "paper III.B, eq. (2)"
    excludes = ("viscous",)
    example = {"D0": 6.0, "A": 0.4}
    parameters = (
        Param("D0", 3.0, 0.0, 1e6, "kg/s", "viscosity at zero operating force"),
        Param(
            "A",
            0.4,
            0.0,
            1e3,
            "1/N",
            "sensitivity of the viscosity to the operating force",
            needs_thrust_levels=True,
        ),
    )

    @staticmethod
    def force(f: float, v: float, z: float, h: float, D0: float, A: float) -> float:
        return -D0 * math.exp(-A * abs(h)) * v
