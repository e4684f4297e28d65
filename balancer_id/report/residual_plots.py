"""The residual analysis of a fit, drawn as MATLAB's ``resid`` does.

Top: the residual's autocorrelation with its 95 % band (whiteness) and its correlation
with the thrust step against the time since the onset, with the band of the test. Bottom:
the residual against the simulated position, velocity and drive force (the thrust seen
through the drive's lag); a trend there is an effect the model lacks. Everything drawn
is what the diagnosis computed (its tests and its trial views); nothing is refitted.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from balancer_id.report.plots import _format_axes, _new_figure

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from balancer_id.diagnostics.diagnosis import Diagnosis

__all__ = ["plot_residual_analysis"]

#: Points drawn per scatter panel at most (evenly thinned; the trend stays visible).
MAX_POINTS = 4000


def _thin(*arrays: np.ndarray) -> list[np.ndarray]:
    n = arrays[0].size
    step = max(1, n // MAX_POINTS)
    return [a[::step] for a in arrays]


def _binned_mean(x: np.ndarray, r: np.ndarray, bins: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """The residual's mean in equal-count bins of ``x`` (the trend line)."""
    if x.size < 2 * bins:
        return np.array([]), np.array([])
    order = np.argsort(x)
    parts = np.array_split(order, bins)
    return (
        np.array([float(np.mean(x[p])) for p in parts]),
        np.array([float(np.mean(r[p])) for p in parts]),
    )


def _scatter(ax: Axes, x: np.ndarray, r: np.ndarray, label: str, noise: float) -> None:
    _format_axes(ax)
    xs, rs = _thin(x, r)
    ax.scatter(xs, rs, s=2, color="#9DB9D3", alpha=0.5, linewidths=0, rasterized=True)
    bx, br = _binned_mean(x, r)
    if bx.size:
        ax.plot(bx, br, color="#D55E00", lw=1.8, label="binned mean")
    if np.isfinite(noise) and noise > 0:
        for s in (-noise, noise):
            ax.axhline(s, color="0.5", lw=0.7, ls=":")
    ax.axhline(0.0, color="0.3", lw=0.6)
    ax.set_xlabel(label, fontsize=8)
    ax.set_ylabel("residual (m/s²)", fontsize=8)
    if np.any(np.isfinite(x)) and np.size(x) > 2 and np.std(x) > 0:
        c = float(np.corrcoef(x, r)[0, 1])
        ax.set_title(f"r = {c:+.2f}", fontsize=8)


def plot_residual_analysis(diagnosis: Diagnosis) -> Figure:
    """Autocorrelation, cross-correlation with the thrust, residual against the states.

    Parameters
    ----------
    diagnosis : Diagnosis
        A diagnosis (its ``tests`` and ``context`` are drawn as they are).

    Returns
    -------
    matplotlib.figure.Figure
        Five panels: the residual's autocorrelation with its 95 % band, its
        cross-correlation with the thrust step with the band, and the residual against
        the simulated position, velocity and drive force.
    """
    fig = _new_figure(10.0, 6.2)
    grid = fig.add_gridspec(2, 6)
    ax_acf = fig.add_subplot(grid[0, :3])
    ax_xc = fig.add_subplot(grid[0, 3:])
    ax_z = fig.add_subplot(grid[1, :2])
    ax_v = fig.add_subplot(grid[1, 2:4])
    ax_f = fig.add_subplot(grid[1, 4:])

    w = diagnosis.tests.whiteness
    _format_axes(ax_acf)
    acf = np.asarray(w.get("acf") or [], dtype=float)
    dt = diagnosis.context.dt
    if acf.size:
        lags = np.arange(1, acf.size + 1) * dt
        ax_acf.vlines(lags, 0.0, acf, color="#0072B2", lw=1.0)
        band = float(w.get("band") or 0.0)  # type: ignore[arg-type]
        if band:
            ax_acf.axhspan(-band, band, color="#E69F00", alpha=0.2, label="95 % band")
            ax_acf.legend(fontsize=7, loc="upper right")
    else:
        ax_acf.text(0.5, 0.5, "trials too short", ha="center", va="center", color="0.4")
    ax_acf.axhline(0.0, color="0.3", lw=0.6)
    ax_acf.set_xlabel("lag (s)", fontsize=8)
    ax_acf.set_ylabel("autocorrelation", fontsize=8)
    p = w.get("ljung_box_p")
    ax_acf.set_title(
        "whiteness" + (f": Ljung-Box p = {p:.2g}" if p is not None else ""), fontsize=9
    )

    xc = diagnosis.tests.input_cross_correlation_curve or diagnosis.tests.input_cross_correlation
    _format_axes(ax_xc)
    lag_s = np.asarray(xc.get("lag_s") or [], dtype=float)
    mean = np.asarray(xc.get("mean_residual") or [], dtype=float)
    if lag_s.size:
        ax_xc.plot(lag_s, mean, color="#0072B2", lw=1.2)
        band = float(xc.get("band") or 0.0)  # type: ignore[arg-type]
        ax_xc.axhspan(-band, band, color="#E69F00", alpha=0.2, label="95 % band")
        ax_xc.axvline(0.0, color="0.5", lw=0.6, ls="--")
        ax_xc.legend(fontsize=7, loc="upper right")
    ax_xc.axhline(0.0, color="0.3", lw=0.6)
    ax_xc.set_xlabel("time since the thrust onset (s)", fontsize=8)
    ax_xc.set_ylabel("residual × sign(thrust) (m/s²)", fontsize=8)
    ax_xc.set_title(
        "cross-correlation with the thrust: "
        + ("significant" if xc.get("significant") else "within the band"),
        fontsize=9,
    )

    trials = diagnosis.context.trials
    r = np.concatenate([tv.residual for tv in trials]) if trials else np.array([])
    noise = float(diagnosis.context.noise_floor)
    for ax, key, label in (
        (ax_z, "z", "simulated position (m)"),
        (ax_v, "v", "simulated velocity (m/s)"),
        (ax_f, "f", "drive force: the thrust through the lag (N)"),
    ):
        x = np.concatenate([getattr(tv, key) for tv in trials]) if trials else np.array([])
        ok = np.isfinite(x) & np.isfinite(r)
        _scatter(ax, x[ok], r[ok], label, noise)
    fig.suptitle(
        "Residual analysis (dotted: ± the noise floor; a trend or a lag outside the band is "
        "structure the model lacks)",
        fontsize=9,
    )
    return fig
