"""A noise-free reconstruction of a step trial's measured force: errors in variables.

The measured force drives the model. Its noise then enters the simulated acceleration
through the drive (``m_a a = f - D v``, ``T_a df/dt = u - f``): on a light cart with a
short lag, force noise of 0.03 N on steps of 0.2-0.6 N moves the simulated acceleration
as much as the accelerometer's own noise does, and a least-squares fit that treats the
input as exact is biased (errors in variables, issue 31: ``T_a`` twice the truth, ``A``
0 against 0.5). A step trial's thrust is held between changes, so its input is
reconstructed as the piecewise-constant signal the noise hides: binary segmentation of
the force series, a change kept where it lowers the squared error by more than
``PENALTY x sigma^2 x ln(n)`` (a BIC-like penalty; ``sigma`` from the median absolute
first difference, which the few steps do not move). Each stretch is then its mean: the
noise averages out over a hold, and the steps stay where they are. Only step trials are
reconstructed: a guided move's or a window's force changes smoothly, and there the first
differences are signal, not noise.
"""

from __future__ import annotations

import itertools

import numpy as np

#: Penalty factor of a change (times ``sigma^2 ln n``): 2 is BIC's for a mean shift; at 3
#: a noise spike is never worth a change.
PENALTY = 3.0

#: Shortest stretch (samples) between two changes.
MIN_STRETCH = 2

#: Most stretches in one series.
MAX_STRETCHES = 20000


def noise_sigma(u: np.ndarray) -> float:
    """The white noise's standard deviation in a piecewise-constant series.

    Parameters
    ----------
    u : numpy.ndarray
        A force series.

    Returns
    -------
    float
        ``median |diff u| / (0.6745 sqrt 2)`` (0 for fewer than 3 samples).
    """
    if u.size < 3:
        return 0.0
    return float(np.median(np.abs(np.diff(u))) / (0.6745 * np.sqrt(2.0)))


def piecewise_constant(u: np.ndarray, sigma: float | None = None) -> np.ndarray:
    """``u`` as the piecewise-constant signal its noise hides (binary segmentation).

    Parameters
    ----------
    u : numpy.ndarray
        The measured series (finite).
    sigma : float, optional
        Its noise's standard deviation; None estimates it (:func:`noise_sigma`).

    Returns
    -------
    numpy.ndarray
        Each stretch between the changes found replaced by its mean; a copy of ``u``
        when no noise is seen.
    """
    u = np.asarray(u, dtype=float)
    n = u.size
    s = noise_sigma(u) if sigma is None else float(sigma)
    if n < 2 * MIN_STRETCH or not (np.isfinite(s) and s > 0):
        return u.copy()
    penalty = PENALTY * s * s * np.log(n)
    csum = np.concatenate([[0.0], np.cumsum(u)])
    cuts = [0, n]
    stack = [(0, n)]
    while stack and len(cuts) < MAX_STRETCHES:
        a, b = stack.pop()
        if b - a < 2 * MIN_STRETCH:
            continue
        k = np.arange(a + MIN_STRETCH, b - MIN_STRETCH + 1)
        left = csum[k] - csum[a]
        right = csum[b] - csum[k]
        total = csum[b] - csum[a]
        # the drop in squared error from splitting [a, b) at k
        gain = left**2 / (k - a) + right**2 / (b - k) - total**2 / (b - a)
        j = int(np.argmax(gain))
        if gain[j] <= penalty:
            continue
        c = int(k[j])
        cuts.append(c)
        stack += [(a, c), (c, b)]
    cuts.sort()
    out = np.empty(n)
    for a, b in itertools.pairwise(cuts):
        out[a:b] = (csum[b] - csum[a]) / (b - a)
    return out
