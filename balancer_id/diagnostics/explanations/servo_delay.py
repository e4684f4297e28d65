"""The robot's servo acting late: the delay in the loop, named from the fit's examination."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from balancer_id.diagnostics.explanations.base import Explanation, ExplanationKind, Verdict

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.result import FitResult


class ServoDelay(ExplanationKind):
    """The robot's servo law acts ``tau_r`` late (:mod:`balancer_id.identify.servo_delay`).

    Fitted by the fit's own examination of a robot log (``FitResult.servo_delay``): the
    late servo against a stiffer servo acting at once and a sensor's lag, on the
    acceleration and the force together. Its BIC fall is the examination's: the force
    channel carries the evidence (the servo law fixes its timing), where the acceleration
    alone reads a late servo as a stiffer one and may leave nothing above the noise; so
    it stands on its BIC fall, without the acceleration's excess error. Proposed only for
    a robot fit whose examination names the delay.
    """

    key = "servo_delay"
    kind = "effect"
    verdict = Verdict.EFFECT_MISSING
    stands_alone = True
    tried = "a late robot servo"
    mimics: ClassVar[str] = (
        "a stiffer servo acting at once (the acceleration alone), or a force sensor's lag"
    )
    separating_trial: ClassVar[str] = (
        "record the servo's force with the motion (the force channel): the servo law fixes "
        "its timing against the load's position, which a late servo shifts and a stiffer "
        "one does not; or step the robot's reference by a few mm and time its force"
    )

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """The fit's servo-delay examination, when it names the delay."""
        fit = inp.fit
        late = getattr(fit, "servo_delay", None) if fit is not None else None
        if late is None or not late.named:
            return []
        by = {e.name: e for e in late.explanations}
        gain = by["no_delay"].bic - by["servo_delay"].bic
        lo, hi = late.interval or (late.tau_r, late.tau_r)
        return [
            self.make(
                f"robot servo {1e3 * (late.tau_r or 0.0):.0f} ms late",
                gain,
                by["servo_delay"].rmse,
                detail={
                    "tau_r_s": late.tau_r,
                    "ci95_s": [lo, hi],
                    "values": late.delayed_values,
                    "evidence": "acceleration and force" if late.has_force else "acceleration",
                },
            )
        ]

    def valid(self, e: Explanation, tests_failed: bool, threshold: float, min_drop: float) -> bool:
        """Stands on its BIC fall (its evidence is the force's timing, not the error
        above the acceleration's noise).

        Parameters
        ----------
        e : Explanation
        tests_failed : bool
            Unused.
        threshold : float
            BIC fall needed.
        min_drop : float
            Unused.

        Returns
        -------
        bool
        """
        return not e.null and e.delta_bic > threshold

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """The delay, its interval, what it changes and where the advice is."""
        late = fit.servo_delay
        head = late.lines()[0] if late is not None else e.label
        return (
            f"{head.removeprefix('servo delay: ')}. A fit without the delay reads it as a "
            "stiffer servo; the advice that fit prints is computed and simulated on the "
            f"late loop, over the delay's interval: {fit.command()}"
        )
