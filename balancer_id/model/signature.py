"""What an effect's signature check returns, what it reads, and two helpers it may use.

An effect says how its absence shows in the residual of a fit with a ``signature(ctx)``
classmethod next to its hooks (MODEL.md, "Residual signatures"); the diagnosis calls it
with a :class:`~balancer_id.diagnostics.context.DiagnosisContext`. The model layer
cannot import the diagnosis, so :class:`SignatureContext` spells out what a check may
read of that context, and :class:`Signature`, what it returns, lives here (it is also
importable from :mod:`balancer_id.diagnostics.signatures`).

Nothing here imports numpy: ``balancer-id effects`` lists the effects without it, so a
check imports numpy inside its body.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, SupportsFloat

if TYPE_CHECKING:
    import numpy as np


@dataclass
class Signature:
    """The evidence one effect's check found.

    Attributes
    ----------
    strength : float
        How strongly the residual shows the effect's footprint, in [0, 1].
    evidence : str
        One line of evidence, in numbers and words.
    start : dict
        Start values of the effect's parameters for the quick refit.
    """

    strength: float
    evidence: str
    start: dict[str, float] = field(default_factory=dict)


class SignatureTrial(Protocol):
    """One trial's measured and simulated signals, as a check reads them.

    The diagnosis passes a :class:`~balancer_id.diagnostics.context.TrialView`.

    Attributes
    ----------
    data : TrialData
        The trial (its ``thrust_N`` and ``direction`` among others).
    t : numpy.ndarray
        Time since the onset (s).
    y, y_model, residual : numpy.ndarray
        Measured and simulated acceleration and their difference (m/s^2).
    v, z, f, h : numpy.ndarray
        Simulated velocity, position, drive force and operating force.
    regimes : dict
        Regime name (``rest``, ``rise``, ``steady``, ``stuck``) -> boolean mask over the
        trial's samples.
    """

    data: Any
    t: np.ndarray
    y: np.ndarray
    y_model: np.ndarray
    residual: np.ndarray
    v: np.ndarray
    z: np.ndarray
    f: np.ndarray
    h: np.ndarray
    regimes: dict[str, np.ndarray]


class SignatureContext(Protocol):
    """A fit and its residuals, trial by trial, as a check reads them.

    The diagnosis passes a :class:`~balancer_id.diagnostics.context.DiagnosisContext`.

    Attributes
    ----------
    match : MatchResult
        The fit being diagnosed (its ``values()`` among others).
    noise_floor : float
        Acceleration noise (m/s^2).
    dt : float
        Median sample interval (s).
    """

    match: Any
    noise_floor: float
    dt: float

    @property
    def trials(self) -> Sequence[SignatureTrial]:
        """The trials, each a :class:`SignatureTrial`."""
        ...

    def input_correlation(self, max_lag_s: float = 1.5) -> dict[str, Any]:
        """Mean residual against the time since the onset, and its peak.

        Parameters
        ----------
        max_lag_s : float
            Latest time after the onset to look at (s).

        Returns
        -------
        dict
            ``peak_lag_s``, ``peak_value`` (m/s^2) and ``significant`` among others.
        """
        ...

    def spectrum_peaks(self, factor: float = 8.0) -> dict[str, Any]:
        """Narrow peaks of the residual spectrum above ``factor`` x its median level.

        Parameters
        ----------
        factor : float
            How far above the median spectral level a peak must rise to count.

        Returns
        -------
        dict
            ``peaks``: ``{"frequency_hz", "ratio_to_median"}``, strongest first.
        """
        ...


def t_stat(x: np.ndarray, sigma: float) -> float:
    """The t statistic of the mean of ``x`` against zero, with a known noise level.

    Parameters
    ----------
    x : numpy.ndarray
        Residual samples (m/s^2).
    sigma : float
        Standard deviation of one sample's noise (m/s^2).

    Returns
    -------
    float
        ``mean(x) / (sigma / sqrt(n))``; 0 without samples.
    """
    return float(x.mean() / (sigma / math.sqrt(max(x.size, 1)))) if x.size else 0.0


def clip01(x: SupportsFloat) -> float:
    """``x`` clipped into [0, 1] (a strength).

    Parameters
    ----------
    x : float or numpy scalar
        Any number.

    Returns
    -------
    float
        ``min(max(x, 0), 1)``; NaN stays NaN.
    """
    return min(max(float(x), 0.0), 1.0)
