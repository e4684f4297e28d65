"""What every residual test and signature check looks at, computed once per fit."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from balancer_id.identify.data import TrialData
from balancer_id.identify.matching import MatchResult
from balancer_id.identify.metrics import correlation_time

#: Regimes of a trial, in the order they occur (see :func:`regime_masks`).
REGIMES = ("rest", "rise", "steady", "stuck")


@dataclass
class TrialView:
    """One trial's measured and simulated signals side by side.

    Attributes
    ----------
    data : TrialData
        The trial.
    t : numpy.ndarray
        Time since the onset (s).
    y, y_model, residual : numpy.ndarray
        Measured and simulated acceleration and their difference (m/s^2).
    v, z, f, h : numpy.ndarray
        Simulated velocity, position, drive force and operating force.
    regimes : dict
        Regime name -> boolean mask over the trial's samples.
    """

    data: TrialData
    t: np.ndarray
    y: np.ndarray
    y_model: np.ndarray
    residual: np.ndarray
    v: np.ndarray
    z: np.ndarray
    f: np.ndarray
    h: np.ndarray
    regimes: dict[str, np.ndarray]


@dataclass
class DiagnosisContext:
    """A fit and its residuals, trial by trial.

    Attributes
    ----------
    match : MatchResult
        The fit being diagnosed.
    trials : list of TrialView
    noise_floor : float
        Acceleration noise (m/s^2): the larger of the white-noise level from the residual's
        sample-to-sample differences and the spread of the resting samples before the
        onsets (which also holds coloured noise).
    dt : float
        Median sample interval (s).
    """

    match: MatchResult
    trials: list[TrialView]
    noise_floor: float
    dt: float

    @property
    def residual(self) -> np.ndarray:
        """All residuals, trial after trial."""
        return np.concatenate([tv.residual for tv in self.trials])

    def excess_rmse(self, rmse: float | None = None) -> float:
        """Error above the noise floor: ``sqrt(max(rmse^2 - noise^2, 0))``.

        Parameters
        ----------
        rmse : float, optional
            An RMSE of the acceleration (m/s^2); None uses the RMSE of :attr:`match`.

        Returns
        -------
        float
            The part of ``rmse`` the white noise does not explain (m/s^2).
        """
        rmse = self.match.metrics["rmse"] if rmse is None else rmse
        return float(np.sqrt(max(rmse**2 - self.noise_floor**2, 0.0)))


def regime_masks(
    t: np.ndarray, v: np.ndarray, lag: float, moving_eps: float = 1e-4
) -> dict[str, np.ndarray]:
    """Split a trial into rest (before the onset), rise (first 3 lags), steady motion, stuck.

    Parameters
    ----------
    t : numpy.ndarray
        Time since the onset (s).
    v : numpy.ndarray
        Simulated velocity (m/s).
    lag : float
        The drive lag (s).
    moving_eps : float
        Speed below which the simulated load counts as stuck (m/s).
    """
    rest = t < 0
    rise = (t >= 0) & (t < 3 * lag)
    stuck = (t >= 0) & (np.abs(v) < moving_eps) & ~rise
    steady = (t >= 3 * lag) & ~stuck
    return {"rest": rest, "rise": rise, "steady": steady, "stuck": stuck}


def white_noise_level(diffs: np.ndarray, clip: float = 4.0) -> float:
    """White noise level from sample-to-sample differences of a residual.

    A model error is smooth and cancels in the differences, while white noise doubles its
    variance there. Differences beyond ``clip`` standard deviations (steps of the
    residual where the model switches abruptly) are left out, iterating three times;
    at 4 sigma this biases a Gaussian estimate by less than 0.1 %.

    Parameters
    ----------
    diffs : numpy.ndarray
        Sample-to-sample differences of the residual (m/s^2); non-finite values are
        ignored.
    clip : float
        Differences farther than ``clip`` standard deviations from their mean are left
        out of the estimate.

    Returns
    -------
    float
        Standard deviation of the white noise (m/s^2), NaN with fewer than two finite
        differences.
    """
    d = np.asarray(diffs, float)
    d = d[np.isfinite(d)]
    if d.size < 2:
        return float("nan")
    sigma = float(np.std(d))
    for _ in range(3):
        kept = d[np.abs(d - np.mean(d)) <= clip * sigma]
        if kept.size < 2:
            break
        sigma = float(np.std(kept))
    return sigma / float(np.sqrt(2.0))


def rest_noise_level(segments: Sequence[np.ndarray], removed: int = 1) -> float:
    """Standard deviation of the noise from resting segments, each with its mean removed.

    Removing a segment's mean removes part of the noise's variance with it: for white
    noise one sample's worth, for coloured noise (a sensor's low-pass) the correlation
    time's worth (:func:`correlation_time`). The residual sum of squares is therefore
    divided by ``sum(L_j - removed * tau)``.

    Parameters
    ----------
    segments : sequence of numpy.ndarray
        Resting samples of each trial, mean removed (m/s^2).
    removed : int
        Terms fitted and removed from each segment (1: the mean).

    Returns
    -------
    float
        Standard deviation (m/s^2); NaN without samples.
    """
    segs = [np.asarray(x, float) for x in segments if np.size(x) >= 2]
    if not segs:
        return float("nan")
    rss = float(sum(float(x @ x) for x in segs))
    tau = correlation_time(segs, removed)
    dof = float(sum(max(x.size - removed * tau, 1.0) for x in segs))
    return float(np.sqrt(rss / dof))


def build_context(match: MatchResult) -> DiagnosisContext:
    """Simulate the fitted model once more with every state and cut it into trials.

    Parameters
    ----------
    match : MatchResult
        The fit to diagnose; its model is simulated at the fitted values.

    Returns
    -------
    DiagnosisContext
        One :class:`TrialView` per trial, the noise floor from the residual's
        differences and the median sample interval.
    """
    model = match.model
    values = match.values()
    pvec = np.array([values[n] for n in model.param_names])
    out = match.data.packed.run(model, pvec)
    lag = model.drive_lag(values)
    views = []
    diffs = []
    resting = []
    dts = []
    for td, sl in zip(match.data.trials, match.data.slices(), strict=True):
        t = td.time - td.t_step
        y = td.accel
        ym = out[sl, 0]
        views.append(
            TrialView(
                data=td,
                t=t,
                y=y,
                y_model=ym,
                residual=y - ym,
                v=out[sl, 1],
                z=out[sl, 2],
                f=out[sl, 3],
                h=out[sl, 4],
                regimes=regime_masks(t, out[sl, 1], lag),
            )
        )
        diffs.append(np.diff(y - ym))
        rest = t < -0.02
        if rest.sum() >= 10:
            resting.append(y[rest] - np.mean(y[rest]))
        dts.append(np.median(np.diff(td.time)))
    noise = white_noise_level(np.concatenate(diffs))
    rest_all = np.concatenate(resting) if resting else np.array([])
    if rest_all.size >= 50:
        # Coloured noise (a sensor's low-pass filter) hides part of its variance from the
        # differences; the resting samples before the onsets show all of it.
        # Each trial's mean is removed with its share of the variance (rest_noise_level).
        noise = max(noise, rest_noise_level(resting))
    return DiagnosisContext(match, views, noise, float(np.median(dts)))
