"""An acceleration offset left after gravity removal."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param


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
