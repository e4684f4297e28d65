"""Welch spectrum and prominent peaks in numpy.

``scipy.signal`` loads ``scipy.stats`` on import (more than half a second of start-up,
much of ``diagnose``'s own time); the residual spectrum needs two of its functions only,
written here with numpy and checked against scipy in ``tests/test_spectra.py``.
"""

from __future__ import annotations

import numpy as np

from balancer_id.segment.robust import find_peaks


def welch_psd(x: np.ndarray, fs: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """One-sided power spectral density by Welch's method.

    The same as ``scipy.signal.welch(x, fs, nperseg=nperseg, detrend="linear")``: periodic
    Hann window, half-overlapping segments, a straight line removed from each segment,
    density scaling, segments averaged by their mean.

    Parameters
    ----------
    x : numpy.ndarray
        The signal, at least ``nperseg`` samples.
    fs : float
        Sampling rate in Hz.
    nperseg : int
        Samples per segment.

    Returns
    -------
    frequency : numpy.ndarray
        ``nperseg // 2 + 1`` frequencies in Hz.
    psd : numpy.ndarray
        The density in units of ``x`` squared per Hz.
    """
    x = np.asarray(x, dtype=float)
    nperseg = int(min(nperseg, x.size))
    step = nperseg - nperseg // 2
    count = (x.size - nperseg) // step + 1
    starts = np.arange(count) * step
    segments = x[starts[:, None] + np.arange(nperseg)]
    t = np.arange(nperseg, dtype=float)
    t -= t.mean()
    means = segments.mean(axis=1, keepdims=True)
    slopes = (segments @ t)[:, None] / float(t @ t)
    segments = segments - means - slopes * t
    window = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(nperseg) / nperseg)
    spectra = np.abs(np.fft.rfft(segments * window, axis=1)) ** 2
    spectra /= fs * float(window @ window)
    if nperseg % 2:
        spectra[:, 1:] *= 2.0
    else:
        spectra[:, 1:-1] *= 2.0
    return np.fft.rfftfreq(nperseg, 1.0 / fs), spectra.mean(axis=0)


def prominences(x: np.ndarray, peaks: np.ndarray) -> np.ndarray:
    """How far each peak rises above the higher of its two bases.

    A base is the lowest sample between the peak and the nearest higher sample on that
    side (or the end of the signal), as ``scipy.signal.peak_prominences``.

    Parameters
    ----------
    x : numpy.ndarray
        The signal.
    peaks : numpy.ndarray
        Indices of peaks in ``x``.

    Returns
    -------
    numpy.ndarray
        One prominence per peak.
    """
    x = np.asarray(x, dtype=float)
    out = np.empty(len(peaks))
    for k, i in enumerate(peaks):
        higher = np.flatnonzero(x[:i] > x[i])
        left = x[higher[-1] + 1 if higher.size else 0 : i + 1].min()
        higher = np.flatnonzero(x[i + 1 :] > x[i])
        right = x[i : i + 1 + higher[0] if higher.size else x.size].min()
        out[k] = x[i] - max(left, right)
    return out


def prominent_peaks(x: np.ndarray, height: float, prominence: float) -> np.ndarray:
    """Local maxima at least ``height`` high and ``prominence`` above their bases.

    Parameters
    ----------
    x : numpy.ndarray
        The signal.
    height : float
        Minimum height.
    prominence : float
        Minimum prominence (:func:`prominences`).

    Returns
    -------
    numpy.ndarray
        The peaks' indices, increasing.
    """
    peaks = find_peaks(x, height, 1)
    return peaks[prominences(x, peaks) >= prominence]
