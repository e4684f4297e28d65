"""A parameter drifting in time within a run: oil warming over a shift, a brake wearing."""

from __future__ import annotations

import dataclasses
import itertools
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Verdict,
    head,
)
from balancer_id.diagnostics.explanations.run_changes import (
    FIRST_NFEV,
    MIN_RELATIVE_CHANGE,
    REFINE_NFEV,
)
from balancer_id.identify.data import FitData

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.data import TrialData
    from balancer_id.identify.result import FitResult

#: A run needs this many trials for a trend within it to be fitted ...
MIN_TRIALS = 8
#: ... cut into at most this many blocks of consecutive trials (two trials at least each).
MAX_BLOCKS = 8


@dataclasses.dataclass(frozen=True)
class Blocks:
    """The trials regrouped: consecutive trials of a long run in blocks, the rest alone.

    Attributes
    ----------
    groups : list of list of int
        Trial indices of each group, in order.
    tau : numpy.ndarray
        Each group's place in its run's time, from -0.5 (start) to 0.5 (end); 0 for a
        trial of a short run (no trend fitted there).
    span_s : float
        The longest run's duration (s).
    """

    groups: list[list[int]]
    tau: np.ndarray
    span_s: float


def blocks(inp: ArenaInput) -> Blocks | None:
    """The trials of each run of :data:`MIN_TRIALS` or more cut into blocks in time.

    Parameters
    ----------
    inp : ArenaInput

    Returns
    -------
    Blocks or None
        None when no run is long enough.
    """
    run = arena.run_index(inp.runs)
    groups: list[list[int]] = []
    tau: list[float] = []
    span = 0.0
    for r in range(int(run.max()) + 1 if run.size else 0):
        idx = [int(i) for i in np.flatnonzero(run == r)]
        if len(idx) < MIN_TRIALS:
            groups += [[i] for i in idx]
            tau += [0.0] * len(idx)
            continue
        t0 = float(inp.trials[idx[0]].time[0])
        t1 = float(inp.trials[idx[-1]].time[-1])
        span = max(span, t1 - t0)
        for part in np.array_split(np.array(idx), min(MAX_BLOCKS, len(idx) // 2)):
            mid = 0.5 * (float(inp.trials[part[0]].time[0]) + float(inp.trials[part[-1]].time[-1]))
            groups.append([int(i) for i in part])
            tau.append((mid - t0) / max(t1 - t0, 1e-12) - 0.5)
    if span <= 0:
        return None
    return Blocks(groups, np.array(tau), span)


def _block_data(inp: ArenaInput, b: Blocks, pvecs: list[np.ndarray] | None = None) -> list[FitData]:
    """Each group packed. A group that starts inside a session starts from a state its
    history is not simulated again for: the current fit's simulated state there, or,
    given each group's parameters ``pvecs``, the state the group before it ended in
    (the groups simulated in turn, each with its own values)."""
    match = inp.match
    first_row = [sl.start for sl in match.data.slices()]
    states = None
    if pvecs is None:
        values = match.values()
        pvec = np.array([values[n] for n in match.model.param_names])
        states = match.data.packed.run(match.model, pvec)
    out: list[FitData] = []
    end: tuple[float, float, float] | None = None
    for k, group in enumerate(b.groups):
        trials: list[TrialData] = [inp.trials[i] for i in group]
        head_trial = trials[0]
        if head_trial.continues:
            if states is not None:
                row = states[first_row[group[0]]]
                x0 = (float(row[3]), float(row[1]), float(row[2]))  # f, v, z
            else:
                x0 = end if end is not None else (0.0, 0.0, 0.0)
            trials[0] = dataclasses.replace(
                head_trial,
                continues=False,
                previous=None,
                input=dataclasses.replace(head_trial.input, x0=x0),
            )
        data = FitData.build(trials)
        out.append(data)
        if pvecs is not None:
            last = data.packed.run(match.model, pvecs[k])[-1]
            end = (float(last[3]), float(last[1]), float(last[2]))
    return out


class TimeTrend(ExplanationKind):
    """One parameter changes linearly in time within a run (oil warming, wear).

    Proposed for every free parameter when a run holds :data:`MIN_TRIALS` trials or
    more: its trials are cut into blocks of consecutive trials, each block's value on the
    line ``base + c * tau`` (``tau`` its mid-time in the run, -0.5 to 0.5), one added
    parameter; a block inside a session starts from the state the block before it ends
    in (fitted twice: from the current fit's states, then from the chained ones). It
    mimics a drift over the runs, a change at one moment (a payload) and a missing force
    that grows with time; it is seen with ``fit LOG --track PARAM``.
    """

    key = "trend"
    kind = "trend"
    verdict = Verdict.PARAMETER_DRIFT
    stands_alone = True
    changes_parameter = True
    tried = "a parameter drifting in time within a run"
    mimics: ClassVar[str] = "a change at one moment, or a force growing with time"
    separating_trial: ClassVar[str] = (
        "repeat the first thrust steps at the end of the session: a parameter that drifted "
        "answers differently, a missing effect the same"
    )

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """Each free parameter trending in time within the long runs: along a line, and
        (where a run has :data:`MIN_WANDER_BLOCKS` blocks) with its own value in each
        block (a step, a warm-up that levels off, an oscillation: shapes a line misses)."""
        b = blocks(inp)
        if b is None:
            return []
        first = arena.Trials(inp.trials, _block_data(inp, b))
        model = inp.match.model
        fixed = {k: v for k, v in arena.held(inp.match).items() if k in model.param_names}
        free = [n for n in model.param_names if n not in fixed]
        designs = {"line": b.tau[:, None]}
        wander = _wander_design(b)
        if wander is not None:
            designs["blocks"] = wander

        def fit_one(
            job: tuple[str, str], begin: dict[str, float], c0: np.ndarray | None, nfev: int
        ) -> Explanation:
            name, shape = job
            design = designs[shape]
            # first from the current fit's states at the blocks' starts, then again from
            # the states the blocks, each with its own value, hand on to each other
            parts, base, c, _ = arena.fit_varying(
                model, first, begin, fixed, name, design, c_start=c0, max_nfev=nfev
            )
            pvecs = []
            for row in design:
                vals = {**base, name: base[name] + float(row @ c)}
                pvecs.append(np.array([vals[n] for n in model.param_names]))
            chained = arena.Trials(inp.trials, _block_data(inp, b, pvecs))
            solution: list[object] = []
            parts, base, c, _ = arena.fit_varying(
                model,
                chained,
                base,
                fixed,
                name,
                design,
                c_start=c,
                max_nfev=nfev,
                solution=solution,
            )
            path = base[name] + design @ c
            start, end = float(path[0]), float(path[-1])
            se_start, se_end = _end_errors(
                solution, free.index(name), inp.independence, design[0], design[-1]
            )
            scale = max(float(np.max(np.abs(path))), 1e-300)
            rel = float(np.ptp(path)) / scale
            d, rmse = arena.score(inp, per_trial(parts, chained.data), design.shape[1])
            label = (
                f"{name} drifting in time within the run"
                if shape == "line"
                else f"{name} changing in time within the run (not along a line)"
            )
            e = self.make(
                label,
                d,
                rmse,
                parameters=[name],
                detail={
                    "trend": True,
                    "shape": shape,
                    "start": start,
                    "end": end,
                    "start_stderr": se_start,
                    "end_stderr": se_end,
                    "relative_change": rel,
                    "span_s": b.span_s,
                    "values": base,
                },
                null=rel < MIN_RELATIVE_CHANGE,
            )
            e.refine = lambda: fit_one(job, base, c, REFINE_NFEV)
            return e

        start = inp.match.values()
        jobs = [(name, shape) for shape in designs for name in free]
        return arena.fit_in_threads(
            jobs, lambda job: fit_one(job, start, None, FIRST_NFEV), inp.threads
        )

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """``D0 falls from 7.9 +/- 0.1 at the start of the run to 4.1 +/- 0.1 at its end
        (over 600 s) ... See it: balancer-id fit LOG --track D0``."""
        d = e.detail
        p = e.parameters[0]
        a, b = float(d["start"]), float(d["end"])  # type: ignore[arg-type]
        way = "falls" if b < a else "rises"
        if d.get("shape") == "blocks":
            rel = float(d["relative_change"])  # type: ignore[arg-type]
            way = f"changes in time, not along a line (by {rel:.0%}); it goes"
        return (
            f"{p} {way} from {_pm(a, d.get('start_stderr'))} at the start of the run to "
            f"{_pm(b, d.get('end_stderr'))} at its end (over {float(d['span_s']):.0f} s: "  # type: ignore[arg-type]
            f"oil warming, wear, a slow change of load); {head(e)}. See it in time: "
            f"{fit.command()} --track {p}"
        )


def per_trial(parts: list[np.ndarray], data: list[FitData]) -> list[np.ndarray]:
    """Each block's residual cut into its trials', as the current fit's is scored.

    The arena whitens each trial's residual from its first sample (the exact start of
    the noise's AR(2) likelihood); a block's continuing trials whitened across their
    junctions would be scored by another rule than the current fit, and a slow misfit
    there would read as a gain of the trend.

    Parameters
    ----------
    parts : list of numpy.ndarray
        One residual per block.
    data : list of FitData
        The blocks, packed.

    Returns
    -------
    list of numpy.ndarray
    """
    return [r[sl] for r, d in zip(parts, data, strict=True) for sl in d.slices()]


def _pm(x: float, se: object) -> str:
    return f"{x:.4g} +/- {1.96 * se:.2g}" if isinstance(se, float) else f"{x:.4g}"


#: A run's blocks for a trend with its own value in each (fewer: the line only).
MIN_WANDER_BLOCKS = 4


def _wander_design(b: Blocks) -> np.ndarray | None:
    """The design of a parameter with its own value in each block of a long run: one
    column per block after a run's first (that block is the base); None when no run has
    :data:`MIN_WANDER_BLOCKS` blocks. A trial of a short run (``tau`` 0, alone) keeps the
    base."""
    trended = np.flatnonzero(b.tau != 0.0)
    if trended.size < MIN_WANDER_BLOCKS:
        return None
    # the first block of each long run is where tau is lowest within its run: blocks
    # in order, a run's start where tau falls back
    firsts = {int(trended[0])}
    for i, j in itertools.pairwise(int(k) for k in trended):
        if b.tau[j] < b.tau[i]:
            firsts.add(j)
    cols = [int(i) for i in trended if int(i) not in firsts]
    design = np.zeros((b.tau.size, len(cols)))
    for c, i in enumerate(cols):
        design[i, c] = 1.0
    return design


def _end_errors(
    solution: list[object],
    k: int,
    independence: float,
    first_row: np.ndarray,
    last_row: np.ndarray,
) -> tuple[float | None, float | None]:
    """Standard errors of the path's start and end from the fit's Jacobian.

    The parameter ``k`` of the free ones is the base; the coefficients follow them (the
    last columns): the value in a block is ``base + row @ c``.
    """
    if not solution:
        return None, None
    sol = solution[0]
    jac = np.asarray(sol.jac)  # type: ignore[attr-defined]
    res = np.asarray(sol.fun)  # type: ignore[attr-defined]
    n, p = jac.shape
    if n <= p:
        return None, None
    cov = np.linalg.pinv(jac.T @ jac) * float(res @ res) / (n - p) / max(independence, 0.05)
    out = []
    q = first_row.size
    for row in (first_row, last_row):
        w = np.zeros(p)
        w[k] = 1.0
        w[p - q :] = row
        var = float(w @ cov @ w)
        out.append(float(np.sqrt(var)) if np.isfinite(var) and var >= 0 else None)
    return out[0], out[1]
