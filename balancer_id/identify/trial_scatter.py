"""Standard errors from the scatter between trials: the cluster-robust sandwich (issue 31).

The fit's standard errors hold for a residual that is the sensor's noise, white or
coloured over a few samples (``residual_tau``). Some errors are shared by every sample of
a trial instead: the level of a step's thrust, read from a noisy force over its hold;
a trial's own small offset; a slow drift of the sensor. Each is a constant (or slow)
pull on the whole trial that the correlation time, summed over a few dozen lags under
the noise's band, does not see, and a precise accelerometer then gives intervals too
narrow to hold the truth (``bench_universe``: clean worlds with force noise).

With trials as clusters, the covariance of the estimate is the sandwich

    cov = (J^T J)^-1 [sum_k g_k g_k^T] (J^T J)^-1 * G / (G - 1),   g_k = J_k^T r_k

over the ``G`` trials (a session's holds count each), which holds whatever the
correlation within a trial. With few trials it is itself uncertain, so it only widens:
each standard error becomes the larger of the two, and only with :data:`MIN_TRIALS`
trials or more.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from balancer_id.identify.matching import MatchResult
from balancer_id.notes import Note

#: Fewest trials (clusters) whose scatter is used.
MIN_TRIALS = 3

#: Widening (ratio of standard errors) above which the note says it.
NOTE_RATIO = 1.2

#: Rows simulated per block.
BLOCK_ROWS = 1 << 16


def trial_scatter_stderr(match: MatchResult) -> dict[str, float] | None:
    """Each fitted parameter's standard error from the scatter between trials.

    Parameters
    ----------
    match : MatchResult
        A converged fit.

    Returns
    -------
    dict of str to float, or None
        None with fewer than :data:`MIN_TRIALS` trials, nothing fitted, or a singular
        ``J^T J``.
    """
    model = match.model
    names = [p.name for p in model.params if match.parameters[p.name].vary]
    free = [model.param_names.index(n) for n in names]
    slices = match.data.slices()
    k, n_trials = len(free), len(slices)
    if k == 0 or n_trials < MIN_TRIALS:
        return None
    pvec = np.array([match.parameters[p.name].value for p in model.params], dtype=float)
    starts = np.array([sl.start for sl in slices])
    y = match.data.y
    jtj = np.zeros((k, k))
    scores = np.zeros((n_trials, k))
    with np.errstate(all="ignore"):
        for first, out, sens in match.data.packed.stream_sens(model, pvec, free, BLOCK_ROWS):
            stop = first + out.shape[0]
            r = out[:, 0] - y[first:stop]
            if not (np.isfinite(r).all() and np.isfinite(sens).all()):
                return None
            jtj += sens.T @ sens
            trial = np.searchsorted(starts, np.arange(first, stop), side="right") - 1
            for j in range(k):
                scores[:, j] += np.bincount(trial, sens[:, j] * r, minlength=n_trials)
    try:
        inv = np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        return None
    cov = inv @ (scores.T @ scores) @ inv * n_trials / (n_trials - 1)
    se = np.sqrt(np.abs(np.diag(cov)))
    if not np.all(np.isfinite(se)):
        return None
    return {name: float(se[j]) for j, name in enumerate(names)}


def widen_by_trial_scatter(match: MatchResult) -> list[Note]:
    """Widen each standard error to the trials' scatter where that is larger.

    Parameters
    ----------
    match : MatchResult
        The fit (its estimates' ``stderr`` changed in place; the largest ratio goes into
        ``metrics["trial_scatter_ratio"]``).

    Returns
    -------
    list of Note
        A ``fit.correlated_residual`` note (severity ``info``) when a standard error
        grew by more than :data:`NOTE_RATIO`.
    """
    scatter = trial_scatter_stderr(match)
    if scatter is None:
        return []
    return widen_stderrs(
        match,
        scatter,
        "trial_scatter_ratio",
        lambda ratio, worst: (
            f"the trials scatter more than the noise within each says: standard errors "
            f"widened to that scatter (up to {ratio:.1f}x, {worst}; a thrust level "
            "read from a noisy force, a trial's own offset or a slow drift pull a whole "
            "trial at once)"
        ),
    )


def widen_stderrs(
    match: MatchResult,
    widened: Mapping[str, float],
    metric: str,
    say: Callable[[float, str], str],
) -> list[Note]:
    """Raise each fitted standard error to ``widened`` where that is larger, record the
    largest ratio in ``metrics[metric]`` and say so past :data:`NOTE_RATIO`.

    Parameters
    ----------
    match : MatchResult
        The fit (its estimates' ``stderr`` and ``scatter_ratio`` changed in place).
    widened : mapping of str to float
        Each parameter's standard error with the new source of error counted.
    metric : str
        The metric that holds the largest ratio of new to old standard error.
    say : callable
        The note's text from that ratio and its parameter's name.

    Returns
    -------
    list of Note
        A ``fit.correlated_residual`` note (severity ``info``) when a standard error
        grew by more than :data:`NOTE_RATIO`.
    """
    ratios = {}
    for name, se in widened.items():
        est = match.parameters[name]
        if est.stderr is None or not np.isfinite(est.stderr) or est.stderr <= 0:
            continue
        ratios[name] = se / est.stderr
        if se > est.stderr:
            est.stderr = se
            est.scatter_ratio = float(est.scatter_ratio * ratios[name])
    if not ratios:
        return []
    worst = max(ratios, key=lambda n: ratios[n])
    match.metrics[metric] = float(ratios[worst])
    if ratios[worst] <= NOTE_RATIO:
        return []
    return [
        Note(
            "fit.correlated_residual", say(ratios[worst], worst), subject=worst, severity="info"
        )
    ]
