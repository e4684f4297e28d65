"""What the display and the bands read of a fit, named structurally (a Protocol)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

__all__ = ["ShownFit"]


class ShownFit(Protocol):
    """What the display reads of a fit: a
    :class:`~balancer_id.identify.matching.MatchResult` (named structurally, so that
    ``matching``, which builds on :class:`Displayable`, is not imported back here)."""

    correlations: dict[str, dict[str, float]]
    data: Any
    metrics: dict[str, float]
    model: Any
    nfev: int
    parameters: dict[str, Any]
    success: bool
    y: np.ndarray
    y_model: np.ndarray

    @property
    def warnings(self) -> Sequence[Any]:
        """Notes or sentences (read only: any sequence of them will do)."""
        ...
