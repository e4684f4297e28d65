"""balancer-id: identify a passive balancer's dynamics from force/acceleration logs.

The public API is a set of plain functions that stay what they are however often and in
whatever order they are called (no subpackage carries the name of one of them)::

    load_trials(paths, options) -> TrialSet       the door: read and segment, once
    fit(trials, model=...) -> FitResult            the paper's method, simulation matching
    diagnose(fit) -> Diagnosis                     residual tests, suggested effects
    improve(fit) -> ImproveResult                  add effects while they help
    compare(trials, models) -> [ModelComparison]
    validate(fit_or_params, new_logs) -> Validation  does a saved model hold on new logs?
    full_report(logs, "report.html") -> FullReport  fit, diagnose, improve, write
    plan(fit_or_logs) -> Plan                      the trials to record next
    simulate(model, values, thrust, ...)           the balancer's response
    read_log(path) -> Log

``fit``, ``diagnose``, ``improve`` and ``compare`` also take log paths (one as a plain
``str``). The layers: :mod:`~balancer_id.read` -> :mod:`~balancer_id.segment` ->
:mod:`~balancer_id.model` -> :mod:`~balancer_id.simulation` -> :mod:`~balancer_id.trials`
-> :mod:`~balancer_id.identify` -> :mod:`~balancer_id.diagnostics` ->
:mod:`~balancer_id.report` -> :mod:`~balancer_id.cli`. Heavy modules are imported lazily,
so ``import balancer_id`` is quick.
"""

from __future__ import annotations

import importlib as _importlib
import os as _os
import sys as _sys
from typing import Any

if "numpy" not in _sys.modules:  # a fit's matrices are tall and thin: BLAS threads only cost
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        _os.environ.setdefault(_var, "1")

__version__ = "0.1.0"

#: Public name -> the module that defines it (imported on first use).
_LAZY = {
    "Effect": "balancer_id.model",
    "Param": "balancer_id.model",
    "parse_model": "balancer_id.model",
    "Registry": "balancer_id.model",
    "simulate": "balancer_id.simulation",
    "Thrust": "balancer_id.simulation",
    "read_log": "balancer_id.read",
    "find_trials": "balancer_id.segment",
    "ReadOptions": "balancer_id.trials",
    "TrialSet": "balancer_id.trials",
    "load_trials": "balancer_id.trials",
    "fit": "balancer_id.identify.api",
    "fit_groups": "balancer_id.identify.api",
    "GroupFits": "balancer_id.identify.group_fits",
    "FitResult": "balancer_id.identify.result",
    "diagnose": "balancer_id.diagnostics.api",
    "improve": "balancer_id.diagnostics.api",
    "compare": "balancer_id.diagnostics.api",
    "validate": "balancer_id.diagnostics.api",
    "full_report": "balancer_id.workflows",
    "plan": "balancer_id.workflows",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'balancer_id' has no attribute {name!r}")
    value = getattr(_importlib.import_module(module), name)
    globals()[name] = value  # later look-ups skip this function
    return value


__all__ = sorted(_LAZY)


def __dir__() -> list[str]:
    """The public API (for ``dir(balancer_id)`` and tab completion), not the helpers."""
    return sorted({*_LAZY, "__version__"})
