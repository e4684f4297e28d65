"""One fit over groups of trials: some parameters each group's own, the rest shared.

The engine of ``fit --per-log`` (a group is a log) and ``fit --track`` (a group is a
short block of a session). The groups are simulated apart, each with its own parameter
vector, and fitted together by Levenberg-Marquardt on the block-arrow normal equations:
each group's Jacobian touches the shared parameters and its own only, so a step solves
the shared parameters' Schur complement and then each group's own (cost linear in the
number of groups). Each group's residual and Jacobian come compressed (its ``[J | r]``
factored to ``k + 1`` rows by :class:`~balancer_id.identify.matching._Problem`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from balancer_id.errors import IdentificationError, UsageError
from balancer_id.identify.data import FitData, TrialData, thrust_levels
from balancer_id.identify.matching import ParameterEstimate, _at_bound, _Problem
from balancer_id.identify.metrics import correlation_time
from balancer_id.identify.starts import lag_floor
from balancer_id.model.spec import Model

#: The fit stops when no step moves an estimate by more than this fraction of its
#: standard error (as :data:`~balancer_id.identify.matching.STOP_STEP`).
STOP_STEP = 0.01
MAX_ITERATIONS = 60


@dataclass
class GroupedFit:
    """The outcome of :func:`fit_grouped`.

    Attributes
    ----------
    model : Model
        The model.
    shared : dict of str to ParameterEstimate
        The shared parameters (fitted and held).
    own : list of dict of str to ParameterEstimate
        Each group's own parameters.
    rss : float
        Residual sum of squares over all samples.
    n_samples : int
        Samples fitted.
    n_free : int
        Free parameters in all (shared plus every group's own).
    tau : float
        The residual's correlation time (samples); standard errors are widened by its
        square root, and the information criteria count ``n_samples / tau`` samples.
    group_rss, group_n : list
        Each group's residual sum of squares and sample count.
    own_time : list of dict of str to float
        Each group's own parameters' times: the mean sample time weighted by the
        parameter's information (its sensitivity squared): the time an estimate of a
        parameter that moves within the group stands for.
    own_given_shared : list of dict of str to float or None
        Each group's own parameters' standard errors given the shared values: the part of
        their error independent from group to group (the rest, through the shared
        values' error, is common to all groups).
    converged : bool
        Whether the steps became a small fraction of every standard error.
    iterations : int
        Levenberg-Marquardt iterations.
    """

    model: Model
    shared: dict[str, ParameterEstimate]
    own: list[dict[str, ParameterEstimate]]
    rss: float
    n_samples: int
    n_free: int
    tau: float
    group_rss: list[float]
    group_n: list[int]
    own_time: list[dict[str, float]]
    own_given_shared: list[dict[str, float | None]]
    converged: bool
    iterations: int
    #: Per group, what a change of the own parameters between its trials would do to
    #: the estimates (:class:`WithinGroup`; see :meth:`moved_within`).
    within: list[WithinGroup] = field(default_factory=list)

    def moved_within(
        self, offsets: Sequence[np.ndarray]
    ) -> tuple[dict[str, float], list[dict[str, float]]]:
        """The estimates had each group's own parameters been offset trial by trial.

        A group fits one value of each own parameter to all its trials; where the
        parameter moves between them (a block of a session while it drifts) the estimates,
        the shared ones too, take up the difference. Given each trial's offset from the
        group's value (from a smoothed path of the parameter), the least-squares estimates
        with those offsets in the model are one Gauss-Newton step away (the offsets'
        effect on the response is linear in them through the sensitivities): the shared
        values and each group's own, corrected.

        Parameters
        ----------
        offsets : sequence of numpy.ndarray
            Per group, an array ``trials x own parameters``: each trial's offset of each
            own parameter from the group's value.

        Returns
        -------
        (dict of str to float, list of dict of str to float)
            The shared parameters' corrected values, and each group's own.
        """
        shared_names = [n for n, e in self.shared.items() if e.vary]
        own_names = list(self.own[0]) if self.own else []
        p = len(shared_names)
        s = np.array([self.shared[n].value for n in shared_names], float)
        schur = np.zeros((p, p))
        rhs = np.zeros(p)
        solved = []
        for w, d in zip(self.within, offsets, strict=True):
            grad = np.einsum("kjc,kj->c", w.gradients, np.asarray(d, float))
            gs, go = grad[:p], grad[p:]
            inv = np.linalg.pinv(w.hoo)
            schur += w.hss - w.hso @ inv @ w.hso.T
            rhs -= gs - w.hso @ inv @ go
            solved.append((inv, go, w.hso))
        ds = np.linalg.lstsq(schur, rhs, rcond=None)[0] if p else np.zeros(0)
        shared = {n: float(s[j] + ds[j]) for j, n in enumerate(shared_names)}
        owns = []
        for (inv, go, hso), own in zip(solved, self.own, strict=True):
            do = inv @ (-go - hso.T @ ds)
            owns.append({n: float(own[n].value + do[j]) for j, n in enumerate(own_names)})
        return shared, owns

    @property
    def n_effective(self) -> float:
        """Independent samples the residual is worth (``n_samples / tau``)."""
        return self.n_samples / max(self.tau, 1.0)

    @property
    def bic(self) -> float:
        """Bayesian information criterion on the effective sample count."""
        n = self.n_effective
        return float(n * np.log(self.rss / self.n_samples) + self.n_free * np.log(n))

    def values(self, group: int) -> dict[str, float]:
        """Every parameter's value in one group (its own and the shared ones).

        Parameters
        ----------
        group : int
            The group's position.

        Returns
        -------
        dict of str to float
        """
        out = {k: p.value for k, p in self.shared.items()}
        out.update({k: p.value for k, p in self.own[group].items()})
        return out


@dataclass
class WithinGroup:
    """One group's linearization at the fit (:meth:`GroupedFit.moved_within`).

    Attributes
    ----------
    hss, hso, hoo : numpy.ndarray
        The blocks of ``J^T J`` (shared-shared, shared-own, own-own).
    gradients : numpy.ndarray
        ``trials x own x (shared + own)``: ``J^T u`` with ``u`` the response's change when
        one own parameter moves by 1 in one trial only.
    times : numpy.ndarray
        ``trials x own``: each trial's information-weighted mean time of each own
        parameter (the group's own clock).
    """

    hss: np.ndarray
    hso: np.ndarray
    hoo: np.ndarray
    gradients: np.ndarray
    times: np.ndarray


def _within(sens: np.ndarray, slices: Sequence[slice], times: np.ndarray, p: int) -> WithinGroup:
    """A group's :class:`WithinGroup` from its full sensitivities."""
    ok = np.where(np.isfinite(sens), sens, 0.0)
    a, b = ok[:, :p], ok[:, p:]
    q = b.shape[1]
    grads = np.zeros((len(slices), q, p + q))
    tk = np.zeros((len(slices), q))
    for k, sl in enumerate(slices):
        rows = ok[sl]
        grads[k] = (rows.T @ rows[:, p:]).T
        w = rows[:, p:] ** 2
        total = w.sum(axis=0)
        t = times[sl]
        mean_t = float(np.mean(t)) if t.size else 0.0
        tk[k] = np.where(total > 0, (w * t[:, None]).sum(axis=0) / np.maximum(total, 1e-300),
                         mean_t)
    return WithinGroup(a.T @ a, a.T @ b, b.T @ b, grads, tk)


def _estimate(model: Model, name: str, value: float, se: float | None, lo: float, hi: float,
              vary: bool = True) -> ParameterEstimate:
    side = _at_bound(value, lo, hi) if vary else None
    return ParameterEstimate(
        name=name, value=float(value), stderr=se, unit=model.param(name).unit, vary=vary,
        at_bound=side,
    )


def _check_own(model: Model, own: Sequence[str], fixed: Mapping[str, float]) -> None:
    """Refuse an own parameter that is not the model's or is held."""
    names = list(model.param_names)
    for name in own:
        if name not in names:
            raise UsageError(
                f"{name} is not a parameter of '{model.spec}' (its parameters: {', '.join(names)})"
            )
        if name in fixed:
            raise UsageError(f"{name} is held with --fix; it cannot also be each log's own")


@dataclass
class _Layout:
    """Where each parameter sits in a group's vector: the shared ones (``p``), then the
    group's own (``q``); their bounds, and the same strictly inside (``lo_in``/``hi_in``)."""

    shared_names: list[str]
    own_names: list[str]
    idx: list[int]
    lo: np.ndarray
    hi: np.ndarray
    lo_in: np.ndarray
    hi_in: np.ndarray

    @property
    def p(self) -> int:
        return len(self.shared_names)

    @property
    def q(self) -> int:
        return len(self.own_names)

    def clip_shared(self, s: np.ndarray) -> np.ndarray:
        return np.clip(s, self.lo_in[: self.p], self.hi_in[: self.p])

    def clip_own(self, o: np.ndarray) -> np.ndarray:
        return np.clip(o, self.lo_in[self.p :], self.hi_in[self.p :])


def _layout(
    model: Model, own: Sequence[str], fixed: Mapping[str, float], trials: Sequence[TrialData]
) -> _Layout:
    """The layout of the free parameters; a drive lag's lower bound is the trials' floor."""
    names = list(model.param_names)
    shared_names = [n for n in names if n not in fixed and n not in own]
    own_names = [n for n in names if n in own]
    order = shared_names + own_names
    lo = np.array([model.param(n).min for n in order], float)
    hi = np.array([model.param(n).max for n in order], float)
    floor = lag_floor(trials)
    for j, n in enumerate(order):
        if n in model.drive_lag_names:
            lo[j] = max(lo[j], floor)
    lo_in = lo + 1e-9 * np.maximum(1.0, np.abs(lo))  # strictly inside the bounds
    hi_in = hi - 1e-9 * np.maximum(1.0, np.abs(hi))
    return _Layout(shared_names, own_names, [names.index(n) for n in order], lo, hi, lo_in, hi_in)


def _held_levels(
    model: Model,
    trials: Sequence[TrialData],
    own: Sequence[str],
    fixed: dict[str, float],
    start: Mapping[str, float] | None,
) -> None:
    """Hold the parameters of a thrust level's dependence where the trials have one level."""
    if len(thrust_levels(trials)) >= 2:
        return
    for name in model.thrust_level_names:
        if name in model.param_names and name not in fixed and name not in own:
            fixed[name] = dict(start or {}).get(name, model.param(name).value)


Parts = list[tuple[np.ndarray, np.ndarray]]


def _evaluate(
    problems: Sequence[_Problem], s: np.ndarray, o: Sequence[np.ndarray]
) -> tuple[float, Parts]:
    """The cost over all groups and each group's compressed ``(J, r)``."""
    parts = []
    cost = 0.0
    for prob, og in zip(problems, o, strict=True):
        x = np.concatenate([s, og])
        rt = prob.fun(x)
        jt = prob.jac(x)
        cost += float(rt @ rt)
        parts.append((jt, rt))
    return cost, parts


@dataclass
class _Descent:
    """Where Levenberg-Marquardt ended: the shared vector, each group's own, the parts
    there, whether it converged and after how many iterations."""

    s: np.ndarray
    o: list[np.ndarray]
    parts: Parts
    converged: bool
    iterations: int


def _descend(
    problems: Sequence[_Problem],
    lay: _Layout,
    s: np.ndarray,
    o: list[np.ndarray],
    max_iterations: int,
    spec: str,
) -> _Descent:
    """Levenberg-Marquardt on the block-arrow normal equations from ``(s, o)``."""
    p, q = lay.p, lay.q
    n_total = int(sum(pr.n_samples for pr in problems))
    cost, parts = _evaluate(problems, s, o)
    if not np.isfinite(cost):
        raise IdentificationError(f"model '{spec}' is not finite at its start values")
    lam = 1e-3
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        step_s, step_o, se_s, se_o = _lm_step(parts, p, q, lam, cost, n_total)
        if step_s is None:
            lam *= 10
            if lam > 1e10:
                break
            continue
        new_s = lay.clip_shared(s + step_s)
        new_o = [lay.clip_own(og + d) for og, d in zip(o, step_o, strict=True)]
        new_cost, new_parts = _evaluate(problems, new_s, new_o)
        if np.isfinite(new_cost) and new_cost <= cost:
            small = _small(s, new_s, se_s, o, new_o, se_o)
            s, o, cost, parts = new_s, new_o, new_cost, new_parts
            lam = max(lam / 10, 1e-9)
            if small:
                return _Descent(s, o, parts, True, iterations)
        else:
            lam *= 10
            if lam > 1e10:  # no step lowers the cost: a minimum (at a bound)
                return _Descent(s, o, parts, True, iterations)
    return _Descent(s, o, parts, False, iterations)


@dataclass
class _AtFit:
    """Each group's residual, its own parameters' times and its linearization at the fit."""

    residuals: list[np.ndarray]
    own_time: list[dict[str, float]]
    within: list[WithinGroup]

    def rss_and_tau(self, problems: Sequence[_Problem]) -> tuple[float, float]:
        """The residual sum of squares over all groups, and the residual's correlation
        time (samples, at least 1) over every trial's stretch."""
        rss = float(sum(float(r @ r) for r in self.residuals))
        segs = [
            r[sl] for pr, r in zip(problems, self.residuals, strict=True) for sl in pr.data.slices()
        ]
        return rss, max(correlation_time([x - x.mean() for x in segs if x.size]), 1.0)


def _start_vectors(
    lay: _Layout,
    full: Mapping[str, float],
    n_groups: int,
    own_start: Sequence[Mapping[str, float]] | None,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """The shared start vector and each group's own (``own_start``'s, else ``full``'s),
    strictly inside the bounds."""
    s = lay.clip_shared(np.array([full[n] for n in lay.shared_names], float))
    o = []
    for g in range(n_groups):
        given = dict(own_start[g]) if own_start is not None else {}
        o.append(lay.clip_own(np.array([given.get(n, full[n]) for n in lay.own_names], float)))
    return s, o


def _at_fit(problems: Sequence[_Problem], lay: _Layout, end: _Descent) -> _AtFit:
    """Evaluate every group at the fit: residuals, own times, within-group linearizations."""
    out = _AtFit([], [], [])
    for pr, og in zip(problems, end.o, strict=True):
        r, sens = pr.evaluate(np.concatenate([end.s, og]))
        out.residuals.append(np.where(np.isfinite(r), r, 0.0))
        times = np.concatenate([td.time for td in pr.data.trials])[: r.size]
        if lay.q:
            out.within.append(_within(sens, pr.data.slices(), times, lay.p))
        w = sens[:, lay.p :] ** 2
        total = w.sum(axis=0)
        out.own_time.append(
            {
                name: float(w[:, j] @ times / total[j]) if total[j] > 0 else float(np.mean(times))
                for j, name in enumerate(lay.own_names)
            }
        )
    return out


def _estimates(
    model: Model,
    lay: _Layout,
    end: _Descent,
    fixed: Mapping[str, float],
    cov: tuple[np.ndarray | None, list],
    sigma2: float,
) -> tuple[dict[str, ParameterEstimate], list[dict[str, ParameterEstimate]], list[dict]]:
    """The shared estimates (fitted, then held), each group's own, and their standard
    errors given the shared values."""
    p, lo, hi = lay.p, lay.lo, lay.hi
    cov_s, cov_o = cov
    shared = {}
    for j, name in enumerate(lay.shared_names):
        shared[name] = _estimate(model, name, end.s[j], _se(cov_s, j, sigma2), lo[j], hi[j])
    for name, value in fixed.items():
        if name in model.param_names:
            shared[name] = _estimate(model, name, value, None, -np.inf, np.inf, vary=False)
    owns = []
    own_given_shared = []
    for og, (cond, common) in zip(end.o, cov_o, strict=True):
        full_cov = None if cond is None else cond + common
        owns.append(
            {
                name: _estimate(model, name, og[j], _se(full_cov, j, sigma2), lo[p + j], hi[p + j])
                for j, name in enumerate(lay.own_names)
            }
        )
        own_given_shared.append(
            {name: _se(cond, j, sigma2) for j, name in enumerate(lay.own_names)}
        )
    return shared, owns, own_given_shared


def fit_grouped(
    model: Model,
    groups: Sequence[Sequence[TrialData]],
    own: Sequence[str],
    *,
    start: Mapping[str, float] | None = None,
    own_start: Sequence[Mapping[str, float]] | None = None,
    fixed: Mapping[str, float] | None = None,
    max_iterations: int = MAX_ITERATIONS,
    robust_shared: bool = False,
) -> GroupedFit:
    """Fit ``model`` over ``groups``: ``own`` parameters per group, the rest shared.

    Parameters
    ----------
    model : Model
        The model.
    groups : sequence of sequence of TrialData
        The groups' trials (a log's, or a block of a session's, each made to start on
        its own: no trial continues one of another group).
    own : sequence of str
        The parameters each group has its own value of.
    start : mapping of str to float, optional
        Start values of every parameter (a joint fit's).
    own_start : sequence of mapping, optional
        Start values of the own parameters per group (default: ``start``'s).
    fixed : mapping of str to float, optional
        Parameters held (shared).
    max_iterations : int
        Most Levenberg-Marquardt iterations.
    robust_shared : bool
        Widen the shared parameters' covariance (and the part of every group's error
        that comes through it) to the groups' cluster-robust (sandwich) covariance where
        that is larger (:func:`_robust_shared`): the groups then need not agree with the
        model's noise, and a residual correlated within a group counts as it is.

    Returns
    -------
    GroupedFit

    Raises
    ------
    UsageError
        An own parameter that is not one of the model's, or is held.
    IdentificationError
        No group, or a simulation that is not finite at the start.
    """
    fixed = dict(fixed or {})
    _check_own(model, own, fixed)
    if not groups or not all(groups):
        raise IdentificationError("no trials to fit in a group")
    all_trials = [td for g in groups for td in g]
    _held_levels(model, all_trials, own, fixed, start)
    full = model.resolve({**dict(start or {}), **fixed})
    lay = _layout(model, own, fixed, all_trials)
    base = np.array([full[n] for n in model.param_names], float)
    s, o = _start_vectors(lay, full, len(groups), own_start)
    problems = [_Problem(model, FitData.build(list(g)), base, lay.idx) for g in groups]
    end = _descend(problems, lay, s, o, max_iterations, model.spec)
    n_obs = int(sum(pr.n_samples for pr in problems))
    k = lay.p + lay.q * len(groups)
    at = _at_fit(problems, lay, end)
    rss, tau = at.rss_and_tau(problems)
    sigma2 = rss / max(n_obs - k, 1) * tau
    cov = _covariances(end.parts, lay.p, lay.q, sigma2 if robust_shared else None)
    shared, owns, own_given_shared = _estimates(model, lay, end, fixed, cov, sigma2)
    return GroupedFit(
        model=model,
        shared=shared,
        own=owns,
        rss=rss,
        n_samples=n_obs,
        n_free=k,
        tau=tau,
        group_rss=[float(r @ r) for r in at.residuals],
        group_n=[int(r.size) for r in at.residuals],
        own_time=at.own_time,
        own_given_shared=own_given_shared,
        converged=end.converged,
        iterations=end.iterations,
        within=at.within,
    )


def _se(cov: np.ndarray | None, j: int, sigma2: float) -> float | None:
    if cov is None or not np.isfinite(cov[j, j]) or cov[j, j] < 0:
        return None
    return float(np.sqrt(cov[j, j] * sigma2))


def _small(s, new_s, se_s, o, new_o, se_o) -> bool:
    """Every estimate moved by less than STOP_STEP of its standard error."""
    with np.errstate(divide="ignore", invalid="ignore"):
        if se_s is not None and np.size(s) and np.any(np.abs(new_s - s) > STOP_STEP * se_s):
            return False
        for og, ng, sg in zip(o, new_o, se_o, strict=True):
            if np.size(og) and np.any(np.abs(ng - og) > STOP_STEP * sg):
                return False
    return True


def _lm_step(parts, p: int, q: int, lam: float, cost: float, n: int):
    """A damped Gauss-Newton step on the block-arrow normal equations, and each
    parameter's standard error at the current point (undamped, white residual)."""
    hss = np.zeros((p, p))
    gs = np.zeros(p)
    blocks = []
    for jt, rt in parts:
        a, b = jt[:, :p], jt[:, p:]
        hss += a.T @ a
        gs += a.T @ rt
        blocks.append((a.T @ b, b.T @ b, b.T @ rt))
    k = p + q * len(parts)
    sigma2 = cost / max(n - k, 1)
    try:
        damp_s = hss + lam * np.diag(np.diag(hss) + 1e-12)
        schur = damp_s.copy()
        rhs = -gs.copy()
        solved = []
        se_o = []
        for hso, hoo, go in blocks:
            damp_o = hoo + lam * np.diag(np.diag(hoo) + 1e-12)
            inv = np.linalg.inv(damp_o)
            solved.append((hso, inv, go))
            schur -= hso @ inv @ hso.T
            rhs += hso @ inv @ go
            se_o.append(np.sqrt(np.abs(np.diag(np.linalg.pinv(hoo))) * sigma2))
        ds = np.linalg.solve(schur, rhs) if p else np.zeros(0)
        do = [inv @ (-go - hso.T @ ds) for hso, inv, go in solved]
        se_s = np.sqrt(np.abs(np.diag(np.linalg.pinv(hss))) * sigma2) if p else np.zeros(0)
    except np.linalg.LinAlgError:
        return None, None, None, None
    if not (np.all(np.isfinite(ds)) and all(np.all(np.isfinite(d)) for d in do)):
        return None, None, None, None
    return ds, do, se_s, se_o


def _covariances(parts, p: int, q: int, robust_sigma2: float | None = None):
    """``inv(J^T J)``: its shared block, and each group's own block in two parts: given the
    shared values (independent from group to group) and through the shared values' error
    (common to all groups); their sum is the marginal covariance. With ``robust_sigma2``
    (the noise variance the covariances are later scaled by) the shared block is widened
    to the groups' sandwich covariance where that is larger (:func:`_robust_shared`)."""
    hss = np.zeros((p, p))
    blocks = []
    for jt, _ in parts:
        a, b = jt[:, :p], jt[:, p:]
        hss += a.T @ a
        blocks.append((a.T @ b, b.T @ b))
    try:
        schur = hss.copy()
        invs = []
        for hso, hoo in blocks:
            inv = np.linalg.inv(hoo)
            invs.append(inv)
            schur -= hso @ inv @ hso.T
        cov_s = np.linalg.inv(schur) if p else np.zeros((0, 0))
        if robust_sigma2 is not None and p:
            scores = []
            for (jt, rt), (hso, _), inv in zip(parts, blocks, invs, strict=True):
                a, b = jt[:, :p], jt[:, p:]
                scores.append(a.T @ rt - hso @ inv @ (b.T @ rt))
            cov_s = _robust_shared(cov_s, np.array(scores), robust_sigma2)
        cov_o = []
        for (hso, _), inv in zip(blocks, invs, strict=True):
            m = inv @ hso.T  # q x p
            cov_o.append((inv, m @ cov_s @ m.T))
    except np.linalg.LinAlgError:
        return None, [(None, None)] * len(parts)
    return cov_s, cov_o


def _robust_shared(cov: np.ndarray, scores: np.ndarray, sigma2: float) -> np.ndarray:
    """The shared parameters' covariance widened to the groups' sandwich where larger.

    The sandwich ``C U C`` (``C = inv`` of the shared Schur complement, ``U`` the sum over
    groups of each group's score on the shared parameters, its own ones profiled out,
    squared; times ``G / (G - p)`` for few groups) holds whatever the groups disagree by
    beyond the noise (a residual correlated within a group, a group the model fits less
    well than the others); the model-based ``sigma2 C`` holds the noise. The larger of the
    two in every direction (their positive semi-definite maximum) is returned, in the units
    of ``cov`` (to be scaled by ``sigma2`` as it is).

    Parameters
    ----------
    cov : numpy.ndarray
        ``inv`` of the shared parameters' Schur complement (``p x p``).
    scores : numpy.ndarray
        One row per group: its score on the shared parameters (``J_s^T r`` with the own
        parameters profiled out).
    sigma2 : float
        The noise variance the model-based covariance is scaled by.

    Returns
    -------
    numpy.ndarray
    """
    g, p = scores.shape
    if g <= p + 1 or not np.all(np.isfinite(scores)) or sigma2 <= 0:
        return cov
    u = scores.T @ scores * g / (g - p)
    sandwich = cov @ u @ cov / sigma2
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    if np.any(w <= 0):
        return cov
    half = v @ np.diag(np.sqrt(w)) @ v.T
    inv_half = v @ np.diag(1 / np.sqrt(w)) @ v.T
    m = inv_half @ sandwich @ inv_half
    lam, e = np.linalg.eigh(0.5 * (m + m.T))
    widened = e @ np.diag(np.maximum(lam, 1.0)) @ e.T
    return half @ widened @ half
