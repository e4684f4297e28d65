"""Each trial fitted alone, starting from the joint fit (``--per-trial``, parameter drift)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from balancer_id.errors import IdentificationError
from balancer_id.identify.data import TrialData
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
    for td in trials:
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
