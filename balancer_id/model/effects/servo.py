"""A position-controlled robot holding the load (paper section IV)."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param
from balancer_id.model.signature import Signature, SignatureContext, clip01


class Servo(Effect):
    """Robot coupling: the load is held by a servo spring-damper tracking a reference::

        h = u + k_r (z_ref - z) + c_r (v_ref - v)

    With the lag in the loop the closed loop is
    ``T_a m_a s^3 + (T_a D + m_a) s^2 + (D + c_r) s + k_r`` and is stable only when
    ``(T_a D + m_a)(D + c_r) > T_a m_a k_r``: a stiff, lightly damped servo oscillates
    where a person does not (paper section IV, finding 3).
    """

    name = "servo"
    summary = "robot servo spring k_r and damper c_r tracking its reference (section IV)"
    source = "paper IV, Figs. 14-16"
    example = {"k_r": 400.0, "c_r": 180.0}
    needs_reference = True
    parameters = (
        Param("k_r", 300.0, 0.0, 1e6, "N/m", "servo stiffness of the robot"),
        Param("c_r", 150.0, 0.0, 1e5, "N s/m", "servo damping of the robot"),
    )

    @staticmethod
    def operating_force(
        t: float, u: float, z: float, v: float, z_ref: float, v_ref: float, k_r: float, c_r: float
    ) -> float:
        return u + k_r * (z_ref - z) + c_r * (v_ref - v)

    @classmethod
    def signature(cls, ctx: SignatureContext) -> Signature:
        """A narrow peak in the residual spectrum: an oscillation a person's log does not show.

        Parameters
        ----------
        ctx : SignatureContext
            The fit and its residuals, trial by trial.

        Returns
        -------
        Signature
            Strength in [0, 1], the evidence in words and numbers; no start values.
        """
        peaks = ctx.spectrum_peaks()["peaks"]
        if not peaks:
            return Signature(0.0, "no narrow peak in the residual spectrum")
        p = peaks[0]
        return Signature(
            clip01((p["ratio_to_median"] - 8) / 30),
            f"narrow residual peak at {p['frequency_hz']:.2f} Hz, {p['ratio_to_median']:.0f}x "
            "the median spectrum: an oscillation during motion",
        )
