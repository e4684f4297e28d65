"""An acceleration offset left after gravity removal."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param
from balancer_id.model.signature import Signature, SignatureContext, clip01, t_stat


class Bias(Effect):
    """A constant offset ``b`` on the measured acceleration: ``a_meas = a + b``.

    Left by an error in the estimated gravity direction (tilt), a calibration offset or
    drift. It shows as a nonzero residual mean in the resting parts of a trial.
    """

    name = "bias"
    summary = "constant acceleration offset b left after gravity removal (tilt, drift)"
    source = "MODEL.md"
    example = {"b": 0.05}
    parameters = (Param("b", 0.0, -2.0, 2.0, "m/s^2", "acceleration offset"),)

    @staticmethod
    def output(a: float, v: float, z: float, b: float) -> float:
        return a + b

    @classmethod
    def signature(cls, ctx: SignatureContext) -> Signature:
        """Residual mean at rest differs from zero, with the same sign in every trial.

        Parameters
        ----------
        ctx : SignatureContext
            The fit and its residuals, trial by trial.

        Returns
        -------
        Signature
            Strength in [0, 1], the evidence in words and numbers, and the start value of
            ``b``: the mean residual at rest (m/s^2).
        """
        import numpy as np

        rest = [tv.residual[tv.regimes["rest"]] for tv in ctx.trials]
        rest = [r for r in rest if r.size >= 5]
        if not rest:
            return Signature(0.0, "no resting samples before the onsets to test an offset")
        allr = np.concatenate(rest)
        t = t_stat(allr, ctx.noise_floor)
        means = np.array([np.mean(r) for r in rest])
        same_sign = float(np.mean(np.sign(means) == np.sign(np.mean(allr))))
        motion = np.concatenate([tv.residual[tv.t >= 0] for tv in ctx.trials])
        return Signature(
            clip01((abs(t) - 3) / 10) * same_sign,
            f"residual mean at rest {np.mean(allr):+.4f} m/s^2 (t = {t:+.1f}, same sign in "
            f"{same_sign:.0%} of trials), during motion {np.mean(motion):+.4f} m/s^2",
            {"b": float(np.mean(allr))},
        )
