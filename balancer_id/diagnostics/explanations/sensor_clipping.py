"""An accelerometer at the end of its range: runs of samples pinned at one extreme value."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Verdict,
    head,
)
from balancer_id.diagnostics.explanations.measured_output import corrected, fit_mapped

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.result import FitResult

#: Samples at the extreme (within this share of the acceleration's span) count as pinned.
PINNED_SHARE = 1e-6
#: ... or, reached by two trials at least, within this many noise floors of it (a
#: tilted sensor's clipped axis projected on the vertical still follows the motion a little).
BAND_NOISE = 3.0
#: A run at the top whose scatter is under this share of the noise has lost its noise.
QUIET = 0.5
#: Slopes beyond the knee tried (sin^2 of tilts up to 30 degrees).
SLOPES = (0.0, 0.03, 0.08, 0.15, 0.25)
#: ... in runs of at least this many consecutive samples ...
MIN_RUN = 3
#: ... and at least this many in all.
MIN_PINNED = 6


class SensorClipping(ExplanationKind):
    """The accelerometer clips: the measured acceleration cannot pass its range.

    Proposed when the highest (or lowest) acceleration of the trials is held by runs of
    consecutive samples at one value, or reached in runs by two trials or more
    (:func:`pinned_level`), at any range: a response peaks once and at its own level per
    thrust, a sensor at its limit stays there for every thrust that passes it. Fitted:
    the model's output clipped at a knee (fitted) and growing beyond it at a slope (a
    tilted sensor's projection; from a scan, then held), two parameters, the model's
    refitted. Correction: the clipped samples left out and the refit. It mimics a force
    that limits the acceleration (viscous friction, a speed limit).
    """

    key = "sensor_clipping"
    kind = "sensor"
    verdict = Verdict.SENSOR_EFFECT
    stands_alone = True
    measurement = True
    tried = "the accelerometer's range"
    mimics: ClassVar[str] = "a force that limits the acceleration (viscous, a speed limit)"
    separating_trial: ClassVar[str] = (
        "record with the accelerometer's range set higher (or smaller thrust steps): a "
        "clipped sensor then shows the peak, a force keeps limiting it"
    )

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """The model seen through the clipping sensor, refitted."""
        accel = [np.asarray(td.accel, dtype=float) for td in inp.trials]
        band = BAND_NOISE * inp.noise_floor
        out = []
        for side in (1.0, -1.0):
            level = pinned_level(accel, side, band, inp.noise_floor)
            if level is None:
                continue
            top, n_pinned = level
            knee0, slope = _scan(inp, side, top, band)

            def clip(
                i: int, y: np.ndarray, knee: float, side: float = side, s: float = slope
            ) -> np.ndarray:
                return soft_clip(y, knee, s, side)

            lo, hi = sorted((top - side * 2 * band, top + side * 0.5 * band))
            fit = fit_mapped(inp, clip, knee0, lo, hi, k_extra=2)
            out.append(
                self.make(
                    f"accelerometer clipped at {fit.param:+.3g} m/s^2",
                    fit.delta_bic,
                    fit.rmse,
                    detail={
                        "sensor": "clipping",
                        "clip_level": fit.param,
                        "slope_beyond": slope,
                        "pinned_samples": n_pinned,
                        "values": fit.values,
                    },
                )
            )
        return out

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """The level, the samples pinned there, the correction and the refit."""
        d = e.detail
        return (
            f"the accelerometer clips: {d['pinned_samples']} samples sit at "
            f"{float(d['clip_level']):+.4g} m/s^2 (gravity removed) in runs, where a response "  # type: ignore[arg-type]
            "would peak once: the sensor's range, not the balancer; "
            f"{head(e)}; {corrected(e, fit)}, the clipped samples left out. Record with a "
            "higher range, or leave those samples out of the fit"
        )


def soft_clip(y: np.ndarray, knee: float, slope: float, side: float) -> np.ndarray:
    """``y`` past ``knee`` (on ``side``) grown at ``slope`` of its rate: a tilted sensor's
    clipped axis projected on the vertical (the other axes still follow the motion, at
    ``sin^2`` of the tilt).

    Parameters
    ----------
    y : numpy.ndarray
    knee : float
    slope : float
        0: a hard clip.
    side : float
        ``1`` clips the top, ``-1`` the bottom.

    Returns
    -------
    numpy.ndarray
    """
    with np.errstate(invalid="ignore", over="ignore"):  # a diverged candidate's NaN stays NaN
        beyond = side * (y - knee) > 0
        return np.where(beyond, knee + slope * (y - knee), y)


def _scan(inp: ArenaInput, side: float, top: float, band: float) -> tuple[float, float]:
    """The knee and the slope beyond it that best map the current fit's output onto the
    data (a start for the fit; the slope is then held)."""
    sims = arena.Trials(inp.trials)
    values = inp.match.values()
    pvec = np.array([values[n] for n in inp.match.model.param_names])
    outs = sims.outputs(inp.match.model, [pvec] * len(inp.trials))
    ys = [np.asarray(d.y, dtype=float) for d in sims.data]
    best = (np.inf, top, 0.0)
    for knee in top - side * np.linspace(0.0, 2.0 * band, 9):
        for slope in SLOPES:
            sse = sum(
                float(np.sum((y - soft_clip(o, knee, slope, side)) ** 2))
                for y, o in zip(ys, outs, strict=True)
            )
            if sse < best[0]:
                best = (sse, float(knee), float(slope))
    return best[1], best[2]


def pinned_level(
    accel: list[np.ndarray], side: float, tolerance: float = 0.0, noise: float = 0.0
) -> tuple[float, int] | None:
    """The extreme value held by runs of consecutive samples, and how many sit there.

    Three signatures of a sensor at its limit, the first that holds: samples at exactly
    one value in runs; runs at the top (within ``tolerance``) whose noise has gone (their
    sample-to-sample scatter under :data:`QUIET` of ``noise``: the clipped axis no longer
    carries its noise, only the other axes' share of it); or a band at the top reached in
    runs by two trials or more (a response peaks once, and at its own level per thrust).

    Parameters
    ----------
    accel : list of numpy.ndarray
        Each trial's measured acceleration.
    side : float
        ``1``: the highest value; ``-1``: the lowest.
    tolerance : float
        The band at the top (m/s^2).
    noise : float
        The acceleration's noise (m/s^2); 0 skips the quiet-run test.

    Returns
    -------
    tuple or None
        ``(level, samples pinned)`` when :data:`MIN_PINNED` samples are, in runs of
        :data:`MIN_RUN` or more; else None.
    """
    finite = [a[np.isfinite(a)] for a in accel if a.size]
    if not finite:
        return None
    every = np.concatenate(finite)
    if every.size < 2 * MIN_PINNED:
        return None
    level = float(np.max(every) if side > 0 else np.min(every))
    exact = PINNED_SHARE * max(float(np.ptp(every)), 1e-12)
    counts = [_in_runs(a, level, exact) for a in finite]
    if sum(counts) >= MIN_PINNED:  # samples at one value: a limit, whatever the tilt
        return level, sum(counts)
    band = max(exact, tolerance)
    if noise > 0:
        quiet = sum(_in_runs(a, level, band, QUIET * noise) for a in finite)
        if quiet >= MIN_PINNED:
            return level, quiet
    counts = [_in_runs(a, level, band) for a in finite]
    reached = sum(c > 0 for c in counts)
    return (level, sum(counts)) if reached >= 2 and sum(counts) >= MIN_PINNED else None


def _in_runs(a: np.ndarray, level: float, tol: float, scatter: float | None = None) -> int:
    """Samples within ``tol`` of ``level`` in runs of :data:`MIN_RUN` or more (with a
    sample-to-sample scatter under ``scatter`` when given: the median absolute difference
    of neighbours over 0.954, the noise's standard deviation for white noise, blind to the
    run's few steep samples at its edges)."""
    at = np.abs(a - level) <= tol
    edges = np.diff(np.r_[0, at.astype(int), 0])
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    total = 0
    for lo, hi in zip(starts, stops, strict=True):
        if hi - lo < MIN_RUN:
            continue
        if scatter is not None and np.median(np.abs(np.diff(a[lo:hi]))) / 0.954 >= scatter:
            continue
        total += int(hi - lo)
    return total
