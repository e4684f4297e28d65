"""A parameter split at a run boundary: a payload hooked on, a setting changed."""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Verdict,
    head,
)
from balancer_id.diagnostics.explanations.run_changes import Change, fit_changes

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.data import TrialData
    from balancer_id.identify.result import FitResult

#: The trial that tells a change between runs from a missing effect.
REPEAT_FIRST_RUN = (
    "repeat the first run at the end of the session: a change or drift of the "
    "balancer shows as a different result, a missing effect as the same"
)


class Split(ExplanationKind):
    """One parameter takes another value after run ``k`` (two runs at least each side).

    Proposed for every free parameter and boundary of a log of four runs or more; fitted
    as ``base + c * (run >= k)``; scored with one added parameter. It mimics an effect
    that depends on the direction or the thrust level when the runs' order follows them
    (:func:`confound`).
    """

    key = "split"
    kind = "split"
    verdict = Verdict.PARAMETER_CHANGED
    stands_alone = True
    changes_parameter = True
    tried = "a parameter changed between runs"
    mimics: ClassVar[str] = "an effect depending on the direction or thrust level"
    separating_trial: ClassVar[str] = REPEAT_FIRST_RUN

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """Each free parameter split at each run boundary."""
        return fit_changes(inp, lambda c: split_of(self, c), drifts=False)

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """``m_a is 15 kg in runs 1-3 and 18 kg in runs 4-6: ... --group-by ...``."""
        return split_sentence(e, fit)


def split_of(
    kind: ExplanationKind, c: Change, prefix: str = "", effects: Sequence[str] = ()
) -> Explanation:
    """The explanation of a split ``c`` (a pair's when ``prefix`` names its effect).

    Parameters
    ----------
    kind : ExplanationKind
    c : Change
    prefix : str
    effects : sequence of str

    Returns
    -------
    Explanation
    """
    k = int(c.after_run or 0)
    return kind.make(
        f"{prefix}{c.name} changes after run {k}",
        c.delta_bic,
        c.rmse,
        effects=list(effects),
        parameters=[c.name],
        detail={
            "split_after_run": k,
            "before": c.first,
            "after": c.second,
            "relative_change": c.relative,
            "group_by": f"runs:1-{k},{k + 1}-{c.n_runs}",
            "n_samples": c.n_samples,
        },
        null=c.null,
    )


def split_sentence(e: Explanation, fit: FitResult) -> str:
    """The verdict's paragraph of a split (or a pair with one).

    Parameters
    ----------
    e : Explanation
    fit : FitResult

    Returns
    -------
    str
    """
    d = e.detail
    k = int(str(d["split_after_run"]))
    n = int(str(d["group_by"]).rsplit("-", 1)[-1])
    p = e.parameters[0]
    u = " kg" if p == "m_a" else ""
    first = "run 1" if k == 1 else f"runs 1-{k}"
    second = f"run {n}" if k + 1 == n else f"runs {k + 1}-{n}"
    return (
        f"{p} is {float(d['before']):.3g}{u} in {first} and "  # type: ignore[arg-type]
        f"{float(d['after']):.3g}{u} in {second}: "  # type: ignore[arg-type]
        f"the payload or the balancer's setting changed between runs {k} and {k + 1}"
        + (f" (with {e.effects[0]} added)" if e.effects else "")
        + f"; {head(e)}. Fit each group on its own: {fit.command()} --group-by "
        + shlex.quote(str(d["group_by"]))
    )


def confound(e: Explanation, trials: Sequence[TrialData], runs: Sequence[str]) -> str | None:
    """How the recording confounds a split with the direction or the thrust level.

    Parameters
    ----------
    e : Explanation
        A split (or a pair with a split).
    trials : sequence of TrialData
        The trials.
    runs : sequence of str
        Each trial's run label.

    Returns
    -------
    str or None
        ``"direction"`` when every run before the split goes one way and every run after
        the other, ``"thrust level"`` when the two groups share no thrust level; None.
    """
    at = e.detail.get("split_after_run")
    if at is None:
        return None
    k = int(str(at))
    run = arena.run_index(runs)
    before = [td for td, r in zip(trials, run, strict=True) if r < k]
    after = [td for td, r in zip(trials, run, strict=True) if r >= k]
    sb = {np.sign(td.thrust_N) for td in before}
    sa = {np.sign(td.thrust_N) for td in after}
    if len(sb) == 1 and len(sa) == 1 and sb != sa:
        return "direction"
    lb = {round(abs(td.thrust_N), 1) for td in before}
    la = {round(abs(td.thrust_N), 1) for td in after}
    if not (lb & la) and len(lb) == 1 and len(la) == 1:
        return "thrust level"
    return None


def record_hint(e: Explanation, how: str, trials: Sequence[TrialData]) -> str:
    """The trial to record that tells a confounded split from the effect it mimics.

    Parameters
    ----------
    e : Explanation
        The split (or drift) that is confounded.
    how : str
        ``"direction"`` or ``"thrust"``: what the split coincides with.
    trials : sequence of TrialData
        The trials, in recording order.

    Returns
    -------
    str
        The advice, one sentence.
    """
    if how == "direction":
        first = "up" if trials[0].thrust_N > 0 else "down"
        other = "down" if first == "up" else "up"
        return (
            f"record one {other} step before the {first} steps (or alternate up and down): "
            "a direction-dependent effect then shows in every group, a change between "
            "runs only after it"
        )
    return (
        "record the thrust levels in another order (or repeat the first level at the end): "
        "a thrust-dependent effect then shows at every time, a change between runs only "
        "after it"
    )
