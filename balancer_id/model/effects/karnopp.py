"""Karnopp stick-slip friction."""

from __future__ import annotations

from balancer_id.constants import KARNOPP_EPS
from balancer_id.model.effect import Effect, Param
from balancer_id.model.signature import Signature, SignatureContext, clip01, t_stat


class Karnopp(Effect):
    """Karnopp friction, paper eqs. (3)-(5), with ``f_d = f_s``::

        friction = -F              if |v| <= eps and |F| <= f_s   (stuck)
                 = -sgn(F) f_s     if |v| <= eps and |F| >  f_s   (break-away)
                 = -sgn(v) f_d     otherwise                       (sliding)

    ``F`` is the sum of all other forces on the load and ``eps = 1e-6`` m/s. The
    simulator snaps ``v`` to zero where it changes sign, so a load sticks without
    chattering. A thrust below ``f_s`` produces no motion.
    """

    name = "karnopp"
    summary = "stick-slip friction f_s = f_d with a zero-velocity band (paper eqs. 3-5)"
    source = "paper III.C, eqs. (3)-(5); Karnopp (1985)"
    example = {"f_s": 0.98}
    parameters = (Param("f_s", 1.0, 0.0, 1e5, "N", "static (= dynamic) friction force"),)

    @staticmethod
    def friction(v: float, F: float, f_s: float) -> float:
        if abs(v) <= KARNOPP_EPS:
            if abs(F) <= f_s:
                return -F
            return -f_s if F > 0.0 else f_s
        return -f_s if v > 0.0 else f_s

    @classmethod
    def signature(cls, ctx: SignatureContext) -> Signature:
        """A residual opposing the motion in steady motion, and a thrust that moves nothing.

        Parameters
        ----------
        ctx : SignatureContext
            The fit and its residuals, trial by trial.

        Returns
        -------
        Signature
            Strength in [0, 1], the evidence in words and numbers, and the start value of
            ``f_s``: the friction force the residual implies (N, at most 20).
        """
        import numpy as np

        parts, thrust, accel, accel_model = [], [], [], []
        for tv in ctx.trials:
            m = tv.regimes["steady"]
            if m.sum() >= 10:
                parts.append(tv.residual[m] * np.sign(tv.v[m]))
            late = (tv.t > 0.6) & (tv.t < 1.6)
            if late.sum() >= 10:
                thrust.append(abs(tv.data.thrust_N))
                accel.append(abs(np.mean(tv.y[late])))
                accel_model.append(abs(np.mean(tv.y_model[late])))
        if not parts:
            return Signature(0.0, "no steady motion to test friction")
        r = np.concatenate(parts)
        t = t_stat(r, ctx.noise_floor)
        # The free line |f_in| = m |a| + c of the measurement, against the same line of the
        # model's own response (viscosity bends it too): friction adds c = f_s.
        intercept, z_c = 0.0, 0.0
        if len(thrust) >= 3 and np.ptp(accel) > 0 and np.ptp(accel_model) > 0:
            coef, cov = np.polyfit(accel, thrust, 1, cov=True)
            model_coef = np.polyfit(accel_model, thrust, 1)
            intercept = float(coef[1] - model_coef[1])
            z_c = intercept / np.sqrt(cov[1, 1]) if cov[1, 1] > 0 else 0.0
        m_a = ctx.match.values().get("m_a", 15.0)
        f_s = max(-np.mean(r) * m_a, intercept, 0.05)
        still = [
            tv
            for tv in ctx.trials
            if abs(np.mean(tv.y[tv.t > 0.5])) < 2 * ctx.noise_floor / np.sqrt((tv.t > 0.5).sum())
        ]
        return Signature(
            max(clip01((-t - 3) / 10), clip01((z_c - 3) / 10)),
            f"steady-motion residual {np.mean(r):+.4f} m/s^2 along the motion (t = {t:+.1f}); "
            f"a free line |f_in| = m|a| + c has c = {intercept:+.2f} N more than the model's"
            + (f"; {len(still)} trial(s) show no motion after the step" if still else ""),
            {"f_s": float(min(f_s, 20.0))},
        )
