"""Make result dictionaries strict-JSON safe (no NaN, no numpy scalars)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np


def json_ready(obj: Any) -> Any:
    """Replace NaN/inf by None and numpy scalars and tuples by plain Python, recursively.

    Parameters
    ----------
    obj : object
        A result: dicts, lists, tuples and numpy arrays are walked into; anything else is
        returned as is (after a numpy scalar is turned into its Python value).

    Returns
    -------
    object
        The same structure with lists for tuples and arrays, Python scalars for numpy
        scalars and None for non-finite floats.
    """
    if isinstance(obj, Mapping):  # a dict, or a complete result's read-only table
        return {k: json_ready(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_ready(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_ready(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj
