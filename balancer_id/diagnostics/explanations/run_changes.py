"""The fits shared by the kinds that let a parameter change between runs (split, drift, pair).

A parameter ``name`` takes ``base + c * design[i]`` in trial ``i``: a step after run ``k``
(``design = run >= k``) or a line over the runs (``design = run / (runs - 1)``). Each
(parameter, boundary) is one least-squares fit, run in threads.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

# the arena module, not its names: it imports this package while it loads
from balancer_id.diagnostics import arena

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.diagnostics.explanations.base import Explanation
    from balancer_id.model.spec import Model

#: Parameters of the split and drift explanations must move by at least this share.
MIN_RELATIVE_CHANGE = 0.03
#: Function evaluations of a refinement (:attr:`Explanation.refine`); the first fits of
#: the arena stop at 60, enough to rank them, not always to tell two close ones apart.
REFINE_NFEV = 300
#: Function evaluations of the arena's first fits.
FIRST_NFEV = 60


@dataclass(frozen=True)
class Change:
    """One fitted change of a parameter between runs.

    Attributes
    ----------
    name : str
        The parameter.
    after_run : int or None
        The split's boundary (the change comes after this many runs); None: a drift.
    first, second : float
        Before and after the split (the first and the last run for a drift).
    relative : float
        ``|second - first| / max(|first|, |second|)``.
    delta_bic, rmse : float
        Its score.
    n_runs, n_samples : int
        Runs and samples of the trials.
    """

    name: str
    after_run: int | None
    first: float
    second: float
    relative: float
    delta_bic: float
    rmse: float
    n_runs: int
    n_samples: int

    @property
    def null(self) -> bool:
        """The parameter moves by less than :data:`MIN_RELATIVE_CHANGE`."""
        return self.relative < MIN_RELATIVE_CHANGE


def fit_changes(
    inp: ArenaInput,
    build: Callable[[Change], Explanation],
    *,
    model: Model | None = None,
    start: dict[str, float] | None = None,
    splits: bool = True,
    drifts: bool = True,
    k_base: int = 0,
) -> list[Explanation]:
    """Each free parameter split at each run boundary and/or drifting over the runs.

    Parameters
    ----------
    inp : ArenaInput
        The current fit and its trials (four runs at least, else nothing).
    build : callable
        Makes the explanation of one :class:`Change`.
    model : Model, optional
        The model the change is fitted in (the current one by default; a pair's has its
        effect added).
    start : dict, optional
        Where the fits start (the current values by default).
    splits, drifts : bool
        Which changes to fit: a split after each run with two runs at least on each side,
        a drift per parameter.
    k_base : int
        Parameters the model adds to the current one (counted in the BIC).

    Returns
    -------
    list of Explanation
        In the order (parameter, boundary), a parameter's drift after its splits.
    """
    model = model or inp.match.model
    start = start if start is not None else inp.match.values()
    run = arena.run_index(inp.runs)
    n_runs = int(run.max()) + 1 if run.size else 0
    if n_runs < 4:
        return []
    sims = arena.Trials(inp.trials)
    fixed = {k: v for k, v in arena.held(inp.match).items() if k in model.param_names}
    free = [n for n in model.param_names if n not in fixed]

    def fit_one(
        name: str, k: int | None, begin: dict[str, float], c0: np.ndarray | None, nfev: int
    ) -> Explanation:
        """The split of ``name`` after run ``k`` (None: its drift), fitted from ``begin``."""
        if k is None:
            design = (run / max(n_runs - 1, 1)).astype(float)[:, None]
        else:
            design = (run >= k).astype(float)[:, None]
        parts, base, c, _ = arena.fit_varying(
            model, sims, begin, fixed, name, design, c_start=c0, max_nfev=nfev
        )
        one, two = base[name], base[name] + float(c[0])
        rel = abs(two - one) / max(abs(one), abs(two), 1e-300)
        d, rmse = arena.score(inp, parts, 1 + k_base)
        e = build(Change(name, k, one, two, rel, d, rmse, n_runs, sims.n))
        e.refine = lambda: fit_one(name, k, base, c, REFINE_NFEV)
        return e

    bounds = [*(range(2, n_runs - 1) if splits else []), *([None] if drifts else [])]
    jobs = [(name, k) for name in free for k in bounds]
    return arena.fit_in_threads(
        jobs, lambda job: fit_one(job[0], job[1], start, None, FIRST_NFEV), inp.threads
    )
