"""The human-against-robot figure (paper Figs. 15 and 16): force, acceleration, spectra."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from balancer_id.diagnose.vibration import VibrationComparison
from balancer_id.report.plots import _finish, _format_axes, _new_figure


def plot_vibration(comparison: VibrationComparison, path: str | Path | None = None):
    """Force and acceleration of each move side by side, and their spectra around the mode.

    One column per move: the force (top) and the vertical acceleration (middle) from the
    move's start, and the acceleration spectrum (bottom) with the band around the coupled
    mode shaded and its RMS value written in.

    Parameters
    ----------
    comparison : VibrationComparison
        From :func:`balancer_id.diagnose.vibration.compare_vibration`.
    path : str or Path, optional
        Write a PNG here (atomically) instead of returning the figure.

    Returns
    -------
    Figure or Path
    """
    moves = comparison.moves
    n = len(moves)
    fig = _new_figure(4.2 * n + 0.6, 7.5)
    axes = fig.subplots(3, n, squeeze=False)
    lo, hi = comparison.band_hz
    a_lim = max(float(np.nanmax(np.abs(m.accel))) for m in moves) * 1.1
    f_vals = [np.nanmax(np.abs(m.force)) for m in moves if m.force.size]
    f_lim = max(f_vals) * 1.1 if f_vals else 1.0
    top = max(float(np.max(m.accel_spectrum.psd)) for m in moves if m.accel_spectrum) * 1.2
    for j, m in enumerate(moves):
        t = m.time - m.time[0]
        ax = axes[0, j]
        _format_axes(ax)
        if m.force.size:
            ax.plot(t, m.force, color="#0072B2", linewidth=0.8)
        ax.set_ylim(-f_lim, f_lim)
        ax.set_title(
            f"{Path(m.source.split(' [')[0]).name}\nforce: {m.force_band_rms:.3g} N RMS in band",
            fontsize=9,
            loc="left",
        )
        ax.set_ylabel("force change (N)", fontsize=8)
        ax = axes[1, j]
        _format_axes(ax)
        ax.plot(t, m.accel, color="#D55E00", linewidth=0.8)
        ax.set_ylim(-a_lim, a_lim)
        ax.set_title(
            f"acceleration: {m.accel_band_rms:.3g} m/s² RMS in band", fontsize=9, loc="left"
        )
        ax.set_ylabel("vertical accel. (m/s²)", fontsize=8)
        ax.set_xlabel("time from the move's start (s)", fontsize=8)
        ax = axes[2, j]
        _format_axes(ax)
        sp = m.accel_spectrum
        if sp is not None:
            sel = sp.freq <= 5.0
            ax.plot(sp.freq[sel], sp.psd[sel], color="black", linewidth=0.9)
        ax.axvspan(lo, hi, color="#009E73", alpha=0.15, label=f"mode {comparison.mode_hz:.3g} Hz")
        ax.set_ylim(0, top)
        ax.set_xlabel("frequency (Hz)", fontsize=8)
        ax.set_ylabel("accel. PSD ((m/s²)²/Hz)", fontsize=8)
        ax.legend(fontsize=7, loc="upper right")
    return _finish(fig, path)
