"""An accelerometer that does not read g at rest: its gain or its zero, not the balancer.

The reader removes g from a log whose accelerometer reads gravity, so the trials' rest
before each step sits at 0 when the sensor is calibrated. A sensor whose gain is off by
``k - 1`` leaves ``(k - 1) g`` there (a tilt leaves nothing: the vertical is found from
the resting samples themselves); a zero offset leaves itself. Either way a model without
an offset follows a level the balancer never had: a 4 % gain is 0.4 m/s^2 at rest,
often more than the motion's own acceleration, and the fit fails "worse than the mean"
without saying why. The rest says why, before the balancer is blamed (issue 31.4).
"""

from __future__ import annotations

import numpy as np

from balancer_id.constants import G_DEFAULT
from balancer_id.identify.matching import MatchResult
from balancer_id.identify.metrics import correlation_time
from balancer_id.notes import Note
from balancer_id.trials import TrialSet

#: A resting level below this share of g is not named: local gravity varies by 0.5 %
#: over the Earth, and the diagnosis's gain explanation starts at the same 1.5 %.
LEVEL_SHARE = 0.015

#: The level must also pass this many of its standard errors (the noise's colour counted).
LEVEL_Z = 5.0

#: Fewest resting samples the check needs.
MIN_SAMPLES = 20


def resting_offset(match: MatchResult, trials: TrialSet) -> tuple[float, float, float] | None:
    """The acceleration's level at rest, its standard error and the g removed, when the
    level is clearly not 0 in a log that reads gravity and a model without an offset;
    else None.

    Parameters
    ----------
    match : MatchResult
        The fit (its trials' acceleration, g removed).
    trials : TrialSet
        Where the trials came from: whether the logs read gravity, and the g removed.

    Returns
    -------
    tuple of float or None
        ``(level, stderr, g)`` in m/s^2; the sensor reads ``g + level`` at rest.
    """
    if any(e.name == "bias" for e in match.model.effects):
        return None  # the model has the offset: it fits it
    recs = [r for loaded in trials.logs for r in loaded.log.recordings]
    if not recs or not any(r.accel_includes_gravity for r in recs):
        return None
    rest = []
    for td in match.data.trials:
        if td.continues or td.input.x0 is not None:
            continue
        t = np.asarray(td.time, float) - td.t_step
        a = np.asarray(td.accel, float)[t < -0.02]
        if a.size >= 5:
            rest.append(a[np.isfinite(a)])
    n = sum(x.size for x in rest)
    if n < MIN_SAMPLES:
        return None
    every = np.concatenate(rest)
    level = float(np.mean(every))
    tau = correlation_time([x - x.mean() for x in rest], removed=1)
    se = float(np.std(every)) * np.sqrt(max(tau, 1.0) / n)
    g = float(getattr(trials.options, "g", G_DEFAULT) or G_DEFAULT)
    if abs(level) < max(LEVEL_SHARE * g, LEVEL_Z * se):
        return None
    return level, se, g


def sensor_reading(level: float, g: float) -> str:
    """What a resting ``level`` says of the accelerometer, in words (its gain or zero).

    Parameters
    ----------
    level : float
        The acceleration at rest with ``g`` removed (m/s^2).
    g : float
        The gravity removed (m/s^2).

    Returns
    -------
    str
    """
    return (
        f"the accelerometer reads {g + level:.3f} m/s^2 at rest against g = {g:.3f}, a gain "
        f"of {1.0 + level / g:.3f} (or a zero offset of {level:+.3f} m/s^2), the sensor's "
        "calibration, not the balancer"
    )


def resting_level(match: MatchResult, trials: TrialSet) -> Note | None:
    """A ``fit.rest_level`` note (severity ``error``) when the acceleration at rest is
    clearly not 0 in a log that reads gravity and a model without an offset; else None.

    Parameters
    ----------
    match : MatchResult
        The fit (its trials' acceleration, g removed).
    trials : TrialSet
        Where the trials came from: whether the logs read gravity, and the g removed.

    Returns
    -------
    Note or None
        The note says the level, the sensor's resting magnitude against g, the gain (or
        the zero offset) it means and the correction.
    """
    found = resting_offset(match, trials)
    if found is None:
        return None
    level, se, g = found
    gain = 1.0 + level / g
    return Note(
        "fit.rest_level",
        f"the acceleration at rest reads {level:+.3f} m/s^2 (± {se:.3f}), not 0: "
        f"{sensor_reading(level, g)}; the model follows a level the balancer never had, "
        f"so its values are not trusted: divide the acceleration by {gain:.3f} (or "
        "subtract the offset) and refit, or run 'balancer-id diagnose', whose sensor "
        "explanations refit both",
        severity="error",
    )
