"""Robust statistics and windowed filters shared by the segmentation modules."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import ndimage


def n_samples(seconds: float, rate_hz: float, minimum: int = 1) -> int:
    """Return the number of samples that spans ``seconds`` at ``rate_hz`` (at least ``minimum``).

    Parameters
    ----------
    seconds : float
        Duration (s).
    rate_hz : float
        Sample rate (Hz).
    minimum : int, optional
        Smallest count returned.

    Returns
    -------
    int
        ``max(minimum, round(seconds * rate_hz))``.
    """
    return max(minimum, round(seconds * rate_hz))


def odd(n: int) -> int:
    """Return ``n`` if odd, else ``n + 1`` (filter kernels need a centre sample).

    Parameters
    ----------
    n : int
        A kernel length (samples).

    Returns
    -------
    int
    """
    return n if n % 2 else n + 1


def median(x: np.ndarray, *, overwrite: bool = False) -> float:
    """``float(np.median(x))`` of a 1-D float array, bit for bit, without its overhead.

    The segmenters take hundreds of medians of short stretches a log; ``np.median``'s
    generic machinery (axes, ``out``, dispatch) costs more than the partition itself.
    The same partition and the same mean of the middle pair give the same bits; NaN
    anywhere gives NaN, an empty array NaN (without numpy's warning).

    Parameters
    ----------
    x : numpy.ndarray
        One-dimensional samples.
    overwrite : bool, optional
        Partition ``x`` itself (a temporary of the caller's) instead of a copy.

    Returns
    -------
    float
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    if n == 0:
        return float("nan")
    half = n // 2
    kth = (half - 1, half, n - 1) if n % 2 == 0 else (half, n - 1)
    if overwrite and x.flags.writeable:
        x.partition(kth)  # in place: the caller's own temporary, no copy of a long log
        part = x
    else:
        part = np.partition(x, kth)
    if np.isnan(part[-1]):
        return float("nan")
    if n % 2:
        return float(part[half])
    return float((part[half - 1] + part[half]) / 2.0)


def rate_of(time: np.ndarray) -> float:
    """Return the sample rate (Hz) from the median time step of ``time``.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s); non-finite and non-positive steps (gaps in the record, repeats)
        are ignored.

    Returns
    -------
    float
        ``1 / median(dt)`` (Hz), NaN when there is no positive step.
    """
    dt = np.diff(time)
    good = np.isfinite(dt) & (dt > 0)
    if not good.all():
        dt = dt[good]
    if dt.size == 0:
        return float("nan")
    return float(1.0 / median(dt, overwrite=True))


def fill_nan(x: np.ndarray) -> np.ndarray:
    """Return ``x`` with NaN samples linearly interpolated (edges held).

    Parameters
    ----------
    x : numpy.ndarray
        One-dimensional signal with at least one finite sample.

    Returns
    -------
    numpy.ndarray
        A float copy without NaN; where ``x`` has none, a read-only view of it (a long
        log's channels are not copied to be left as they are).
    """
    x = np.asarray(x, dtype=float)
    bad = ~np.isfinite(x)
    if not bad.any():
        view = x.view()
        view.flags.writeable = False
        return view
    x = x.copy()
    idx = np.arange(x.size)
    x[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
    return x


def smooth(x: np.ndarray, size: int) -> np.ndarray:
    """Median filter then moving average, both of ``size`` samples (spikes, then noise).

    Parameters
    ----------
    x : numpy.ndarray
        One-dimensional signal.
    size : int
        Kernel length in samples (made odd).

    Returns
    -------
    numpy.ndarray
        The smoothed signal, same length.
    """
    size = odd(size)
    if size <= 1:
        return np.asarray(x, dtype=float)
    med = ndimage.median_filter(np.asarray(x, dtype=float), size=size, mode="nearest")
    # in place (the 1-D filters work through a line buffer): one signal-long array
    return ndimage.uniform_filter1d(med, size=size, mode="nearest", output=med)


def local_std(x: np.ndarray, size: int) -> np.ndarray:
    """Centred moving standard deviation over ``size`` samples.

    Parameters
    ----------
    x : numpy.ndarray
        One-dimensional signal.
    size : int
        Window length (samples); the edges repeat the end samples.

    Returns
    -------
    numpy.ndarray
        The standard deviation around each sample, same length as ``x``.
    """
    x = np.asarray(x, dtype=float)
    m = ndimage.uniform_filter1d(x, size=size, mode="nearest")
    m2 = ndimage.uniform_filter1d(x * x, size=size, mode="nearest")
    return np.sqrt(np.clip(m2 - m * m, 0.0, None))


def before_after_means(x: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Means of the ``w`` samples before and from each index.

    Parameters
    ----------
    x : numpy.ndarray
        One-dimensional signal.
    w : int
        Window length (samples).

    Returns
    -------
    before, after : numpy.ndarray
        ``before[i] = mean(x[i-w:i])`` and ``after[i] = mean(x[i:i+w])``; NaN where the
        window leaves the signal.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    c = np.concatenate([[0.0], np.cumsum(x - x.mean())])
    before = np.full(n, np.nan)
    after = np.full(n, np.nan)
    if n >= w:  # slices, not index arrays: no temporary the size of the signal
        np.subtract(c[w:n], c[: n - w], out=before[w:])
        before[w:] /= w
        np.subtract(c[w:], c[: n - w + 1], out=after[: n - w + 1])
        after[: n - w + 1] /= w
    return before, after


#: Samples per batch of blocks in the block statistics (bounds their working memory).
BLOCK_BATCH = 1 << 18


def _detrended_block_stat(
    x: np.ndarray, block: int, stat: Callable[[np.ndarray], np.ndarray]
) -> np.ndarray:
    """``stat`` (per row) of ``x`` cut into blocks of ``block`` samples, each minus its
    least-squares line; the blocks are detrended a batch at a time, so that no copy of
    the whole signal is made."""
    nb = x.size // block
    t = np.arange(block) - (block - 1) / 2.0
    per_batch = max(1, BLOCK_BATCH // block)
    out = np.empty(nb)
    for first in range(0, nb, per_batch):
        last = min(nb, first + per_batch)
        blocks = np.asarray(x[first * block : last * block], dtype=float).reshape(-1, block)
        centred = blocks - blocks.mean(axis=1, keepdims=True)
        slope = centred @ t / (t @ t)
        centred -= slope[:, None] * t
        out[first:last] = stat(centred)
    return out


def block_noise(x: np.ndarray, block: int, floor: float) -> float:
    """Typical noise standard deviation: the median over blocks of the detrended block std.

    Blocks with motion or transients are a minority in a log, so the median sees rest.

    Parameters
    ----------
    x : numpy.ndarray
        One-dimensional signal.
    block : int
        Block length (samples).
    floor : float
        Smallest value returned (clean or coarsely quantized data can give 0).

    Returns
    -------
    float
        Noise standard deviation estimate.
    """
    x = np.asarray(x, dtype=float)
    if x.size < block or block < 3:
        return float(max(floor, np.std(x) if x.size > 1 else 0.0))
    spread = _detrended_block_stat(x, block, lambda b: np.std(b, axis=1))
    return float(max(floor, median(spread)))


def block_range(x: np.ndarray, block: int) -> float:
    """Typical peak-to-peak range of a detrended block (covers noise and quantization).

    Parameters
    ----------
    x : numpy.ndarray
        One-dimensional signal.
    block : int
        Block length (samples); with fewer than ``block`` samples, or a block shorter
        than 3, the range of the whole signal is returned.

    Returns
    -------
    float
        The median over blocks of the detrended block's peak-to-peak range (same unit as
        ``x``), 0 for an empty signal.
    """
    x = np.asarray(x, dtype=float)
    if x.size < block or block < 3:
        return float(np.ptp(x)) if x.size else 0.0
    return float(median(_detrended_block_stat(x, block, lambda b: np.ptp(b, axis=1))))


def clipped_mean(x: np.ndarray, half_width: float) -> float:
    """Mean of ``x`` clipped to its median +- ``half_width`` (NaN when empty).

    Unlike a median or a trimmed mean it keeps the sub-quantum information that noise
    dithers into a coarsely quantized signal, while spikes weigh at most ``half_width``.

    Parameters
    ----------
    x : numpy.ndarray
        The samples of a stretch.
    half_width : float
        Half-width of the clip around the median (same unit as ``x``).

    Returns
    -------
    float
    """
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return float("nan")
    m = median(x)
    return float(np.mean(np.clip(x, m - half_width, m + half_width)))


def level(x: np.ndarray) -> float:
    """Robust level of a stretch: the 20 %-trimmed mean (NaN when empty).

    Parameters
    ----------
    x : numpy.ndarray
        The samples of a stretch; 20 % are cut from each end before averaging.

    Returns
    -------
    float
    """
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return float("nan")
    cut = int(0.2 * x.size)  # scipy.stats.trim_mean's own steps; importing scipy.stats costs ~1 s
    part = np.partition(x, (cut, x.size - cut - 1))
    return float(np.mean(part[cut : x.size - cut]))


def spread(x: np.ndarray) -> float:
    """Robust standard deviation of a stretch (IQR / 1.349; 0 when shorter than 2).

    Parameters
    ----------
    x : numpy.ndarray
        The samples of a stretch.

    Returns
    -------
    float
        Equal to the standard deviation for Gaussian samples, unmoved by a few outliers.
    """
    x = np.asarray(x, dtype=float)
    if x.size < 2:
        return 0.0
    q75, q25 = np.percentile(x, [75, 25])
    return float((q75 - q25) / 1.349)


def changepoint(x: np.ndarray) -> int:
    """Least-squares single change in mean: the index ``k`` splitting ``x[:k]`` / ``x[k:]``.

    Parameters
    ----------
    x : numpy.ndarray
        One-dimensional stretch of at least 2 samples.

    Returns
    -------
    int
        ``k`` in ``1 .. len(x) - 1`` minimising the two-segment squared error.
    """
    x = np.asarray(x, dtype=float)
    x = x - x.mean()
    n = x.size
    if n < 2:
        return 0
    c1 = np.cumsum(x)
    c2 = np.cumsum(x * x)
    k = np.arange(1, n)
    left = c2[k - 1] - c1[k - 1] ** 2 / k
    right = (c2[-1] - c2[k - 1]) - (c1[-1] - c1[k - 1]) ** 2 / (n - k)
    return int(k[np.argmin(left + right)])


def find_peaks(x: np.ndarray, height: float, distance: int) -> np.ndarray:
    """Indices of the peaks of ``x``, as ``scipy.signal.find_peaks(x, height, distance)``.

    Local maxima (the middle sample of a flat top) at least ``height`` high, thinned so
    that no two are closer than ``distance`` samples, the higher one kept. Written with
    numpy so that segmentation does not import ``scipy.signal`` (which loads
    ``scipy.stats``, about a second at start-up).

    Parameters
    ----------
    x : numpy.ndarray
        The signal.
    height : float
        Minimum height of a peak.
    distance : int
        Minimum distance between peaks (samples, >= 1).

    Returns
    -------
    numpy.ndarray
        The peaks' indices, increasing.
    """
    x = np.asarray(x, dtype=float)
    if x.size < 3:
        return np.zeros(0, dtype=np.intp)
    # only samples at least ``height`` high, and their neighbours, can make a peak: the
    # search runs on them alone (a long log's signal is mostly below the height); the
    # neighbours lie below it, so joining the stretches never joins two flat tops
    high = x >= height
    near = high.copy()
    near[1:] |= high[1:] | high[:-1]
    near[:-1] |= high[1:]
    sel = np.flatnonzero(near)
    del high, near
    xs = x[sel]
    if xs.size < 3:
        return np.zeros(0, dtype=np.intp)
    starts = np.flatnonzero(np.r_[True, xs[1:] != xs[:-1]])
    ends = np.r_[starts[1:] - 1, xs.size - 1]
    v = xs[starts]
    inner = np.arange(1, starts.size - 1)
    is_peak = (v[inner - 1] < v[inner]) & (v[inner + 1] < v[inner])
    peaks = (sel[starts[inner[is_peak]]] + sel[ends[inner[is_peak]]]) // 2
    peaks = peaks[x[peaks] >= height]
    distance = int(np.ceil(max(distance, 1)))
    if distance <= 1 or peaks.size < 2:
        return peaks
    keep = np.ones(peaks.size, dtype=bool)
    for j in np.argsort(x[peaks])[::-1]:  # the same order as scipy, ties included
        if not keep[j]:
            continue
        k = j - 1
        while k >= 0 and peaks[j] - peaks[k] < distance:
            keep[k] = False
            k -= 1
        k = j + 1
        while k < peaks.size and peaks[k] - peaks[j] < distance:
            keep[k] = False
            k += 1
    return peaks[keep]
