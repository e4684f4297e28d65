"""Transport delay between the thrust and the drive."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param
from balancer_id.model.signature import Signature, SignatureContext, clip01


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

    @classmethod
    def signature(cls, ctx: SignatureContext) -> Signature:
        """The model leads the measurement just after the onset (input cross-correlation).

        Parameters
        ----------
        ctx : SignatureContext
            The fit and its residuals, trial by trial.

        Returns
        -------
        Signature
            Strength in [0, 1], the evidence in words and numbers, and the start value of
            ``tau_d``: the median lag of the measurement behind the model (s).
        """
        import numpy as np

        shifts = []
        for tv in ctx.trials:
            m = (tv.t > -0.2) & (tv.t < 1.0)
            if m.sum() < 30:
                continue
            y, ym = tv.y[m], tv.y_model[m]
            best, best_err = 0, np.inf
            for k in range(0, int(0.3 / ctx.dt)):
                err = np.mean((y[k:] - ym[: ym.size - k]) ** 2)
                if err < best_err:
                    best, best_err = k, err
            shifts.append(best * ctx.dt)
        xc = ctx.input_correlation(max_lag_s=1.0)
        tau = float(np.median(shifts)) if shifts else 0.0
        lead = xc["significant"] and xc["peak_value"] < 0 and 0 <= xc["peak_lag_s"] < 1.0
        return Signature(
            clip01(tau / (3 * ctx.dt) - 0.5) * (1.0 if lead else 0.5),
            f"the measured response lags the model by {tau * 1e3:.0f} ms (median over "
            f"trials); mean residual against the thrust peaks at {xc['peak_value']:+.4f} "
            f"m/s^2, {xc['peak_lag_s']:.2f} s after the onset",
            {"tau_d": float(np.clip(tau, 0.0, 0.9))},
        )
