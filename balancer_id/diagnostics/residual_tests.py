"""Statistical tests on the residual: whiteness, input correlation, spectrum, regimes."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from balancer_id.diagnostics.context import REGIMES, DiagnosisContext
from balancer_id.identify.data import thrust_levels

#: Lags of the whiteness tests (samples).
ACF_LAGS = 25


def autocorrelation(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation of ``x`` at lags ``1..max_lag``.

    Parameters
    ----------
    x : numpy.ndarray
        One series (a trial's residual); its mean is removed first.
    max_lag : int
        Largest lag (samples).

    Returns
    -------
    numpy.ndarray
        ``max_lag`` autocorrelations; zeros for a constant series.
    """
    x = np.asarray(x, float) - np.mean(x)
    denom = float(x @ x)
    if denom == 0:
        return np.zeros(max_lag)
    return np.array([float(x[:-k] @ x[k:]) / denom for k in range(1, max_lag + 1)])


def whiteness(ctx: DiagnosisContext, max_lag: int = ACF_LAGS) -> dict[str, object]:
    """Autocorrelation of the residual with its 95 % band, and the Ljung-Box test.

    The autocorrelation is averaged over trials (each trial's residual is its own series),
    so trial boundaries do not count as correlation.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.
    max_lag : int
        Lags tested (samples); trials shorter than ``3 * max_lag`` are left out.

    Returns
    -------
    dict
        ``n`` (samples used), ``acf``, ``band`` (the 95 % band ``1.96 / sqrt(n)``),
        ``outside_band`` (lags beyond it), ``ljung_box_q`` and ``ljung_box_p``; all but
        ``n`` and ``acf`` are None when no trial is long enough.
    """
    from scipy.special import chdtrc

    acfs, weights = [], []
    for tv in ctx.trials:
        if tv.residual.size > 3 * max_lag:
            acfs.append(autocorrelation(tv.residual, max_lag))
            weights.append(tv.residual.size)
    n = int(sum(weights))
    if not acfs:
        return {
            "n": n,
            "acf": [],
            "band": None,
            "outside_band": None,
            "ljung_box_q": None,
            "ljung_box_p": None,
        }
    acf = np.average(np.array(acfs), axis=0, weights=weights)
    band = 1.96 / np.sqrt(n)
    k = np.arange(1, max_lag + 1)
    q = float(n * (n + 2) * np.sum(acf**2 / (n - k)))
    return {
        "n": n,
        "acf": [round(float(a), 4) for a in acf],
        "band": float(band),
        "outside_band": int(np.sum(np.abs(acf) > band)),
        "ljung_box_q": q,
        "ljung_box_p": float(chdtrc(max_lag, q)),
    }


def input_correlation(ctx: DiagnosisContext, max_lag_s: float = 1.5) -> dict[str, object]:
    """Cross-correlation of the residual with the thrust step, as a function of lag.

    The same as :meth:`DiagnosisContext.input_correlation
    <balancer_id.diagnostics.context.DiagnosisContext.input_correlation>` (a method there,
    so that the signature checks of the effects can call it).

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.
    max_lag_s : float
        Latest time after the onset to look at (s); the lags start 0.3 s before the onset.

    Returns
    -------
    dict
        ``lag_s`` and ``mean_residual`` (m/s^2) per lag, the Bonferroni-corrected 95 %
        ``band``, ``peak_lag_s``, ``peak_value`` and whether the peak is ``significant``.
    """
    return ctx.input_correlation(max_lag_s)


def spectrum_peaks(ctx: DiagnosisContext, factor: float = 8.0) -> dict[str, object]:
    """Welch spectrum of the residual; narrow peaks above ``factor`` x the median level.

    The same as :meth:`DiagnosisContext.spectrum_peaks
    <balancer_id.diagnostics.context.DiagnosisContext.spectrum_peaks>` (a method there, so
    that the signature checks of the effects can call it).

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.
    factor : float
        How far above the median spectral level a peak must rise to count.

    Returns
    -------
    dict
        ``peaks``: up to five ``{"frequency_hz", "ratio_to_median"}``, strongest first;
        ``frequency_hz`` and ``psd``: the spectrum averaged over trials.
    """
    return ctx.spectrum_peaks(factor)


def regime_table(ctx: DiagnosisContext) -> list[dict[str, object]]:
    """Residual mean and RMS per regime, per direction and per operating-force bin.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    list of dict
        Rows of ``group``, ``label``, ``n``, ``mean``, ``rms`` (m/s^2) and
        ``rms_over_noise``; groups with fewer than five samples are left out.
    """
    rows: list[dict[str, object]] = []

    def add(group: str, label: str, parts: list[np.ndarray]) -> None:
        r = np.concatenate(parts) if parts else np.array([])
        if r.size >= 5:
            rows.append(
                {
                    "group": group,
                    "label": label,
                    "n": int(r.size),
                    "mean": float(np.mean(r)),
                    "rms": float(np.sqrt(np.mean(r**2))),
                    "rms_over_noise": float(np.sqrt(np.mean(r**2)) / max(ctx.noise_floor, 1e-12)),
                }
            )

    for name in REGIMES:
        add("regime", name, [tv.residual[tv.regimes[name]] for tv in ctx.trials])
    for d in ("up", "down"):
        add("direction", d, [tv.residual for tv in ctx.trials if tv.data.direction == d])
    levels = thrust_levels([tv.data for tv in ctx.trials])
    for lo, hi in zip(levels, [*levels[1:], np.inf], strict=True):
        add(
            "|h| bin",
            f"~{lo:.2f} N",
            [tv.residual for tv in ctx.trials if lo <= abs(tv.data.thrust_N) < hi],
        )
    return rows


def state_correlations(ctx: DiagnosisContext) -> dict[str, float]:
    """Correlation of the residual with the simulated states during motion.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    dict of str to float
        Pearson correlation with ``velocity``, ``position``, ``drive force`` and
        ``time`` (signed by the thrust), over the samples after the onsets; a state
        that does not vary is left out.
    """
    res: list[Any] = []
    states: dict[str, list[Any]] = {"velocity": [], "position": [], "drive force": [], "time": []}
    for tv in ctx.trials:
        m = tv.t >= 0
        res.append(tv.residual[m])
        states["velocity"].append(tv.v[m])
        states["position"].append(tv.z[m])
        states["drive force"].append(tv.f[m])
        states["time"].append(tv.t[m] * np.sign(tv.data.thrust_N))
    r = np.concatenate(res)
    out = {}
    for name, parts in states.items():
        x = np.concatenate(parts)
        if np.std(x) > 0 and np.std(r) > 0:
            out[name] = float(np.corrcoef(r, x)[0, 1])
    return out


def worst_windows(ctx: DiagnosisContext, width_s: float = 0.5, count: int = 3) -> list[dict]:
    """The time windows with the largest residual RMS (trial, start, end, rmse).

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.
    width_s : float
        Length of a window (s).
    count : int
        Windows to return at most; each trial contributes its worst window only.

    Returns
    -------
    list of dict
        ``trial``, ``t_start`` and ``t_end`` (s, log time) and ``rmse`` (m/s^2), worst
        first.
    """
    found = []
    for tv in ctx.trials:
        w = max(round(width_s / ctx.dt), 1)
        if tv.residual.size < w:
            continue
        c = np.convolve(tv.residual**2, np.ones(w) / w, mode="valid")
        k = int(np.argmax(c))
        found.append(
            {
                "trial": tv.data.index,
                "t_start": float(tv.data.time[k]),
                "t_end": float(tv.data.time[min(k + w, tv.data.time.size - 1)]),
                "rmse": float(np.sqrt(c[k])),
            }
        )
    found.sort(key=lambda r: -r["rmse"])
    return found[:count]


@dataclass
class ResidualTests:
    """The residual tests of a fit (CONTRACT.md ``diagnose`` ``residual_tests``).

    Attributes
    ----------
    noise_floor : float
        Acceleration noise (m/s^2).
    whiteness : dict
        Autocorrelation, its band and the Ljung-Box test
        (:func:`~balancer_id.diagnostics.residual_tests.whiteness`).
    input_cross_correlation : dict
        The residual against the thrust step, its peak and significance.
    spectrum : dict
        ``peaks`` of the residual's spectrum.
    regimes : list of dict
        The residual by regime, direction and thrust level.
    state_correlation : dict of str to float
        Correlation of the residual with each simulated state.
    worst_windows : list of dict
        Where the residual is largest.
    paper_line : dict
        ``m_a``, ``intercept_N`` and ``free_slope`` of the paper's method.
    parameter_drift : list of dict
        Per-trial refits: each parameter's slope against thrust and up/down difference.
    parameter_groups : dict or None
        A parameter that changed between runs (payload, setting), with its per-run
        estimates and the split test; None when none did.
    input_cross_correlation_curve : dict
        :attr:`input_cross_correlation` with its curve (``lag_s``, ``mean_residual``).
    """

    noise_floor: float
    whiteness: dict[str, object]
    input_cross_correlation: dict[str, object]
    spectrum: dict[str, object]
    regimes: list[dict[str, object]]
    state_correlation: dict[str, float]
    worst_windows: list[dict[str, object]]
    paper_line: dict[str, float]
    parameter_drift: list[dict[str, object]]
    parameter_groups: dict[str, object] | None = None
    #: The cross-correlation with its ``lag_s`` and ``mean_residual`` curve (for the
    #: report's plot; the JSON keeps the peak and the band only).
    input_cross_correlation_curve: dict[str, object] = field(default_factory=dict, repr=False)

    def __getitem__(self, key: str) -> object:
        """The test named ``key``, as in :meth:`to_dict`.

        Parameters
        ----------
        key : str
            A key of the CONTRACT.md ``residual_tests`` object.

        Returns
        -------
        object
        """
        if key not in self.__dataclass_fields__:
            raise KeyError(key)
        return getattr(self, key)

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``residual_tests`` object."""
        return {
            "noise_floor": self.noise_floor,
            "whiteness": self.whiteness,
            "input_cross_correlation": self.input_cross_correlation,
            "spectrum": self.spectrum,
            "regimes": self.regimes,
            "state_correlation": self.state_correlation,
            "worst_windows": self.worst_windows,
            "paper_line": self.paper_line,
            "parameter_drift": self.parameter_drift,
            **({"parameter_groups": self.parameter_groups} if self.parameter_groups else {}),
        }
