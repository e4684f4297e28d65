"""The sensor's own low-pass filter on the measured acceleration (its lag is not T_a's)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Stage,
    Verdict,
    head,
)
from balancer_id.identify.data import TrialData

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.result import FitResult

#: The trial that tells a sensor's effect from the balancer's.
SENSOR_TRIAL = (
    "record a few seconds at rest with the sensor on the frame (its noise spectrum "
    "shows the sensor's filter) and one step with a second, unfiltered sensor"
)


#: Evaluations of the 1st-order filter's fit, started where the 2nd-order one ended.
FIRST_ORDER_NFEV = 25
#: Evaluations of the 2nd-order filter's fit started from a late channel's fit.
LATE_START_NFEV = 30


class SensorLowpass(ExplanationKind):
    """The accelerometer's low-pass (2nd or 1st order), when the resting noise rolls off
    as a filter's (40 dB per decade; :func:`rest_cutoff`) or the response lags its drive.

    Fitted: the model's output through the filter, its cut-off started at the resting
    noise's and fitted with the model's parameters, or held at it (no parameter added),
    the better by BIC. Offered only with the resting noise's own evidence, it stands
    unless the response contradicts it; it mimics a longer T_a.
    """

    key = "sensor"
    kind = "sensor"
    verdict = Verdict.SENSOR_EFFECT
    #: after the channel timing's fit, whose lag (a late acceleration) it starts from
    stage = Stage.PAIRED
    stands_alone = True
    measurement = True
    tried = "the sensor's low-pass"
    mimics: ClassVar[str] = "a longer T_a (the filter's lag)"
    separating_trial: ClassVar[str] = SENSOR_TRIAL

    def valid(self, e: Explanation, tests_failed: bool, threshold: float, min_drop: float) -> bool:
        """Stands unless the response contradicts it (tests passed), else by BIC alone.

        Offered only when the resting noise shows a filter's roll-off (independent
        evidence, measured with the balancer still): a response fitted as well without
        it has the sensor's lag in T_a, which is worth saying, not "adequate". A sensor's
        low-pass hides part of the noise from the floor's estimate (its resting parts
        are short and smooth), so its drop of the excess error is understated: BIC only.
        """
        if e.null:
            return False
        if e.detail.get("rest_noise_cutoff_hz") is None:  # the response's evidence alone
            return super().valid(e, tests_failed, threshold, min_drop)
        if not tests_failed:
            return e.delta_bic > -arena.CLOSE_BIC
        return e.delta_bic > threshold

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """The model's output through the low-pass: its cut-off started at the resting
        noise's, or, without that evidence, at the acceleration's lag behind its drive
        (none where it does not clearly lag). The filter's order is not known: a
        2nd-order one (a MEMS sensor's digital filter) and a 1st-order one (an
        exponential running average in the sensor's firmware) of about the same lag are
        both fitted, the better by BIC kept (one parameter each)."""
        rest_fc = inp.rest_cutoff_hz
        from_response = rest_fc is None
        late = _late_acceleration(inp)
        start_fc = _lag_cutoff(inp) if rest_fc is None else rest_fc
        values = inp.match.values()
        if from_response and late is not None:
            # the lag the channel-timing fit found, with the balancer it found there: a
            # filter's lag and a late channel are read from the same samples
            start_fc = _cutoff_of_lag(inp, -float(late.detail["force_delay_s"]))  # type: ignore[arg-type]
            values = {**values, **late.detail.get("values", {})}  # type: ignore[dict-item]
        if start_fc is None:
            return []
        fc0: float = start_fc
        model = inp.match.model
        sims = arena.Trials(inp.trials)
        # a session's trials filtered as one record: the filter remembers the motion
        # before the step that starts a continuing trial
        chains = arena.session_chains(inp.trials)
        times = [np.asarray(td.time, dtype=float) for td in inp.trials]
        joined = {c[0]: np.concatenate([times[j] for j in c]) for c in chains}
        dts = [float(np.median(np.diff(t))) for t in times]
        fss = [1.0 / dt for dt in dts]
        fixed = arena.held(inp.match)
        names = [n for n in model.param_names if n not in fixed]
        none = np.zeros((len(inp.trials), 0))

        def fitted_filter(
            order: int, start: float, values: dict[str, float], nfev: int
        ) -> tuple[list[np.ndarray], dict[str, float], float]:
            def post(i: int, y: np.ndarray) -> np.ndarray:
                return lowpass_at(joined[i], y, post.param, fss[i], order)  # type: ignore[attr-defined]

            post.chains = chains  # type: ignore[attr-defined]

            parts, base, _, fc = arena.fit_varying(
                model,
                sims,
                values,
                fixed,
                names[0],
                none,
                post=post,
                extra=(start, 0.3 * start, min(4 * start, 0.45 * min(fss))),
                max_nfev=nfev,
            )
            return parts, base, float(fc if fc is not None else start)

        # from the late channel's fit the balancer's values are nearly settled already
        nfev = LATE_START_NFEV if from_response and late is not None else 60
        parts, base, fc = fitted_filter(2, fc0, values, nfev)
        d, rmse = arena.score(inp, parts, 1)
        order = 2
        # the 1st-order filter of the same lag (sqrt(2) / (2 pi fc) against 1 / (2 pi fc)),
        # from the balancer's values the 2nd-order fit found: a few steps settle it
        parts1, base1, fc1 = fitted_filter(1, fc / np.sqrt(2.0), base, FIRST_ORDER_NFEV)
        d1, rmse1 = arena.score(inp, parts1, 1)
        if d1 > d:
            parts, base, fc, d, rmse, order = parts1, base1, fc1, d1, rmse1, 1
        fitted = True
        if not from_response:
            # the cut-off as measured at rest (no parameter fitted): when the response
            # cannot place the cut-off itself, the resting noise's is the estimate
            def measured(i: int, y: np.ndarray) -> np.ndarray:
                return lowpass_at(joined[i], y, fc0, fss[i])

            measured.chains = chains  # type: ignore[attr-defined]

            parts0, base0, _, _ = arena.fit_varying(
                model, sims, inp.match.values(), fixed, names[0], none, post=measured
            )
            d0, rmse0 = arena.score(inp, parts0, 0)
            fitted = d > d0
            if not fitted:
                d, rmse, base, fc, order = d0, rmse0, base0, fc0, 2
        return [
            self.make(
                f"sensor low-pass at {fc:.1f} Hz",
                d,
                rmse,
                detail={
                    "sensor": "low-pass",
                    "cutoff_hz": fc,
                    "order": order,
                    "rest_noise_cutoff_hz": None if from_response else fc0,
                    "cutoff_fitted": fitted,
                    "values": base,
                },
            )
        ]

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """``the accelerometer smooths its signal: a low-pass at 6.1 Hz ...``."""
        d = e.detail
        said = head(e)
        if e.delta_bic <= arena.BIC_THRESHOLD:
            values: dict[str, float] = d.get("values") or {}  # type: ignore[assignment]
            now = fit.match.values()
            moved = [
                f"{k} {float(values[k]):.4g} with it, {now[k]:.4g} without"  # type: ignore[index]
                for k in ("T_a", "m_a")
                if k in values and k in now
            ]
            said = (
                f"the response fits as well with it (BIC {-e.delta_bic:+.0f}), and without it "
                "the balancer's parameters hold the sensor's lag"
                + (f" ({'; '.join(moved)})" if moved else "")
            )
        rest = d.get("rest_noise_cutoff_hz")
        why = (
            f"the resting noise rolls off at {float(rest):.1f} Hz, as a filter's, not as "  # type: ignore[arg-type]
            "coloured noise's"
            if rest is not None
            else "the response lags its drive as a filter's, smoothed; the resting noise "
            "shows no filter, so the noise enters after it"
        )
        return (
            f"the accelerometer smooths its signal: a low-pass at {float(d['cutoff_hz']):.1f} Hz "  # type: ignore[arg-type]
            f"({why}); {said}. Not the balancer: record with "
            "the sensor's filter off or a higher bandwidth, or read its delay as part of the "
            "sensor"
        )


#: The acceleration must lag its drive by this many standard errors (the fit's timing
#: test) for a low-pass to be tried without the resting noise's evidence.
LAG_Z = 2.0


def _lag_cutoff(inp: ArenaInput) -> float | None:
    """The cut-off whose lag is the acceleration's lag behind its drive (the fit's timing
    test, ``sqrt(2) / (2 pi fc)`` for the 2nd-order filter), or None when the acceleration
    does not clearly lag (:data:`LAG_Z`)."""
    lead = inp.match.metrics.get("timing_lead_s")
    se = inp.match.metrics.get("timing_lead_stderr_s")
    if lead is None or se is None or not (np.isfinite(lead) and np.isfinite(se) and se > 0):
        return None
    if lead >= 0 or -lead < LAG_Z * se:
        return None
    return _cutoff_of_lag(inp, -lead)


def _cutoff_of_lag(inp: ArenaInput, lag: float) -> float | None:
    """The 2nd-order filter's cut-off whose lag is ``lag`` (s), within the sample rate's
    reach."""
    dts = [float(np.median(np.diff(td.time))) for td in inp.trials if td.time.size > 1]
    if not dts or lag <= 0:
        return None
    fs = 1.0 / max(dts)
    return float(np.clip(np.sqrt(2.0) / (2.0 * np.pi * lag), 0.5, 0.4 * fs))


def _late_acceleration(inp: ArenaInput) -> Explanation | None:
    """The channel-timing explanation, where it found the acceleration late by more than
    two of its standard errors and with a benefit (BIC, and a tenth of the error above
    the noise floor removed), else None. A lag under half a sample counts (no finding as
    a late channel, but a filter's lag at a low rate)."""
    for e in inp.found:
        if e.key != "force_delay" or e.delta_bic <= arena.CLOSE_BIC:
            continue
        if e.excess_drop <= arena.MIN_EXCESS_DROP:
            continue
        d = e.detail.get("force_delay_s")
        se = e.detail.get("force_delay_stderr_s")
        if isinstance(d, float) and d < 0 and (not isinstance(se, float) or -d > LAG_Z * se):
            return e
    return None


def _butter2(cutoff: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients of a 2nd-order Butterworth low-pass (bilinear, prewarped)."""
    w = np.tan(np.pi * min(cutoff, 0.45 * fs) / fs)
    k = np.sqrt(2.0)
    a0 = 1 + k * w + w * w
    b = np.array([w * w, 2 * w * w, w * w]) / a0
    a = np.array([1.0, (2 * w * w - 2) / a0, (1 - k * w + w * w) / a0])
    return b, a


def _first_order(cutoff: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients of a 1st-order low-pass as sensors' firmware runs it: the exponential
    running average ``y[n] = y[n-1] + (1 - a) (x[n] - y[n-1])``, ``a = exp(-2 pi fc / fs)``
    (the sample just read enters at once; a bilinear form would lag it half a sample)."""
    a = float(np.exp(-2.0 * np.pi * min(cutoff, 0.45 * fs) / fs))
    return np.array([1.0 - a]), np.array([1.0, -a])


def lowpass(y: np.ndarray, cutoff: float, fs: float, order: int = 2) -> np.ndarray:
    """``y`` through a Butterworth low-pass of order 2 (or 1), started at rest on its
    first value.

    Parameters
    ----------
    y : numpy.ndarray
        A signal sampled at ``fs``.
    cutoff : float
        -3 dB frequency (Hz).
    fs : float
        Sample rate (Hz).
    order : int
        2 or 1.

    Returns
    -------
    numpy.ndarray
    """
    from scipy.signal import lfilter, lfilter_zi

    b, a = _butter2(cutoff, fs) if order == 2 else _first_order(cutoff, fs)
    return lfilter(b, a, y, zi=lfilter_zi(b, a) * y[0])[0]


def lowpass_at(
    time: np.ndarray, y: np.ndarray, cutoff: float, fs: float, order: int = 2
) -> np.ndarray:
    """``y``, sampled at ``time``, through the low-pass of :func:`lowpass` run on the
    sensor's own clock: a sample lost (a drop-out) does not cut the filter's time short.

    Parameters
    ----------
    time : numpy.ndarray
        The samples' times (s); gaps where samples were lost.
    y : numpy.ndarray
        The signal at those times.
    cutoff, fs : float
        -3 dB frequency and the sensor's rate (Hz).
    order : int
        2 or 1.

    Returns
    -------
    numpy.ndarray
    """
    if time.size != y.size or time.size < 2:
        return lowpass(y, cutoff, fs, order)
    dt = 1.0 / fs
    if float(np.max(np.diff(time))) < 1.5 * dt:
        return lowpass(y, cutoff, fs, order)
    grid = time[0] + np.arange(round(float(time[-1] - time[0]) * fs) + 1) * dt
    return np.interp(time, grid, lowpass(np.interp(grid, time, y), cutoff, fs, order))


#: A rest spectrum is a sensor filter's when a 2nd-order low-pass fits its log this many
#: times better (sum of squares) than AR(1) colour does.
FILTER_EVIDENCE = 4.0


def rest_spectrum(trials: Sequence[TrialData], fs: float) -> dict[str, float] | None:
    """The resting noise's averaged spectrum against two shapes: a filter's and AR(1)'s.

    The resting samples before each onset are cut into 64-sample segments (a step of 16;
    slope removed, Hann window); the log of their averaged periodogram (0 < f <= 0.45 fs)
    is fitted, up to a level, by a 2nd-order Butterworth low-pass (flat, then falling by
    40 dB per decade beyond its cut-off: a sensor's filter) and by AR(1) noise (falling
    gently, by at most 20 dB per decade: colour that is not a filter of the signal, such
    as the environment's), each over a grid of its one parameter.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials.
    fs : float
        Sample rate (Hz).

    Returns
    -------
    dict or None
        ``cutoff_hz`` and ``sse_filter`` of the low-pass, ``phi`` and ``sse_ar1`` of the
        AR(1), ``segments``; None with fewer than 4 segments.
    """
    n_seg = 64
    segs = []
    x = np.arange(n_seg) - (n_seg - 1) / 2
    for td in trials:
        t = td.time - td.t_step
        y = np.asarray(td.accel)[t < -0.02]
        for j in range(0, y.size - n_seg + 1, 16):
            seg = y[j : j + n_seg]
            segs.append(seg - np.polyval(np.polyfit(x, seg, 1), x))
    if len(segs) < 4:
        return None
    w = np.hanning(n_seg)
    p = np.mean(np.abs(np.fft.rfft(np.array(segs) * w, axis=1)) ** 2, axis=0)
    f = np.fft.rfftfreq(n_seg, 1.0 / fs)
    keep = (f > 0) & (f <= 0.45 * fs) & (p > 0)
    if keep.sum() < 6:
        return None
    lp, ff = np.log(p[keep]), f[keep]

    def sse(shape: np.ndarray) -> float:
        r = lp - shape
        r = r - r.mean()
        return float(r @ r)

    tf = np.tan(np.pi * ff / fs)
    cuts = np.geomspace(0.01 * fs, 0.45 * fs, 240)
    filt = [sse(-np.log1p((tf / np.tan(np.pi * c / fs)) ** 4)) for c in cuts]
    om = 2 * np.pi * ff / fs
    phis = np.linspace(0.0, 0.99, 199)
    ar = [sse(-np.log(1 + q * q - 2 * q * np.cos(om))) for q in phis]
    i, j = int(np.argmin(filt)), int(np.argmin(ar))
    return {
        "cutoff_hz": float(cuts[i]),
        "sse_filter": filt[i],
        "phi": float(phis[j]),
        "sse_ar1": ar[j],
        "segments": float(len(segs)),
    }


def rest_cutoff(trials: Sequence[TrialData], fs: float) -> float | None:
    """The cut-off of the sensor's low-pass the resting noise shows, or None.

    The resting noise is a filter's when a 2nd-order low-pass fits its spectrum
    :data:`FILTER_EVIDENCE` times better than AR(1) colour does and its cut-off lies
    below 0.3 fs (:func:`rest_spectrum`). White noise (no roll-off) and gently
    coloured noise give None.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials.
    fs : float
        Sample rate (Hz).

    Returns
    -------
    float or None
        The cut-off (Hz).
    """
    spec = rest_spectrum(trials, fs)
    if spec is None:
        return None
    steep = spec["sse_filter"] * FILTER_EVIDENCE < spec["sse_ar1"]
    return spec["cutoff_hz"] if steep and spec["cutoff_hz"] < 0.3 * fs else None
