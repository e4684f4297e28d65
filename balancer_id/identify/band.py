"""How far the fitted model's response could be: a 95 % band around every simulated sample.

The fit's parameter covariance ``C`` (Wald, widened for a correlated residual) is carried
to the simulated acceleration through the same forward sensitivities the fit steps with,
``S = d a_model / d theta`` (one simulation, ``n x k``): the response's variance at each
sample is ``diag(S C S^T)`` (the delta method, what MATLAB's ``simsd`` approximates by
drawing). Where posterior samples exist the band is their response's 2.5 and 97.5 %
quantiles instead (no linearization).

Two bands are given. The *model band* holds the true noise-free response with 95 %
probability at each sample; the *noise band* (the model band widened by the noise,
``sqrt(var_model + sigma^2)``) holds a new measurement's sample with 95 % probability,
``sigma`` the residual's standard deviation. A measurement that leaves the noise band over
a stretch is a model failure there; inside it, noise and parameter uncertainty explain it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from balancer_id.identify.data import FitData, TrialData

if TYPE_CHECKING:
    from balancer_id.identify.shown import ShownFit

__all__ = ["ResponseBand", "Stretch", "band_summary", "covariance_of", "response_band"]

#: Normal quantile of a two-sided 95 % band.
Z95 = 1.959963984540054
#: Rows simulated per block when the band is computed (a long session never holds its
#: whole sensitivity matrix).
BAND_ROWS = 1 << 16
#: A stretch where the measurement leaves the noise band: at least this share of the
#: samples of a centred window are outside (nominally 5 %).
STRETCH_SHARE = 0.5
#: Width of that window (s), and the shortest stretch reported (s).
STRETCH_WINDOW_S = 0.25
STRETCH_MIN_S = 0.1
#: Posterior draws simulated for a band from samples.
BAND_DRAWS = 200


@dataclass(frozen=True)
class Stretch:
    """A stretch of a trial where the measurement leaves the noise band.

    Attributes
    ----------
    trial : int
        The trial's index.
    t_start, t_end : float
        Log time (s) of the stretch's first and last sample.
    share_outside : float
        Share of its samples outside the noise band.
    side : str
        ``"above"`` or ``"below"``: where most of those samples are.
    """

    trial: int
    t_start: float
    t_end: float
    share_outside: float
    side: str

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "trial": self.trial,
            "t_start": self.t_start,
            "t_end": self.t_end,
            "share_outside": self.share_outside,
            "side": self.side,
        }


@dataclass(frozen=True)
class ResponseBand:
    """The 95 % bands of a model's simulated acceleration, sample by sample.

    Attributes
    ----------
    simulated : numpy.ndarray
        The response at the fitted values (m/s^2), over the trials' samples in order.
    model_low, model_high : numpy.ndarray
        The model band (parameter uncertainty only).
    noise_low, noise_high : numpy.ndarray
        The model band widened by the noise (where a new measurement falls).
    sigma : float
        The noise's standard deviation (m/s^2) used for the widening.
    method : str
        ``"covariance"`` (delta method) or ``"posterior"`` (quantiles of the responses
        of posterior samples).
    level : float
        0.95.
    trials : list of TrialData
        The trials the band is over (their samples in order).
    """

    simulated: np.ndarray
    model_low: np.ndarray
    model_high: np.ndarray
    noise_low: np.ndarray
    noise_high: np.ndarray
    sigma: float
    method: str
    level: float
    trials: list[TrialData]

    def slices(self) -> list[slice]:
        """The slice of each trial in the band's arrays."""
        sizes = [td.time.size for td in self.trials]
        o = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        return [slice(int(o[j]), int(o[j + 1])) for j in range(len(self.trials))]

    def inside(self, measured: np.ndarray, *, noise: bool = True) -> np.ndarray:
        """Which samples of ``measured`` lie inside the band.

        Parameters
        ----------
        measured : numpy.ndarray
            Acceleration at the band's samples (m/s^2).
        noise : bool
            The noise band (True) or the model band.

        Returns
        -------
        numpy.ndarray of bool
        """
        lo, hi = (self.noise_low, self.noise_high) if noise else (self.model_low, self.model_high)
        y = np.asarray(measured, float)
        return (y >= lo) & (y <= hi)

    def coverage(self, measured: np.ndarray, *, noise: bool = True) -> float:
        """Share of the samples of ``measured`` inside the band (0.95 when all holds).

        Parameters
        ----------
        measured : numpy.ndarray
            Acceleration at the band's samples (m/s^2).
        noise : bool
            The noise band (True) or the model band.

        Returns
        -------
        float
        """
        ok = self.inside(measured, noise=noise)
        return float(np.mean(ok)) if ok.size else float("nan")

    def stretches(self, measured: np.ndarray) -> list[Stretch]:
        """Where the measurement leaves the noise band: the model fails there.

        A sample belongs to a stretch when at least :data:`STRETCH_SHARE` of the samples
        in a centred :data:`STRETCH_WINDOW_S` window around it lie outside the noise band
        (5 % do by chance, and a coloured noise's runs of a few samples do not fill a
        window); stretches shorter than :data:`STRETCH_MIN_S` are dropped.

        Parameters
        ----------
        measured : numpy.ndarray
            Acceleration at the band's samples (m/s^2).

        Returns
        -------
        list of Stretch
            In trial and time order.
        """
        y = np.asarray(measured, float)
        out = []
        for td, sl in zip(self.trials, self.slices(), strict=True):
            t = np.asarray(td.time, float)
            ys, lo, hi = y[sl], self.noise_low[sl], self.noise_high[sl]
            above, below = ys > hi, ys < lo
            outside = (above | below).astype(float)
            if t.size < 3:
                continue
            dt = float(np.median(np.diff(t)))
            w = max(3, round(STRETCH_WINDOW_S / dt) | 1) if dt > 0 else 3
            if w > outside.size:
                continue
            share = np.convolve(np.pad(outside, w // 2, mode="edge"), np.ones(w) / w, "valid")
            flagged = share >= STRETCH_SHARE
            for a, b in _runs(flagged):
                if t[b - 1] - t[a] < STRETCH_MIN_S:
                    continue
                side = "above" if above[a:b].sum() >= below[a:b].sum() else "below"
                out.append(
                    Stretch(
                        td.index, float(t[a]), float(t[b - 1]), float(outside[a:b].mean()), side
                    )
                )
        return out

    def to_dict(self) -> dict[str, object]:
        """A summary (the per-sample arrays are in ``to_frame`` and ``--series``)."""
        width = self.model_high - self.model_low
        return {
            "method": self.method,
            "level": self.level,
            "sigma": self.sigma,
            "model_halfwidth_max": float(np.max(width) / 2) if width.size else 0.0,
            "model_halfwidth_median": float(np.median(width) / 2) if width.size else 0.0,
        }


def band_summary(band: ResponseBand, measured: np.ndarray) -> dict[str, object]:
    """The ``band`` object of ``fit --json``: the band's widths and the measurement against it.

    Parameters
    ----------
    band : ResponseBand
        The fit's band over its own trials.
    measured : numpy.ndarray
        The measured acceleration at the band's samples (m/s^2).

    Returns
    -------
    dict
        ``method``, ``level``, ``sigma``; over all samples the model band's median and
        largest half-width, the noise band's median half-width, the share of the measured
        samples outside the noise band (``share_outside``, nominally 0.05) and the number
        of stretches where the model fails (:meth:`ResponseBand.stretches`); per trial
        (``trials``, in order) its ``index``, ``model_halfwidth_median``,
        ``noise_halfwidth_median`` and ``share_outside``.
    """
    y = np.asarray(measured, float)
    ok = np.isfinite(y)
    out_all = ~band.inside(y) & ok
    model_half = (band.model_high - band.model_low) / 2
    noise_half = (band.noise_high - band.noise_low) / 2

    def med(x: np.ndarray) -> float:
        return float(np.median(x)) if x.size else 0.0

    def share(sl: slice) -> float | None:
        n = int(ok[sl].sum())
        return float(out_all[sl].sum() / n) if n else None

    trials = [
        {
            "index": td.index,
            "model_halfwidth_median": med(model_half[sl]),
            "noise_halfwidth_median": med(noise_half[sl]),
            "share_outside": share(sl),
        }
        for td, sl in zip(band.trials, band.slices(), strict=True)
    ]
    return {
        **band.to_dict(),
        "noise_halfwidth_median": med(noise_half),
        "share_outside": share(slice(None)),
        "failing_stretches": len(band.stretches(y)),
        "trials": trials,
    }


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[a, b)`` of each run of True in ``mask``."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def covariance_of(fit: ShownFit) -> tuple[list[str], np.ndarray] | None:
    """The fit's parameter covariance, from its standard errors and correlations.

    Parameters
    ----------
    fit : ShownFit
        A simulation-matching fit.

    Returns
    -------
    (names, covariance) or None
        The fitted parameters' names (those not reached, reported as bounds, left out)
        and their covariance (widened as the standard errors are); None when a fitted
        parameter has no finite standard error. An empty list and a 0 x 0 matrix when
        nothing was fitted.
    """
    # a limit or friction the data do not reach is a bound, not an estimate: held here
    names = [
        n for n, p in fit.parameters.items() if p.vary and getattr(p, "not_reached", None) is None
    ]
    sd = np.array([fit.parameters[n].stderr or np.nan for n in names], float)
    if names and not np.all(np.isfinite(sd)):
        return None
    corr = np.eye(len(names))
    for i, a in enumerate(names):
        row = fit.correlations.get(a, {})
        for j, b in enumerate(names):
            c = row.get(b)
            if i != j and c is not None and np.isfinite(c):
                corr[i, j] = c
    return names, corr * np.outer(sd, sd)


#: Resting samples (over all trials) from which the noise is measured at rest.
REST_SAMPLES_MIN = 50


def noise_sigma(fit: ShownFit) -> float:
    """The measurement noise's standard deviation (m/s^2), not the model's misfit.

    The larger of the white-noise level of the residual's sample-to-sample differences
    (robust: a scaled median absolute deviation) and the spread of the resting samples
    before the onsets (each trial's mean removed; it holds a coloured noise's whole
    variance, which the differences partly miss). Without :data:`REST_SAMPLES_MIN`
    resting samples, the residual's standard deviation ``sqrt(chisqr / (n - k))`` (which
    holds any misfit too).

    Parameters
    ----------
    fit : ShownFit
        A fit.

    Returns
    -------
    float
    """
    diffs, rest, dof = [], [], 0
    for td, sl in zip(fit.data.trials, fit.data.slices(), strict=True):
        r = np.asarray(fit.y[sl], float) - np.asarray(fit.y_model[sl], float)
        t = np.asarray(td.time, float)[: r.size]
        ok = np.isfinite(r)
        diffs.append(np.diff(r[ok]))
        at_rest = ok & (t < td.t_step - 0.02)
        if at_rest.sum() >= 10:
            x = r[at_rest]
            rest.append(x - x.mean())
            dof += x.size - 1
    d = np.concatenate(diffs) if diffs else np.array([])
    white = 1.4826 * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2) if d.size else 0.0
    if dof >= REST_SAMPLES_MIN:
        x = np.concatenate(rest)
        return max(white, float(np.sqrt(np.einsum("i,i", x, x) / dof)))
    r = np.asarray(fit.y, float) - np.asarray(fit.y_model, float)
    r = r[np.isfinite(r)]
    k = sum(1 for p in fit.parameters.values() if p.vary)
    if r.size <= k:
        return float("nan")
    return float(np.sqrt(np.einsum("i,i", r, r) / (r.size - k)))


def response_band(
    fit: ShownFit,
    trials: Sequence[TrialData] | None = None,
    *,
    samples: np.ndarray | None = None,
    sample_names: Sequence[str] | None = None,
    values: Mapping[str, float] | None = None,
    sigma: float | None = None,
    seed: int = 0,
) -> ResponseBand:
    """The 95 % bands of ``fit``'s model on its trials, or on other (held-out) trials.

    Parameters
    ----------
    fit : ShownFit
        A simulation-matching fit (its model, values, covariance and residual).
    trials : sequence of TrialData, optional
        Where to draw the band; None: the fit's own trials.
    samples : numpy.ndarray, optional
        Posterior samples (``m x len(sample_names)``): the band is then the 2.5-97.5 %
        quantiles of the responses of up to :data:`BAND_DRAWS` of them.
    sample_names : sequence of str, optional
        The parameters of ``samples``' columns.
    values : mapping of str to float, optional
        The values to simulate at (default: the fit's).
    sigma : float, optional
        The noise's standard deviation for the noise band (default: the measurement
        noise of the fit's trials, :func:`noise_sigma`).
    seed : int
        Seed of the choice of posterior draws.

    Returns
    -------
    ResponseBand
        A band of zero width where the covariance is undefined (the simulated response
        alone; ``method`` then says ``"none"``).
    """
    model = fit.model
    chosen = list(trials) if trials is not None else list(fit.data.trials)
    data = fit.data if trials is None else FitData.build(chosen)
    vals = {**{n: p.value for n, p in fit.parameters.items()}, **dict(values or {})}
    pvec = np.asarray(model.vector(vals), float)
    sig = noise_sigma(fit) if sigma is None else float(sigma)
    if samples is not None and sample_names is not None and len(samples):
        return _sampled_band(model, data, chosen, pvec, samples, list(sample_names), sig, seed)
    cov = covariance_of(fit)
    names = cov[0] if cov is not None else []
    cols = [list(model.param_names).index(n) for n in names]
    sim = np.empty(data.y.size)
    var = np.zeros(data.y.size)
    if cov is not None and cols:
        c = cov[1]
        for first, out, sens in data.packed.stream_sens(model, pvec, cols, BAND_ROWS):
            stop = first + out.shape[0]
            sim[first:stop] = out[:, 0]
            with np.errstate(all="ignore"):
                var[first:stop] = np.einsum("ij,jk,ik->i", sens, c, sens)
        method = "covariance"
    else:
        for first, out in data.packed.stream(model, pvec, BAND_ROWS):
            sim[first : first + out.shape[0]] = out[:, 0]
        method = "covariance" if cov is not None else "none"
    half = Z95 * np.sqrt(np.where(np.isfinite(var), np.maximum(var, 0.0), 0.0))
    return _band(sim, sim - half, sim + half, sig, method, chosen)


def _band(
    sim: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    sigma: float,
    method: str,
    trials: list[TrialData],
) -> ResponseBand:
    """The band with its noise widening, each side widened in quadrature."""
    s = Z95 * (sigma if np.isfinite(sigma) else 0.0)
    below = np.sqrt((sim - low) ** 2 + s**2)
    above = np.sqrt((high - sim) ** 2 + s**2)
    return ResponseBand(sim, low, high, sim - below, sim + above, sigma, method, 0.95, trials)


def _sampled_band(
    model: Any,
    data: FitData,
    trials: list[TrialData],
    pvec: np.ndarray,
    samples: np.ndarray,
    names: list[str],
    sigma: float,
    seed: int,
) -> ResponseBand:
    """Quantiles of the responses of posterior draws."""
    rng = np.random.default_rng(seed)
    pick = samples
    if len(samples) > BAND_DRAWS:
        pick = samples[rng.choice(len(samples), BAND_DRAWS, replace=False)]
    idx = [list(model.param_names).index(n) for n in names]
    sim = data.packed.run(model, pvec)[:, 0]
    lo = np.full(sim.size, np.inf)
    hi = np.full(sim.size, -np.inf)
    draws = np.empty((len(pick), sim.size))
    for d, row in enumerate(pick):
        p = pvec.copy()
        p[idx] = row
        with np.errstate(all="ignore"):
            draws[d] = data.packed.run(model, p)[:, 0]
    draws = np.where(np.isfinite(draws), draws, sim[None, :])
    lo, hi = np.quantile(draws, [0.025, 0.975], axis=0)
    lo, hi = np.minimum(lo, sim), np.maximum(hi, sim)
    return _band(sim, lo, hi, sigma, "posterior", trials)
