"""What every residual test and signature check looks at, computed once per fit."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from balancer_id.diagnostics.spectra import prominent_peaks, welch_psd
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
        Acceleration noise (m/s^2): the larger of the level from the residual's
        sample-to-sample differences (their first-order colour given back,
        :func:`difference_colour`) and the spread of the resting samples before the
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

    def input_correlation(self, max_lag_s: float = 1.5) -> dict[str, object]:
        """Cross-correlation of the residual with the thrust step, as a function of lag.

        For a step input this is the residual averaged over trials (sign-corrected by the
        thrust) against the time since the onset: its peak says when after the step the
        model is wrong, and a peak within the first lag with the model leading points to
        dead time.

        Parameters
        ----------
        max_lag_s : float
            Latest time after the onset to look at (s); the lags start 0.3 s before the
            onset.

        Returns
        -------
        dict
            ``lag_s`` and ``mean_residual`` (m/s^2) per lag, the Bonferroni-corrected 95 %
            ``band``, ``peak_lag_s``, ``peak_value`` and whether the peak is
            ``significant``.
        """
        dt = self.dt
        n_lag = round(max_lag_s / dt)
        lags = np.arange(-round(0.3 / dt), n_lag + 1)
        acc = np.zeros(lags.size)
        cnt = np.zeros(lags.size)
        scale = []
        for tv in self.trials:
            k0 = int(np.searchsorted(tv.t, 0.0))
            s = np.sign(tv.data.thrust_N) or 1.0
            idx = k0 + lags
            ok = (idx >= 0) & (idx < tv.residual.size)
            acc[ok] += s * tv.residual[idx[ok]]
            cnt[ok] += 1
            scale.append(np.std(tv.residual))
        mean = np.divide(acc, cnt, out=np.zeros_like(acc), where=cnt > 0)
        from scipy.special import ndtri

        sigma = float(np.mean(scale)) if scale else 1.0
        # 95 % band for the largest of all lags (Bonferroni over the lags)
        band = float(-ndtri(0.025 / lags.size)) * sigma / np.sqrt(max(len(self.trials), 1))
        peak = int(np.argmax(np.abs(mean)))
        return {
            "lag_s": [round(float(x), 4) for x in lags * dt],
            "mean_residual": [round(float(x), 5) for x in mean],
            "band": float(band),
            "peak_lag_s": float(lags[peak] * dt),
            "peak_value": float(mean[peak]),
            "significant": bool(abs(mean[peak]) > band),
        }

    def spectrum_peaks(self, factor: float = 8.0) -> dict[str, object]:
        """Welch spectrum of the residual; narrow peaks above ``factor`` x the median level.

        Parameters
        ----------
        factor : float
            How far above the median spectral level a peak must rise to count; trials
            shorter than 128 samples are left out.

        Returns
        -------
        dict
            ``peaks``: up to five ``{"frequency_hz", "ratio_to_median"}``, strongest first
            (the three lowest bins are ignored); ``frequency_hz`` and ``psd``: the
            spectrum averaged over trials.
        """
        fs = 1.0 / self.dt
        psds: list[Any] = []
        f: Any = None
        for tv in self.trials:
            if tv.residual.size >= 128:
                f_here, p = welch_psd(tv.residual, fs, min(256, tv.residual.size))
                if psds and p.size != psds[0].size:
                    continue  # another segment length: its bins are not the first's
                if f is None:
                    f = f_here  # the frequencies of the spectra kept, not of the last seen
                psds.append(p)
        if not psds:
            return {"peaks": [], "frequency_hz": [], "psd": []}
        psd = np.mean(psds, axis=0)
        level = float(np.median(psd[1:]))
        idx = prominent_peaks(psd, height=factor * level, prominence=factor * level / 2)
        peaks = [
            {"frequency_hz": float(f[i]), "ratio_to_median": float(psd[i] / level)}
            for i in idx
            if i >= 3  # leave out what a trend leaks into the lowest bins
        ]
        peaks.sort(key=lambda p: -p["ratio_to_median"])
        return {"peaks": peaks[:5], "frequency_hz": f.tolist(), "psd": psd.tolist()}


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


def difference_colour(residuals: Sequence[np.ndarray]) -> float:
    """The lag-one correlation of a first-order (AR(1)) noise, from a residual's
    sample-to-sample differences.

    A model's error is smooth and cancels in the differences, while an AR(1) noise of
    lag-one correlation ``r`` gives differences correlated ``-(1 - r) / 2`` at lag one
    (``-1/2`` for white noise); so ``r = 1 + 2 corr``. Differences beyond 4 of their
    standard deviations (the residual's jumps where a model switches) are left out.

    Parameters
    ----------
    residuals : sequence of numpy.ndarray
        The residual, trial by trial (m/s^2).

    Returns
    -------
    float
        ``r`` in ``[0, 0.95]`` (0 without enough samples).
    """
    diffs = [np.diff(np.asarray(r, float)) for r in residuals if np.size(r) > 3]
    if not diffs:
        return 0.0
    sd = float(np.std(np.concatenate(diffs)))
    if sd <= 0:
        return 0.0
    g0 = g1 = 0.0
    n0 = n1 = 0
    for d in diffs:
        sd_k = np.where(np.abs(d - np.mean(d)) <= 4.0 * sd, d, np.nan)
        ok = np.isfinite(sd_k)
        g0 += float(np.sum(sd_k[ok] ** 2))
        n0 += int(ok.sum())
        both = ok[1:] & ok[:-1]
        g1 += float(np.sum(sd_k[1:][both] * sd_k[:-1][both]))
        n1 += int(both.sum())
    if n0 < 10 or n1 < 10 or g0 <= 0:
        return 0.0
    corr = (g1 / n1) / (g0 / n0)
    return float(np.clip(1.0 + 2.0 * corr, 0.0, 0.95))


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
    # a coloured noise hides part of its variance from the differences: a first-order
    # colour read from them gives it back (bounded by the residual's own RMS)
    r1 = difference_colour([v.residual for v in views])
    if r1 > 0 and np.isfinite(noise):
        rms = float(np.sqrt(np.mean(np.concatenate([v.residual for v in views]) ** 2)))
        noise = max(noise, min(noise / float(np.sqrt(1.0 - r1)), rms))
    rest_all = np.concatenate(resting) if resting else np.array([])
    if rest_all.size >= 50:
        # Coloured noise (a sensor's low-pass filter) hides part of its variance from the
        # differences; the resting samples before the onsets show all of it.
        # Each trial's mean is removed with its share of the variance (rest_noise_level).
        noise = max(noise, rest_noise_level(resting))
    return DiagnosisContext(match, views, noise, float(np.median(dts)))
