"""balancer-id: identify a passive balancer's dynamics from force/acceleration logs.

The pipeline, one subpackage each: :mod:`~balancer_id.read` -> :mod:`~balancer_id.segment`
-> :mod:`~balancer_id.model` / :mod:`~balancer_id.simulate` -> :mod:`~balancer_id.fit`
-> :mod:`~balancer_id.diagnose` -> :mod:`~balancer_id.report`.
Heavy modules are imported lazily, so ``import balancer_id`` is quick.
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import Any

if "numpy" not in sys.modules:  # a fit's matrices are tall and thin: BLAS threads only cost
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

__version__ = "0.1.0"

_LAZY = {
    "Effect": "balancer_id.model",
    "Param": "balancer_id.model",
    "parse_model": "balancer_id.model",
    "Registry": "balancer_id.model",
    "simulate": "balancer_id.simulate",
    "Thrust": "balancer_id.simulate",
    "read_log": "balancer_id.read",
    "find_trials": "balancer_id.segment",
    "fit": "balancer_id.fit",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'balancer_id' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)


__all__ = sorted(_LAZY)
