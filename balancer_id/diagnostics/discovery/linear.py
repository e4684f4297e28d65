"""The linearized problem: the sparse regression of the discrepancy on the terms."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from balancer_id.diagnostics.discovery.settings import (
    BOOTSTRAP,
    COULOMB,
    MAX_TERMS,
    STRIBECK,
    TERM_BIC,
)
from balancer_id.diagnostics.discovery.terms import Term
from balancer_id.identify.data import FitData
from balancer_id.identify.matching import MatchResult
from balancer_id.model.spec import Model

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput


# ---- the regression ---------------------------------------------------------------------


def _whiten(x: np.ndarray, ar: tuple[float, float]) -> np.ndarray:
    """Rows of one trial prewhitened with AR(2) coefficients (drops the first two)."""
    p1, p2 = ar
    return x[2:] - p1 * x[1:-1] - p2 * x[:-2]


def _gram_rss(xx: np.ndarray, xy: np.ndarray, yy: float, keep: Sequence[int]) -> float:
    """Residual sum of squares of ``y`` on the columns ``keep``, from the Gram matrix
    ``xx`` of the columns, their products ``xy`` with ``y`` and ``yy = y.y``."""
    keep = list(keep)
    if not keep:
        return max(yy, 1e-300)
    b = np.linalg.lstsq(xx[np.ix_(keep, keep)], xy[keep], rcond=1e-12)[0]
    return max(yy - float(xy[keep] @ b), 1e-300)


def _project(base: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x`` with its part along the columns of ``base`` removed."""
    if base.shape[1] == 0:
        return x
    q, _ = np.linalg.qr(base)
    return x - q @ (q.T @ x)


@dataclass
class _Linear:
    """The linearized problem: per trial, whitened residual, parameter and term columns."""

    r: list[np.ndarray]
    p: list[np.ndarray]
    q: list[np.ndarray]
    #: The model's parameters behind the columns of ``p``, in order.
    free: list[str] = field(default_factory=list)
    #: Per trial, the Gram matrix of ``[p, q, r]`` (filled on first use).
    grams: list[np.ndarray] = field(default_factory=list, repr=False)

    def gram(self, trials: Sequence[int]) -> tuple[np.ndarray, int]:
        """The Gram matrix of ``[p, q, r]`` over ``trials`` (repeats allowed) and its rows.

        A bootstrap resample of the trials is a sum of the trials' own Gram matrices, so
        the sparse regression never touches the rows again.
        """
        if not self.grams:
            for r, p, q in zip(self.r, self.p, self.q, strict=True):
                a = np.hstack([p, q, r[:, None]])
                self.grams.append(a.T @ a)
        g = np.sum([self.grams[i] for i in trials], axis=0)
        return g, int(sum(self.r[i].size for i in trials))

    def rows(self, trials: Sequence[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (
            np.concatenate([self.r[i] for i in trials]),
            np.vstack([self.p[i] for i in trials]),
            np.vstack([self.q[i] for i in trials]),
        )


def select(lin: _Linear, trials: Sequence[int], usable: Sequence[int]) -> list[int]:
    """The sparse support: the pursuit path's lowest BIC, then each term must pay.

    The model's parameter columns are projected out (the Schur complement of their block
    of the Gram matrix), the term columns normalized, and scikit-learn's orthogonal
    matching pursuit runs on the Gram matrix.

    Parameters
    ----------
    lin : _Linear
        The linearized problem.
    trials : sequence of int
        The trials (rows) used (repeats allowed: a bootstrap resample).
    usable : sequence of int
        Term columns that may enter.

    Returns
    -------
    list of int
        The chosen term columns, in the order the path took them.
    """
    from sklearn.linear_model import orthogonal_mp_gram  # type: ignore[import-untyped]

    g, n = lin.gram(trials)
    if n < 20 or not usable:
        return []
    npar = lin.p[0].shape[1]
    idx = [npar + c for c in usable] + [g.shape[0] - 1]
    s = g[np.ix_(idx, idx)]
    if npar:
        gpx = g[:npar, idx]
        s = s - gpx.T @ np.linalg.lstsq(g[:npar, :npar], gpx, rcond=1e-12)[0]
    k = len(usable)
    norms = np.sqrt(np.maximum(np.diag(s)[:k], 0.0))
    ok = norms > 1e-9 * max(float(norms.max()), 1e-300)
    cols = [c for c, good in zip(usable, ok, strict=True) if good]
    if not cols:
        return []
    scale = norms[ok]
    xx = s[:k, :k][np.ix_(ok, ok)] / np.outer(scale, scale)
    xy = s[:k, k][ok] / scale
    yy = float(s[k, k])

    def rss(support: list[int]) -> float:
        return _gram_rss(xx, xy, yy, support)

    kmax = min(MAX_TERMS, len(cols))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        path = orthogonal_mp_gram(xx, xy, n_nonzero_coefs=kmax, return_path=True)
    path = np.atleast_2d(path.T) if path.ndim == 2 else path[:, None].T
    best: list[int] = []
    best_bic = n * np.log(max(yy, 1e-300) / n)
    for coefs in path:
        support = [int(j) for j in np.flatnonzero(np.abs(coefs) > 0)]
        b = n * np.log(rss(support) / n) + len(support) * np.log(n)
        if b < best_bic - 1e-9:
            best, best_bic = support, b
    return [cols[j] for j in _each_term_pays(best, rss, n)]


def _each_term_pays(best: list[int], rss: Any, n: int) -> list[int]:
    """Drop, one by one, the term whose removal costs least while it costs under
    :data:`TERM_BIC`."""
    changed = True
    while changed and best:
        changed = False
        full = rss(best)
        costs = [n * np.log(rss([k for k in best if k != j]) / full) - np.log(n) for j in best]
        worst = int(np.argmin(costs))
        if costs[worst] < TERM_BIC:
            best = [k for k in best if k != best[worst]]
            changed = True
    return best


def _ranked(r: np.ndarray, p: np.ndarray, q: np.ndarray) -> list[tuple[int, float]]:
    """Each term column with the BIC fall it alone brings to the linear step, best first."""
    n = r.size
    qp = _project(p, q)
    rp = _project(p, r[:, None])[:, 0]
    rss0 = max(float(rp @ rp), 1e-300)
    out = []
    for c in range(qp.shape[1]):
        x = qp[:, c]
        xx = float(x @ x)
        if xx <= 1e-300:
            continue
        rss = max(rss0 - float(x @ rp) ** 2 / xx, 1e-300)
        out.append((c, n * np.log(rss0 / rss) - np.log(n)))
    return sorted(out, key=lambda t: -t[1])


def held_out_gain(lin: _Linear, support: Sequence[int], folds: int = 3) -> list[float]:
    """For each term of ``support``: held-out error without it over with it (> 1: it helps).

    K-fold across trials: the model's parameter steps and the terms are fitted on the other
    trials and predict the held-out trial's residual.

    Parameters
    ----------
    lin : _Linear
    support : sequence of int
    folds : int

    Returns
    -------
    list of float
        One ratio per term (1.0 with fewer than three trials: no test).
    """
    n = len(lin.r)
    if n < 3:
        return [1.0 for _ in support]
    k = min(folds, n)

    def sse(cols: list[int]) -> float:
        total = 0.0
        for j in range(k):
            train = [i for i in range(n) if i % k != j]
            test = [i for i in range(n) if i % k == j]
            r, p, q = lin.rows(train)
            a = np.hstack([p, q[:, cols]])
            coef, *_ = np.linalg.lstsq(a, r, rcond=None)
            rt, pt, qt = lin.rows(test)
            e = rt - np.hstack([pt, qt[:, cols]]) @ coef
            total += float(e @ e)
        return total

    full = sse(list(support))
    return [sse([c for c in support if c != s]) / max(full, 1e-300) for s in support]


def term_price(terms: Sequence[Term], support: Sequence[int], j: int) -> float:
    """The BIC fall term ``j`` must bring beyond BIC's own penalty to stay in ``support``.

    A term pays :data:`TERM_BIC`; the Coulomb level beside a Stribeck term is a parameter
    of one law (Coulomb with Stribeck), counted in the BIC like any other: 0.

    Parameters
    ----------
    terms : sequence of Term
        The candidate library.
    support : sequence of int
        The terms in the model.
    j : int
        The term judged (in ``support``).

    Returns
    -------
    float
    """
    law = terms[j].name == COULOMB and any(
        terms[k].name.startswith(STRIBECK) for k in support if k != j
    )
    return 0.0 if law else TERM_BIC


def _linearize(
    model: Model,
    data: FitData,
    values: dict[str, float],
    fixed: dict[str, float],
    q_names: Sequence[str],
    support: Sequence[int],
    candidates: Sequence[int],
    ar: tuple[float, float],
) -> _Linear | None:
    """The output's sensitivities at ``values``: the model's free parameters and the
    terms already chosen as parameters, the ``candidates`` as columns; rows whitened."""
    names = model.param_names
    pvec = np.array([values.get(n, model.param(n).value) for n in names])
    chosen = {q_names[j] for j in support}
    free = [i for i, n in enumerate(names) if n not in fixed and (n not in q_names or n in chosen)]
    cand = [names.index(q_names[j]) for j in candidates]
    out, sens = data.packed.run_sens(model, pvec, [*free, *cand])
    if not (np.all(np.isfinite(out[:, 0])) and np.all(np.isfinite(sens))):
        return None
    resid = data.y - out[:, 0]
    k = len(free)
    lin = _Linear([], [], [], [names[i] for i in free])
    for sl in data.slices():
        lin.r.append(_whiten(resid[sl], ar))
        lin.p.append(_whiten(sens[sl, :k], ar))
        lin.q.append(_whiten(sens[sl, k:], ar))
    return lin


def _final_inclusion(
    model: Model,
    inp: ArenaInput,
    refit: MatchResult,
    hold: dict[str, float],
    freed: dict[str, float],
    terms: Sequence[Term],
    support: Sequence[int],
    seed: int,
) -> np.ndarray | None:
    """Inclusion probabilities of the final terms: over bootstrap resamples of the trials,
    how often each still pays (removing it from the model linearized at the refit raises
    BIC by more than its :func:`term_price`). The first round's selection speaks only of a term
    chosen then; a term chosen later, or one acting through the stick band of dry
    friction (which the linear step at zero cannot see), is judged where it was fitted."""
    q_names = [f"q{j}" for j in range(len(terms))]
    held = {**hold, **freed}
    lin = _linearize(model, inp.match.data, refit.values(), held, q_names, support, [], inp.ar)
    if lin is None or not lin.r:
        return None
    cols = {j: lin.free.index(q_names[j]) for j in support}
    values = refit.values()
    rng = np.random.default_rng(seed)
    counts = np.zeros(len(terms))
    n_trials = len(lin.r)
    for _ in range(BOOTSTRAP):
        g, n = lin.gram(list(rng.integers(0, n_trials, n_trials)))
        k = g.shape[0] - 1
        xx = g[:k, :k]
        every = list(range(k))
        full = _gram_rss(xx, g[:k, k], float(g[k, k]), every)
        for j, c in cols.items():
            # the residual with term j taken out of the model (its linear contribution
            # added back), refitted by every other column
            q = float(values[q_names[j]])
            gy = g[:k, k] + q * g[:k, c]
            yy = float(g[k, k] + 2.0 * q * g[c, k] + q * q * g[c, c])
            rest = [i for i in every if i != c]
            cost = n * np.log(_gram_rss(xx, gy, yy, rest) / full) - np.log(n)
            counts[j] += cost > term_price(terms, support, j)
    return counts / BOOTSTRAP


def _bootstrap(lin: _Linear, usable: Sequence[int], n_terms: int, seed: int) -> np.ndarray:
    """How often each term is selected over bootstrap resamples of the trials."""
    rng = np.random.default_rng(seed)
    counts = np.zeros(n_terms)
    n = len(lin.r)
    for _ in range(BOOTSTRAP):
        pick = rng.integers(0, n, n)
        chosen = select(lin, list(pick), list(range(len(usable))))
        for j in chosen:
            counts[usable[j]] += 1
    return counts / BOOTSTRAP
