"""Operating-force dependent viscosity (the paper's model)."""

from __future__ import annotations

import math

from balancer_id.model.effect import Effect, Param
from balancer_id.model.signature import Signature, SignatureContext, clip01


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

    @classmethod
    def signature(cls, ctx: SignatureContext) -> Signature:
        """The decay rate depends on the thrust: a constant viscosity over- or under-damps.

        Parameters
        ----------
        ctx : SignatureContext
            The fit and its residuals, trial by trial.

        Returns
        -------
        Signature
            Strength in [0, 1], the evidence in words and numbers, and the start value
            ``A = 0.2``.
        """
        import numpy as np

        rows = []
        for tv in ctx.trials:
            m = tv.regimes["steady"]
            if m.sum() >= 20:
                rows.append(
                    (abs(tv.data.thrust_N), float(np.mean(tv.residual[m] * np.sign(tv.v[m]))))
                )
        if len(rows) < 3 or len({round(r[0], 1) for r in rows}) < 2:
            return Signature(0.0, "needs trials at two or more thrust levels")
        h, r = np.array(rows).T
        corr = float(np.corrcoef(h, r)[0, 1]) if np.std(r) > 0 else 0.0
        return Signature(
            clip01((corr - 0.5) / 0.4),
            f"steady-motion residual along the motion rises with the thrust (r = {corr:+.2f}): "
            "the viscosity falls with the operating force",
            {"A": 0.2},
        )
