"""Is the misfit more than the sensor's noise? The rest before each step says (issue 31).

Before a step nothing moves: the residual there is the sensor's own noise, its level and
its colour (a low-pass, a phone's filtering), measured on the very log. After the step
the residual holds that noise plus whatever the model does not describe (a friction, a
limit, a late force channel, a clipped sensor). Where the residual in motion carries
clearly more power than at rest, the fitted values bend to follow what the model lacks,
and their intervals (which assume the residual is noise) no longer hold the truth: the
fit is not trusted, and the note says to diagnose it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from balancer_id.identify.data import TrialData
from balancer_id.identify.matching import (
    MatchResult,
    residual_around_steps,
    residual_continuing,
)
from balancer_id.identify.metrics import correlation_time
from balancer_id.notes import Note

#: Excess of the residual's power in motion over the noise's at rest (a fraction of it)
#: above which the misfit is the model's: 0.25 is a misfit of half the noise's RMS.
EXCESS = 0.25

#: The excess must also pass this many of its standard errors (from the effective
#: sample counts of both parts).
SIGMAS = 3.0

#: Fewest resting samples (over all trials) the test needs.
MIN_REST = 20

#: The residual in motion is structured when its correlation time exceeds the noise's at
#: rest by this factor plus :data:`TAU_MARGIN` samples (a misfit at a third of the
#: noise's level, slow against the samples, raises it several-fold; a white noise's
#: estimate varies by a few tenths).
TAU_FACTOR = 2.0
TAU_MARGIN = 1.5


def _power(parts: Sequence[np.ndarray]) -> tuple[float, float]:
    """Mean square and effective sample count (samples over correlation time)."""
    kept = [p for p in parts if p.size >= 5]
    if not kept:
        return float("nan"), 0.0
    x = np.concatenate(kept)
    tau = max(correlation_time(kept, removed=0), 1.0)
    return float(np.mean(x * x)), x.size / tau


def _f_isf(alpha: float, d1: float, d2: float) -> float:
    """The F distribution's upper ``alpha`` quantile, from ``scipy.special`` (the same
    values as ``scipy.stats.f.isf``; importing ``scipy.stats`` cost every fit 0.45 s)."""
    from scipy.special import fdtri

    return float(fdtri(d1, d2, 1.0 - alpha))


def _critical_ratio(least: float, n_motion: float, n_rest: float, tests: int) -> float:
    """The ratio of the powers in motion and at rest that noise alone passes with the
    one-sided probability of :data:`SIGMAS` normal deviations (shared by ``tests``
    tests, Bonferroni), and at least ``least``.

    Both powers are means of squares over their effective samples (samples over the
    correlation time): under the noise alone their ratio is F-distributed. A normal
    approximation of the ratio's spread is too narrow for a short rest (a few tens of
    effective samples: the rest's power is then skewed low, and a clean fit's motion
    looked 1.9 times the noise's, ``bench_universe`` clean world 8209).
    """
    from scipy.special import ndtr

    alpha = float(ndtr(-SIGMAS)) / max(tests, 1)
    critical = _f_isf(alpha, max(n_motion, 1.0), max(n_rest, 1.0))
    return max(least, critical if np.isfinite(critical) else np.inf)


def _coloured_in_motion(rest: list[np.ndarray], motion: list[np.ndarray]) -> Note | None:
    """The whiteness test: a residual in motion correlated over far more samples than the
    noise at rest is a misfit hidden under the noise's level (a friction, a limit partly
    reached, a lag that differs up and down), which still bends the values."""
    rest = [p for p in rest if p.size >= 5]
    motion = [p for p in motion if p.size >= 5]
    if not rest or not motion:
        return None
    tau_rest = correlation_time(rest, removed=1)
    tau_motion = correlation_time(motion, removed=1)
    if tau_motion <= TAU_FACTOR * tau_rest + TAU_MARGIN:
        return None
    return Note(
        "fit.structured_residual",
        f"the residual in motion is correlated over {tau_motion:.1f} samples against the "
        f"sensor's {tau_rest:.1f} at rest before the steps: under the noise's level, the "
        "model misses something the trials show (a force it lacks, a limit partly "
        "reached, a lag that differs up and down), so the values bend to follow it and "
        "their intervals do not hold; run 'balancer-id diagnose' on the same logs",
        severity="error",
    )


#: A single trial's misfit: its power in motion over its own rest's must pass this
#: excess (the RMS x1.41) ...
TRIAL_EXCESS = 1.0


def _worst_trial(
    rest: list[np.ndarray], motion: list[np.ndarray]
) -> tuple[float, float] | None:
    """The rest and motion powers of the trial whose misfit clearly exceeds its own rest's
    noise, or None.

    The pooled test compares all motion with all rest; one trial that is not at rest
    before its step (a glide left by a push the segmentation took for a catch) inflates
    the pooled rest and hides every other trial's misfit. Each trial is held to its own
    rest too, at :data:`TRIAL_EXCESS` and the F test at :data:`SIGMAS` raised for the
    number of trials compared (Bonferroni; :func:`_critical_ratio`).
    """
    pairs = [(r, m) for r, m in zip(rest, motion, strict=True) if r.size >= 20 and m.size >= 20]
    if not pairs:
        return None
    worst: tuple[float, float, float] | None = None
    for r, m in pairs:
        p_rest, n_rest = _power([r])
        p_motion, n_motion = _power([m])
        if not (p_rest > 0 and np.isfinite(p_motion)):
            continue
        critical = _critical_ratio(1.0 + TRIAL_EXCESS, n_motion, n_rest, len(pairs))
        margin = p_motion / p_rest - critical
        if margin > 0 and (worst is None or margin > worst[0]):
            worst = (margin, p_rest, p_motion)
    return None if worst is None else (worst[1], worst[2])


#: A trial's "rest" is motion when its residual there has at least this many times the
#: power of the other rests' median ...
MOVING_POWER = 4.0


def _moving_before_step(
    parts: list[tuple[TrialData, np.ndarray, np.ndarray]],
) -> Note | None:
    """A ``fit.structured_residual`` note when a trial fitted as starting at rest moves
    before its step, else None.

    Its residual before the step is both far stronger than the other rests' median (at
    least :data:`MOVING_POWER` times the power, and beyond an F test at 3 sigma over the
    trials, on the samples counted by the sensor's correlation time) and correlated over
    far more samples (:data:`TAU_FACTOR`, :data:`TAU_MARGIN`): a glide left by a push the
    segmentation took for a catch, not noise (a sensor's colour is the same before every
    step). A rest shorter than 10 of the sensor's correlation times is not judged.
    """
    rests = [(td, r) for td, r, _ in parts if r.size >= 20]
    if len(rests) < 2:
        return None
    stats = [
        (td, float(np.mean(r * r)), correlation_time([r], removed=0), r.size) for td, r in rests
    ]
    for i, (td, p, tau, n) in enumerate(stats):
        others = stats[:i] + stats[i + 1 :]
        ref_p = float(np.median([o[1] for o in others]))
        ref_tau = max(float(np.median([o[2] for o in others])), 1.0)
        n_eff = n / ref_tau  # samples over the sensor's own correlation time
        n_ref = sum(o[3] for o in others) / ref_tau
        if not (ref_p > 0 and n_eff >= 10):
            continue
        critical = _f_isf(0.00135 / len(stats), n_eff, n_ref)
        if p > max(MOVING_POWER, critical) * ref_p and tau > TAU_FACTOR * ref_tau + TAU_MARGIN:
            quiet = min(others, key=lambda o: o[1])[0]
            return Note(
                "fit.structured_residual",
                f"trial {td.index} does not start at rest: before its step the residual is "
                f"{np.sqrt(p):.3g} m/s^2 RMS, correlated over {tau:.0f} samples, against "
                f"{np.sqrt(ref_p):.3g} m/s^2 before the other steps (trial {quiet.index}'s "
                "the quietest); the load still moved (a glide left by a push not taken as a "
                "trial, or a catch), the fit assumes it still, so the values bend; check the "
                "trials with 'balancer-id inspect' and fit a window that starts at rest",
                severity="error",
                subject=f"trial {td.index}",
            )
    return None


#: Relative change of the thrust levels that gives the response's sensitivity to them.
LEVEL_STEP = 1e-4

#: The level shifts that flatten the residual are the force's noise while their chi-square
#: (against each level's standard error) stays below its quantile at this probability.
LEVEL_ALPHA = 1e-3


def _level_sensitivity(
    match: MatchResult, parts: list[tuple[TrialData, np.ndarray, np.ndarray]]
) -> list[np.ndarray] | None:
    """Each trial's simulated acceleration after its onset per relative change of its
    thrust level (one simulation of the trials with every level scaled at once: trials
    from rest do not share a state)."""
    from balancer_id.simulation.engine import PackedTrials, TrialInput
    from balancer_id.simulation.inputs import Thrust

    model = match.model
    values = match.values()
    pvec = np.array([values[n] for n in model.param_names], dtype=float)

    def run(scale: float) -> np.ndarray:
        inputs = [
            TrialInput(
                td.input.time,
                Thrust(td.input.thrust.times, np.asarray(td.input.thrust.values) * scale),
                td.input.z_ref,
                td.input.v_ref,
                td.input.x0,
            )
            for td, _, _ in parts
        ]
        return PackedTrials.pack(inputs).run(model, pvec)[:, 0]

    try:
        with np.errstate(all="ignore"):
            base, moved = run(1.0), run(1.0 + LEVEL_STEP)
    except (ValueError, FloatingPointError):
        return None
    out, k = [], 0
    for td, rest, motion in parts:
        n = td.time.size
        sens = (moved[k : k + n] - base[k : k + n]) / LEVEL_STEP
        k += n
        out.append(sens[rest.size :] if sens.size == rest.size + motion.size else sens[:0])
    return out if all(np.isfinite(x).all() for x in out) else None


def _level_shifts_removed(
    match: MatchResult, parts: list[tuple[TrialData, np.ndarray, np.ndarray]]
) -> list[np.ndarray]:
    """The residuals in motion, less the part a shift of each trial's thrust level within
    its force noise explains (errors in variables), else as they are.

    A step's held level is read from a noisy force: its error (``level_se_N``) moves the
    whole response at once, a slow misfit the whiteness and power tests would take for
    the model's. Each trial's shift is fitted to its residual (least squares on the
    response's sensitivity to the level); where the shifts, against their standard
    errors, pass a chi-square test at :data:`LEVEL_ALPHA`, they are more than the force's
    noise (a friction, a limit: the model's misfit) and nothing is removed.
    """
    motion = [m for _, _, m in parts]
    if not parts or any(td.level_se_N is None or td.thrust_N == 0 for td, _, _ in parts):
        return motion
    sens = _level_sensitivity(match, parts)
    if sens is None:
        return motion
    from scipy.special import gammainccinv  # chi-square's quantile

    shifts, z2 = [], 0.0
    for (td, _, m), s in zip(parts, sens, strict=True):
        ss = float(s @ s)
        if s.size != m.size or ss <= 0:
            return motion
        delta = float(s @ m) / ss  # relative level error
        se = float(td.level_se_N or 0.0) / abs(td.thrust_N)
        if se <= 0:
            return motion
        shifts.append(delta)
        z2 += (delta / se) ** 2
    if z2 > 2.0 * float(gammainccinv(0.5 * len(parts), LEVEL_ALPHA)):
        return motion
    return [m - d * s for m, d, s in zip(motion, shifts, sens, strict=True)]


def structured_residual(match: MatchResult) -> Note | None:
    """A ``fit.structured_residual`` note (severity ``error``) when the residual in motion
    carries clearly more power than the sensor's noise at rest, or is correlated over
    clearly more samples than that noise (:func:`_coloured_in_motion`), else None.

    Parameters
    ----------
    match : MatchResult
        The fit.

    Returns
    -------
    Note or None
        None also when the trials hold fewer than :data:`MIN_REST` resting samples.
    """
    parts = residual_around_steps(match)
    moving = _moving_before_step(parts)
    if moving is not None:
        return moving
    rest = [r for _, r, _ in parts]
    if sum(p.size for p in rest) < MIN_REST:
        return None
    from_rest = _level_shifts_removed(match, parts)
    # a session's trials that go on while moving are motion too: left out, a misfit there
    # (most of a session) went unseen (a 500 Hz session's decimated jumps: 2.8x the noise)
    motion = from_rest + residual_continuing(match)
    p_rest, n_rest = _power(rest)
    p_motion, n_motion = _power(motion)
    if not (np.isfinite(p_rest) and p_rest > 0 and np.isfinite(p_motion) and n_motion > 0):
        return None
    if p_motion / p_rest <= _critical_ratio(1.0 + EXCESS, n_motion, n_rest, 1):
        worst = _worst_trial(rest, from_rest)
        if worst is None:
            return _coloured_in_motion(rest, motion)
        p_rest, p_motion = worst
    return Note(
        "fit.structured_residual",
        f"the residual in motion is {np.sqrt(p_motion):.3g} m/s^2 RMS against the sensor's "
        f"{np.sqrt(p_rest):.3g} m/s^2 at rest before the steps: the model does not describe "
        "what the trials show (a force it lacks, a limit, a late or clipped channel), so the "
        "values bend to follow it and their intervals do not hold; run 'balancer-id "
        "diagnose' on the same logs",
        severity="error",
    )
