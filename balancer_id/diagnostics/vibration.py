"""Human against robot: the vibration of each move around the coupled mode (paper Figs. 15-16).

A person guiding the load is a soft, well-damped "servo"; a position-controlled robot is
a stiff one, and the lag of the balancer's drive turns it into a lightly damped mode
(MODEL.md, ``servo``). For each move window this module measures the band power of the
force and of the acceleration around that mode, so the logs can be set side by side.

The mode's frequency is taken from an identified coupling when one is given, else from
the highest peak (0.2-5 Hz) of the acceleration spectra of the logs compared. The band
is half an octave either side (``f0 / sqrt 2 .. f0 sqrt 2``); the power is the
periodogram (Hann window, mean and trend removed) of the window from the move's start to
its settled end, integrated over the band and given as an RMS value.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.signal import periodogram

from balancer_id.segment.trial import Trial

#: Where the mode's peak is searched (Hz), and the half-width of the band (factor).
PEAK_RANGE_HZ = (0.2, 5.0)
BAND_FACTOR = float(np.sqrt(2.0))


@dataclass
class Spectrum:
    """A one-sided power spectral density on a uniform grid."""

    freq: np.ndarray
    psd: np.ndarray

    def band_rms(self, lo: float, hi: float) -> float:
        """RMS value of the signal's content between ``lo`` and ``hi`` Hz.

        Parameters
        ----------
        lo, hi : float
            Band edges (Hz).

        Returns
        -------
        float
            ``sqrt(integral of the PSD over the band)``.
        """
        sel = (self.freq >= lo) & (self.freq <= hi)
        if sel.sum() < 2:
            return float("nan")
        return float(np.sqrt(np.trapezoid(self.psd[sel], self.freq[sel])))

    def total_rms(self) -> float:
        """RMS value of the whole signal (trend removed) from the same spectrum, so that a
        band's RMS (:meth:`band_rms`) never exceeds it.

        Returns
        -------
        float
        """
        if self.freq.size < 2:
            return float("nan")
        return float(np.sqrt(np.trapezoid(self.psd, self.freq)))


@dataclass
class MoveVibration:
    """The vibration of one move window.

    Attributes
    ----------
    source : str
        File and run.
    accel_band_rms, force_band_rms : float
        RMS of acceleration (m/s^2) and force (N) in the band around the mode.
    accel_rms, force_rms : float
        RMS of the detrended acceleration and force over the window.
    peak_hz : float
        The acceleration spectrum's highest peak in :data:`PEAK_RANGE_HZ`.
    time, accel, force : numpy.ndarray
        The window's signals (for plots); ``force`` may be empty.
    accel_spectrum, force_spectrum : Spectrum or None
        Their spectra.
    """

    source: str
    accel_band_rms: float
    force_band_rms: float
    accel_rms: float
    force_rms: float
    peak_hz: float
    time: np.ndarray = field(repr=False)
    accel: np.ndarray = field(repr=False)
    force: np.ndarray = field(repr=False)
    accel_spectrum: Spectrum | None = field(default=None, repr=False)
    force_spectrum: Spectrum | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "source": self.source,
            "accel_band_rms": self.accel_band_rms,
            "force_band_rms": self.force_band_rms,
            "accel_rms": self.accel_rms,
            "force_rms": self.force_rms,
            "peak_hz": self.peak_hz,
        }


@dataclass
class VibrationComparison:
    """Band power around the coupled mode for several moves, side by side.

    Attributes
    ----------
    mode_hz : float
        The coupled mode's frequency (Hz).
    band_hz : tuple of float
        The band's edges (Hz).
    mode_from : str
        Where ``mode_hz`` came from (an identified coupling, or the spectra's peak).
    moves : list of MoveVibration
        One per move window, in the order of the logs.
    """

    mode_hz: float
    band_hz: tuple[float, float]
    mode_from: str
    moves: list[MoveVibration]

    def to_dict(self) -> dict[str, object]:
        """The ``vibration`` record of ``compare --json``."""
        return {
            "mode_hz": self.mode_hz,
            "band_hz": list(self.band_hz),
            "mode_from": self.mode_from,
            "moves": [m.to_dict() for m in self.moves],
        }

    def lines(self) -> list[str]:
        """Short lines of text: one per move, and the ratio of the extremes."""
        return vibration_lines(self.to_dict())


def vibration_lines(vibration: Mapping[str, Any]) -> list[str]:
    """Short lines of text from a ``vibration`` record (:meth:`VibrationComparison.to_dict`).

    Parameters
    ----------
    vibration : mapping
        The ``vibration`` object of ``compare --json``.

    Returns
    -------
    list of str
        The band, one line per move, and the ratio of the most to the least vibrating.
    """
    lo, hi = vibration["band_hz"]
    out = [
        f"vibration around the coupled mode {vibration['mode_hz']:.3g} Hz "
        f"({vibration['mode_from']}), band {lo:.3g}-{hi:.3g} Hz:"
    ]
    moves = vibration["moves"]
    for m in moves:
        out.append(
            f"  {m['source']}: acceleration {m['accel_band_rms']:.3g} m/s^2 RMS in band "
            f"(of {m['accel_rms']:.3g}), force {m['force_band_rms']:.3g} N RMS in band "
            f"(of {m['force_rms']:.3g}); peak at {m['peak_hz']:.3g} Hz"
        )
    a = [m["accel_band_rms"] for m in moves if np.isfinite(m["accel_band_rms"])]
    if len(a) >= 2 and min(a) > 0:
        out.append(f"  the most vibrating move has {max(a) / min(a):.1f} x the band acceleration")
    return out


def spectrum(time: np.ndarray, x: np.ndarray) -> Spectrum:
    """Periodogram of ``x`` (Hann window, linear trend removed) on a uniform time grid.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s); gaps are bridged by linear interpolation.
    x : numpy.ndarray
        The signal.

    Returns
    -------
    Spectrum
        Zero-padded to four times the window for a smooth curve.
    """
    time = np.asarray(time, dtype=float)
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x) & np.isfinite(time)
    time, x = time[ok], x[ok]
    dt = float(np.median(np.diff(time)))
    grid = np.arange(time[0], time[-1], dt)
    y = np.interp(grid, time, x)
    f, p = periodogram(y, fs=1.0 / dt, window="hann", detrend="linear", nfft=4 * y.size)
    return Spectrum(f, p)


def _peak(sp: Spectrum) -> float:
    sel = (sp.freq >= PEAK_RANGE_HZ[0]) & (sp.freq <= PEAK_RANGE_HZ[1])
    if not sel.any():
        return float("nan")
    return float(sp.freq[sel][np.argmax(sp.psd[sel])])


def compare_vibration(
    moves: Sequence[Trial], mode_hz: float | None = None, mode_from: str = ""
) -> VibrationComparison:
    """Band power of force and acceleration around the coupled mode, per move window.

    Parameters
    ----------
    moves : sequence of Trial
        Move windows (:class:`~balancer_id.segment.move.MoveTrial`), e.g. one from a
        human-assist log and one from a robot-assist log of the same move.
    mode_hz : float, optional
        The coupled mode's frequency; None takes the highest acceleration peak in
        :data:`PEAK_RANGE_HZ` over all moves.
    mode_from : str
        Where a given ``mode_hz`` comes from (for the text).

    Returns
    -------
    VibrationComparison

    Raises
    ------
    ValueError
        When no move is given.
    """
    if not moves:
        raise ValueError("compare_vibration: no move window given")
    parts = []
    peaks = []
    for tr in moves:
        t0 = float(tr.t_step)
        sel = np.asarray(tr.time) >= t0
        time = np.asarray(tr.time, dtype=float)[sel]
        accel = np.asarray(tr.accel, dtype=float)[sel]
        force = np.asarray(tr.force, dtype=float)[sel] if tr.force is not None else np.empty(0)
        sa = spectrum(time, accel)
        sf = spectrum(time, force) if force.size == time.size and force.size > 8 else None
        sel_pk = (sa.freq >= PEAK_RANGE_HZ[0]) & (sa.freq <= PEAK_RANGE_HZ[1])
        peaks.append(float(sa.psd[sel_pk].max()) if sel_pk.any() else 0.0)
        parts.append((tr, time, accel, force, sa, sf))
    if mode_hz is None or not np.isfinite(mode_hz) or mode_hz <= 0:
        k = int(np.argmax(peaks))
        mode_hz = _peak(parts[k][4])
        mode_from = f"the acceleration spectrum's peak of {parts[k][0].source or 'move ' + str(k)}"
    lo, hi = mode_hz / BAND_FACTOR, mode_hz * BAND_FACTOR
    out = []
    for tr, time, accel, force, sa, sf in parts:
        out.append(
            MoveVibration(
                source=f"{tr.source} [{tr.recording}]",
                accel_band_rms=sa.band_rms(lo, hi),
                force_band_rms=sf.band_rms(lo, hi) if sf is not None else float("nan"),
                accel_rms=sa.total_rms(),
                force_rms=sf.total_rms() if sf is not None else float("nan"),
                peak_hz=_peak(sa),
                time=time,
                accel=accel,
                force=force,
                accel_spectrum=sa,
                force_spectrum=sf,
            )
        )
    return VibrationComparison(float(mode_hz), (lo, hi), mode_from or "given", out)
