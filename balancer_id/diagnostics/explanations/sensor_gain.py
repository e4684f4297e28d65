"""The accelerometer's gain against gravity: at rest it must read g."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np

from balancer_id.constants import G_DEFAULT
from balancer_id.diagnostics import arena
from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Verdict,
    head,
)
from balancer_id.diagnostics.explanations.effect import LibraryEffect
from balancer_id.diagnostics.explanations.measured_output import (
    corrected,
    fit_mapped,
    rest_samples,
)

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.result import FitResult

#: A gain off 1 by less than this is not named: local gravity varies by 0.5 % over the
#: Earth, and a smaller gain moves m_a by less than a fit's usual tolerance.
GAIN_TOLERANCE = 0.015
#: The resting level must differ from 0 by this many standard errors.
REST_Z = 5.0


class SensorGain(ExplanationKind):
    """The accelerometer reads ``k`` times the true acceleration (``k != 1``).

    At rest a sensor that reads specific force sees g; the reader removes g, so a
    resting level ``r`` left in the trials is ``(k - 1) g`` (a tilt would not leave one:
    the vertical is found from the resting samples themselves). Fitted: the model's
    output mapped ``k a + (k - 1) g``, ``k`` started at ``1 + r / g``. A zero offset of
    the sensor (the ``bias`` effect) fits the same data as well (the gain is then in m_a
    and D0): both are the sensor's, and the two readings are said with their m_a.
    Proposed only when the log's accelerometer reads gravity and the gain is off by
    :data:`GAIN_TOLERANCE` at least.
    """

    key = "sensor_gain"
    kind = "sensor"
    verdict = Verdict.SENSOR_EFFECT
    stands_alone = True
    measurement = True
    tried = "the accelerometer's gain against g"
    mimics: ClassVar[str] = "a constant acceleration offset (bias), with m_a and D0 scaled"
    separating_trial: ClassVar[str] = (
        "record a few seconds at rest with the sensor upside down (or on each side): a "
        "gain reads g too high both ways, a zero offset adds on one side and subtracts on "
        "the other"
    )

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """The gain from the resting level, fitted with the model."""
        g = _gravity(inp)
        if g is None or any(e.name == "bias" for e in inp.match.model.effects):
            return []
        rest = rest_samples(inp)
        if sum(r.size for r in rest) < 20:
            return []
        every = np.concatenate(rest)
        level = float(np.mean(every))
        se = float(np.std(every)) / np.sqrt(every.size * max(inp.independence, 0.05))
        k0 = 1.0 + level / g
        if abs(k0 - 1.0) < GAIN_TOLERANCE or abs(level) < REST_Z * se:
            return []

        def scaled(i: int, y: np.ndarray, k: float) -> np.ndarray:
            return k * y + (k - 1.0) * g

        fit = fit_mapped(inp, scaled, k0, 0.5, 1.5)
        offset = dict(inp.effect_fits).get("bias")
        from_offset = _offset_as_gain(offset.values() if offset is not None else None, g)
        if from_offset is not None:
            # the offset's fit is the gain's, rescaled (k a + (k - 1) g with m_a and D0
            # times k is a + b): started there, the gain's fit is as good as the offset's
            # where its own start, from the current fit, stops short
            k_b, values_b = from_offset
            other = fit_mapped(inp, scaled, k_b, 0.5, 1.5, values=values_b)
            if other.delta_bic > fit.delta_bic:
                fit = other
        return [
            self.make(
                f"accelerometer gain {fit.param:.3f}",
                fit.delta_bic,
                fit.rmse,
                detail={
                    "sensor": "gain",
                    "gain": fit.param,
                    "gain_stderr": fit.stderr,
                    "rest_magnitude": g + level,
                    "g": g,
                    "values": fit.values,
                    "offset_reading": offset.values() if offset is not None else None,
                },
            )
        ]

    def absorbs(self, e: Explanation, other: Explanation) -> bool:
        """The bias effect within :data:`~balancer_id.diagnostics.arena.CLOSE_BIC`: the
        same sensor seen as an offset (said in the sentence, not a rival)."""
        return (
            other.key == LibraryEffect.key
            and other.effects == ["bias"]
            and (other.delta_bic - e.delta_bic <= arena.CLOSE_BIC)
        )

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """The resting magnitude against g, the gain, both readings' m_a and the check."""
        d = e.detail
        k = float(d["gain"])  # type: ignore[arg-type]
        other = d.get("offset_reading") or {}
        alt = (
            f"; read as a zero offset of {float(other['b']):+.3f} m/s^2 instead (the bias "  # type: ignore[index]
            f"effect fits alike), m_a would be {float(other['m_a']):.4g}"  # type: ignore[index]
            if isinstance(other, dict) and "b" in other and "m_a" in other
            else ""
        )
        return (
            f"the accelerometer reads {float(d['rest_magnitude']):.3f} m/s^2 at rest against "  # type: ignore[arg-type]
            f"g = {float(d['g']):.3f}: a gain of {k:.3f}, the sensor's calibration, not the "  # type: ignore[arg-type]
            f"balancer; {head(e)}; {corrected(e, fit)}{alt}. Calibrate the sensor (divide "
            f"the acceleration by {k:.3f}) and refit; to tell a gain from an offset, "
            f"{self.separating_trial}"
        )


def _offset_as_gain(
    values: dict[str, float] | None, g: float
) -> tuple[float, dict[str, float]] | None:
    """The bias effect's fit read as a gain: ``k = 1 + b / g`` and the balancer's values
    with ``m_a`` and ``D0`` times ``k`` (the same output), or None without an offset."""
    if not values or "b" not in values:
        return None
    k = 1.0 + float(values["b"]) / g
    if not 0.5 < k < 1.5:
        return None
    out = {n: float(v) for n, v in values.items() if n != "b"}
    for name in ("m_a", "D0"):
        if name in out:
            out[name] *= k
    return k, out


def _gravity(inp: ArenaInput) -> float | None:
    """The g the reader removed, when the fit's logs read gravity; else None."""
    fit = inp.fit
    if fit is None:
        return None
    trial_set = fit.trial_set
    recs = [r for loaded in trial_set.logs for r in loaded.log.recordings]
    if not any(r.accel_includes_gravity for r in recs):
        return None
    return float(getattr(trial_set.options, "g", G_DEFAULT) or G_DEFAULT)
