"""A parameter that changes between runs: the per-run estimates split into two groups.

A payload hooked on between two runs, or a setting of the balancer changed, moves a
parameter (m_a above all) from one value to another at one point of the recording. No
effect of the model explains that; an effect that merely mimics it (a bias, a speed
limit) would be wrong physics. This module is pure: per-run estimates in, a finding out.

The test: over the runs in recording order, every split point ``k`` divides them into
runs ``1..k`` and ``k+1..n``; the split that lowers the weighted sum of squares most is
kept. Its improvement ``delta = chi2(one value) - chi2(two values)`` is chi-square with
one degree of freedom when nothing changed; standard errors are first scaled up by the
scatter left inside the groups (never down), the best split over ``n - 1`` candidates
is Bonferroni-corrected, and the split must also beat a straight line in the order of
the runs (a drift), a straight line in the thrust and one value per thrust level (a
thrust dependence: a missing effect makes the per-run values follow the thrust), and
move the parameter by more than :data:`MIN_RELATIVE_CHANGE`. A change that coincides
with a change of every thrust level cannot be told from a thrust dependence and is not
reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import chdtrc

#: Family-wise false-alarm probability of the split test (per parameter).
ALPHA = 1e-4
#: Smallest relative change reported (a change below this is not worth a sentence).
MIN_RELATIVE_CHANGE = 0.03
#: How much better (in chi-square) the split must be than a line in order or thrust.
MIN_GAIN_OVER_LINE = 9.0


@dataclass(frozen=True)
class RunEstimate:
    """One run's estimate of a parameter.

    Attributes
    ----------
    run : str
        The run's label (file and run name).
    value : float
        The estimate.
    stderr : float
        Its standard error (> 0).
    thrust_N : float
        Mean thrust magnitude of the run's trials (N), to tell a thrust dependence.
    """

    run: str
    value: float
    stderr: float
    thrust_N: float = 0.0


@dataclass(frozen=True)
class GroupSplit:
    """A parameter that takes one value in the first runs and another in the rest.

    Attributes
    ----------
    parameter : str
        The parameter's name.
    split_after : int
        Number of runs in the first group (the change happened after run ``split_after``).
    runs : tuple of str
        All run labels, in order.
    before, after : float
        Weighted means of the two groups.
    stderr_before, stderr_after : float
        Their standard errors (scaled by the scatter inside the groups when it is larger).
    delta_chi2 : float
        The split's improvement of the weighted sum of squares.
    p_value : float
        Bonferroni-corrected probability of so large an improvement without a change.
    estimates : tuple of RunEstimate
        The per-run evidence.
    """

    parameter: str
    split_after: int
    runs: tuple[str, ...]
    before: float
    after: float
    stderr_before: float
    stderr_after: float
    delta_chi2: float
    p_value: float
    estimates: tuple[RunEstimate, ...]

    def sentence(self, unit: str = "") -> str:
        """The finding in words.

        Parameters
        ----------
        unit : str
            Unit printed after the values (``"kg"`` for m_a).

        Returns
        -------
        str
            E.g. "m_a is 15.1 kg in runs 1-3 and 19.1 kg in runs 4-6: the payload or the
            balancer's setting changed between runs 3 and 4".
        """
        k, n = self.split_after, len(self.runs)
        u = f" {unit}" if unit else ""
        first = "run 1" if k == 1 else f"runs 1-{k}"
        second = f"run {n}" if k + 1 == n else f"runs {k + 1}-{n}"
        return (
            f"{self.parameter} is {self.before:.3g}{u} in {first} and {self.after:.3g}{u} in "
            f"{second}: the payload or the balancer's setting changed between runs {k} "
            f"and {k + 1} (split test p = {self.p_value:.1e})"
        )

    def group_spec(self) -> str:
        """The ``fit --group-by`` value that fits the two groups separately."""
        k, n = self.split_after, len(self.runs)
        return f"runs:1-{k},{k + 1}-{n}"

    def to_dict(self) -> dict[str, object]:
        """JSON-ready record with the evidence."""
        return {
            "parameter": self.parameter,
            "split_after_run": self.split_after,
            "before": {"value": self.before, "stderr": self.stderr_before},
            "after": {"value": self.after, "stderr": self.stderr_after},
            "delta_chi2": self.delta_chi2,
            "p_value": self.p_value,
            "group_by": self.group_spec(),
            "runs": [
                {"run": e.run, "value": e.value, "stderr": e.stderr, "thrust_N": e.thrust_N}
                for e in self.estimates
            ],
        }


def _wls(x: np.ndarray, w: np.ndarray, design: np.ndarray) -> float:
    """Weighted residual sum of squares of ``x`` on ``design``."""
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(design * sw[:, None], x * sw, rcond=None)
    r = x - design @ coef
    return float(np.sum(w * r**2))


def _level_design(thrust: np.ndarray, rel_tol: float = 0.1) -> np.ndarray:
    """One column per thrust level (magnitudes within ``rel_tol`` are one level)."""
    order = np.argsort(thrust)
    label = np.empty(thrust.size, dtype=int)
    level, last = -1, -np.inf
    for i in order:
        if thrust[i] > last * (1 + rel_tol) or level < 0:
            level += 1
            last = thrust[i]
        label[i] = level
    return (label[:, None] == np.arange(level + 1)[None, :]).astype(float)


def find_split(parameter: str, estimates: Sequence[RunEstimate]) -> GroupSplit | None:
    """Test whether a parameter's per-run estimates fall into two groups in time.

    Parameters
    ----------
    parameter : str
        The parameter's name.
    estimates : sequence of RunEstimate
        One per run, in recording order; at least four with finite positive stderr (a
        group is two runs or more).

    Returns
    -------
    GroupSplit or None
        The best split when it is significant at :data:`ALPHA` (after correction), beats
        a line in run order, a line in thrust and one value per thrust level by
        :data:`MIN_GAIN_OVER_LINE`, and changes the parameter by at least
        :data:`MIN_RELATIVE_CHANGE`; None otherwise.
    """
    est = [e for e in estimates if np.isfinite(e.value) and np.isfinite(e.stderr) and e.stderr > 0]
    n = len(est)
    if n < 4:
        return None
    x = np.array([e.value for e in est])
    w = 1.0 / np.array([e.stderr for e in est]) ** 2
    ones = np.ones(n)
    chi_one = _wls(x, w, ones[:, None])
    best = None
    for k in range(2, n - 1):  # two runs at least on each side: one odd run is no group
        step = (np.arange(n) >= k).astype(float)
        chi = _wls(x, w, np.column_stack([ones, step]))
        if best is None or chi < best[1]:
            best = (k, chi)
    assert best is not None
    k, chi_split = best
    scale = max(1.0, chi_split / max(n - 2, 1))
    delta = (chi_one - chi_split) / scale
    p = min(1.0, float(chdtrc(1, delta)) * (n - 3))
    order = np.arange(n, dtype=float)
    thrust = np.array([e.thrust_N for e in est])
    chi_lines = [_wls(x, w, np.column_stack([ones, order]))]
    if np.ptp(thrust) > 0:
        chi_lines.append(_wls(x, w, np.column_stack([ones, thrust])))
        chi_lines.append(_wls(x, w, _level_design(thrust)))
    gain = (min(chi_lines) - chi_split) / scale
    before = float(np.average(x[:k], weights=w[:k]))
    after = float(np.average(x[k:], weights=w[k:]))
    rel = abs(after - before) / max(abs(before), abs(after), 1e-300)
    if p > ALPHA or gain < MIN_GAIN_OVER_LINE or rel < MIN_RELATIVE_CHANGE:
        return None
    return GroupSplit(
        parameter=parameter,
        split_after=k,
        runs=tuple(e.run for e in est),
        before=before,
        after=after,
        stderr_before=float(np.sqrt(scale / w[:k].sum())),
        stderr_after=float(np.sqrt(scale / w[k:].sum())),
        delta_chi2=float(delta),
        p_value=p,
        estimates=tuple(est),
    )


def strongest_split(splits: Sequence[GroupSplit | None]) -> GroupSplit | None:
    """The most significant of several parameters' splits (largest ``delta_chi2``).

    Parameters
    ----------
    splits : sequence of GroupSplit or None
        One per parameter tested.

    Returns
    -------
    GroupSplit or None
    """
    found = [s for s in splits if s is not None]
    return max(found, key=lambda s: s.delta_chi2) if found else None


def run_estimates(
    runs: Sequence[str],
    values: Sequence[float],
    stderrs: Sequence[float | None],
    thrusts: Sequence[float],
) -> list[RunEstimate]:
    """Combine per-trial estimates into per-run ones (weighted means, in first-seen order).

    Parameters
    ----------
    runs : sequence of str
        The run label of each trial.
    values : sequence of float
        Each trial's estimate.
    stderrs : sequence of float or None
        Their standard errors; a trial without one is left out.
    thrusts : sequence of float
        Each trial's thrust (N); the run keeps the mean magnitude.

    Returns
    -------
    list of RunEstimate
    """
    order: list[str] = []
    acc: dict[str, list[tuple[float, float, float]]] = {}
    for run, v, s, h in zip(runs, values, stderrs, thrusts, strict=True):
        if s is None or not (np.isfinite(v) and np.isfinite(s) and s > 0):
            continue
        if run not in acc:
            order.append(run)
            acc[run] = []
        acc[run].append((float(v), float(s), abs(float(h))))
    out = []
    for run in order:
        vals, errs, levels = (np.array(c, dtype=float) for c in zip(*acc[run], strict=True))
        w = 1.0 / errs**2
        out.append(
            RunEstimate(
                run,
                float(np.average(vals, weights=w)),
                float(w.sum() ** -0.5),
                float(levels.mean()),
            )
        )
    return out


def detect_groups(
    names: Sequence[str],
    runs: Sequence[str],
    values: Sequence[dict[str, float]],
    stderrs: Sequence[dict[str, float | None]],
    thrusts: Sequence[float],
) -> GroupSplit | None:
    """The strongest split of any parameter over the runs, from per-trial fits.

    Parameters
    ----------
    names : sequence of str
        The parameters to test.
    runs : sequence of str
        Each trial's run label.
    values, stderrs : sequence of dict
        Each trial's fitted values and standard errors by parameter name.
    thrusts : sequence of float
        Each trial's thrust (N).

    Returns
    -------
    GroupSplit or None
    """
    splits = []
    for name in names:
        est = run_estimates(
            runs,
            [v.get(name, np.nan) for v in values],
            [s.get(name) for s in stderrs],
            thrusts,
        )
        splits.append(find_split(name, est))
    return strongest_split(splits)
