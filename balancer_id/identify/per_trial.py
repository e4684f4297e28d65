"""Each trial fitted alone, starting from the joint fit (``--per-trial``, parameter drift)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from balancer_id.errors import IdentificationError
from balancer_id.identify.data import FitData, TrialData
from balancer_id.identify.matching import match_trials
from balancer_id.model.spec import Model


@dataclass
class PerTrialFit:
    """The model fitted to one trial alone (``--per-trial``)."""

    index: int
    thrust_N: float
    direction: str
    values: dict[str, float]
    stderr: dict[str, float | None]
    rmse: float

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "index": self.index,
            "thrust_N": self.thrust_N,
            "direction": self.direction,
            "parameters": {
                k: {"value": v, "stderr": self.stderr.get(k)} for k, v in self.values.items()
            },
            "rmse": self.rmse,
        }


def fit_each_trial(
    model: Model,
    trials: Sequence[TrialData],
    start: Mapping[str, float],
    fixed: Mapping[str, float] | None = None,
) -> list[PerTrialFit]:
    """Fit ``model`` to each trial alone, starting from the joint fit.

    Parameters
    ----------
    model : Model
        The model to fit.
    trials : sequence of TrialData
        The trials; each is fitted on its own.
    start : mapping of str to float
        Start values of every fit (the joint fit's values).
    fixed : mapping of str to float, optional
        Parameters held at these values.

    Returns
    -------
    list of PerTrialFit
        One per trial whose fit succeeded; a trial that cannot be fitted is left out.
    """
    out = []
    for td in detach_sessions(model, trials, {**start, **(fixed or {})}):
        try:
            m = match_trials(model, [td], start=start, fixed=fixed)
        except IdentificationError:
            continue
        out.append(
            PerTrialFit(
                index=td.index,
                thrust_N=td.thrust_N,
                direction=td.direction,
                values=m.values(),
                stderr={k: p.stderr for k, p in m.parameters.items()},
                rmse=m.metrics["rmse"],
            )
        )
    return out


def detach_sessions(
    model: Model, trials: Sequence[TrialData], values: Mapping[str, float]
) -> list[TrialData]:
    """The trials, each one that continues a session made to start on its own.

    A trial that continues the previous one starts from the state the joint model
    (``values``) reaches at its first sample, simulated once over the whole session,
    instead of carrying the session before it: fitting each of a long session's trials
    alone then costs each trial's own samples, not the session's (quadratic otherwise).

    Parameters
    ----------
    model : Model
        The model.
    trials : sequence of TrialData
        The trials, in order (as fitted together).
    values : mapping of str to float
        The joint fit's values (defaults for the rest).

    Returns
    -------
    list of TrialData
        The trials; continuing ones with ``continues=False`` and their input's ``x0`` set.
    """
    trials = list(trials)
    if not any(td.continues for td in trials):
        return trials
    data = FitData.build(trials)
    out = data.packed.run(model, np.asarray(model.vector(dict(values)), dtype=float))
    detached = []
    for td, rows in zip(trials, data.slices(), strict=True):
        if td.continues and td.time.size:
            _, v, z, f, _ = (float(x) for x in out[rows.start])
            state = (f, v, z) if np.isfinite([f, v, z]).all() else None
            td = replace(td, continues=False, previous=None, input=replace(td.input, x0=state))
        detached.append(td)
    return detached
