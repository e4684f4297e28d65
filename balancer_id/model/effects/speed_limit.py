"""Saturation of the winding speed."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param
from balancer_id.model.signature import Signature, SignatureContext, clip01


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

    @classmethod
    def signature(cls, ctx: SignatureContext) -> Signature:
        """The measured speed plateaus at one value across trials while the model speeds on.

        Parameters
        ----------
        ctx : SignatureContext
            The fit and its residuals, trial by trial.

        Returns
        -------
        Signature
            Strength in [0, 1], the evidence in words and numbers, and the start value of
            ``v_max``: the measured plateau speed (m/s), or above the model's top speed
            when there is no plateau.
        """
        import numpy as np

        plateaus, gaps = [], []
        for tv in ctx.trials:
            m = tv.t >= 0
            if m.sum() < 20:
                continue
            v_meas = np.concatenate(
                [[0.0], np.cumsum(0.5 * (tv.y[m][1:] + tv.y[m][:-1]) * np.diff(tv.t[m]))]
            )
            v_peak = float(np.max(np.abs(v_meas)))
            v_model = float(np.max(np.abs(tv.v[m])))
            late = tv.t > tv.t[-1] - 1.0
            if v_model > 1.05 * v_peak and v_peak > 0.05:
                plateaus.append(v_peak)
                gaps.append(float(np.sqrt(np.mean(tv.residual[late] ** 2))) / ctx.noise_floor)
        v_top = max(float(np.max(np.abs(tv.v))) for tv in ctx.trials)
        if len(plateaus) < 2:
            return Signature(
                0.0,
                "no trial where the model outruns the measured speed",
                {"v_max": float(np.clip(1.2 * v_top, 0.02, 4.9))},
            )
        spread = float(np.std(plateaus) / np.mean(plateaus))
        agree = clip01((0.25 - spread) / 0.2)
        return Signature(
            agree * clip01((np.mean(gaps) - 1.2) / 2),
            f"measured speed plateaus at {np.mean(plateaus):.3f} m/s (spread {spread:.0%}) in "
            f"{len(plateaus)} trials while the model speeds on; "
            f"late residual {np.mean(gaps):.1f}x noise",
            {"v_max": float(np.clip(np.median(plateaus), 0.02, 4.9))},
        )
