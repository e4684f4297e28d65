"""Simulation matching: one bounded least-squares fit of a model over all trials at once."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import FrozenInstanceError, dataclass, field
from typing import Any

import numpy as np

from balancer_id.errors import IdentificationError, UsageError
from balancer_id.identify import basins
from balancer_id.identify.data import FitData, TrialData, thrust_levels
from balancer_id.identify.display import Displayable
from balancer_id.identify.metrics import correlation_time, error_metrics
from balancer_id.identify.starts import lag_floor
from balancer_id.model.spec import Model
from balancer_id.notes import Note
from balancer_id.records import FrozenDict
from balancer_id.simulation.kernel import OUT_COLUMNS
from balancer_id.status import tell

#: Mirrors of the best end tried in a default fit: the first best's, and once more where
#: a later start found a better end (world 7562195021: the first end sat at a bound with
#: no mirror; the better end's mirror, the truth's basin 43 noise variances better, was
#: never started from, and the wrong basin was trusted).
MIRRORS = 2


@dataclass
class ParameterEstimate:
    """One fitted (or held) parameter."""

    name: str
    value: float
    stderr: float | None
    unit: str
    vary: bool
    at_bound: str | None = None
    #: The profile-likelihood 95 % interval, where the Wald one crosses a bound
    #: (:func:`~balancer_id.identify.intervals.attach_profile_intervals`).
    profile: tuple[float, float] | None = None
    #: ``"above"`` (a limit above every value reached) or ``"below"`` (a friction or
    #: delay below what the data resolve): the estimate is the bound its profile
    #: interval's inner end gives, not a value (:mod:`~balancer_id.identify.reach`).
    not_reached: str | None = None
    #: Why this parameter alone is not trusted (a check that moves it beyond its
    #: standard error, :mod:`~balancer_id.identify.timing`); empty: nothing against it.
    distrust: list[str] = field(default_factory=list)
    #: The part of ``stderr`` from where the steps lie between their samples
    #: (:func:`~balancer_id.identify.timing.sampling_variance`): no new trial reduces it.
    phase_se: float = 0.0
    #: How many times the thrust levels' errors and the trials' scatter widened ``stderr``
    #: (:func:`~balancer_id.identify.trial_scatter.widen_by_trial_scatter`; 1: not at all):
    #: a profile interval's threshold is widened alike.
    scatter_ratio: float = 1.0
    _sealed: bool = field(default=False, init=False, repr=False, compare=False)

    def __setattr__(self, name: str, value: object) -> None:
        if getattr(self, "_sealed", False):
            raise FrozenInstanceError(f"an estimate is sealed in a FitResult; cannot set {name}")
        object.__setattr__(self, name, value)

    def seal(self) -> ParameterEstimate:
        """Make the estimate complete: no field can be set, ``distrust`` a tuple (the
        checks after the optimizer annotate it first; :meth:`MatchResult.seal` seals it).

        Returns
        -------
        ParameterEstimate
            This estimate.
        """
        object.__setattr__(self, "distrust", tuple(self.distrust))
        object.__setattr__(self, "_sealed", True)
        return self

    @property
    def claim(self) -> str | None:
        """``">= 3.4"`` or ``"<= 0.02"`` for a parameter not reached, else None."""
        if self.not_reached is None or self.profile is None:
            return None
        if self.not_reached == "above":
            return f">= {self.profile[0]:.3g}"
        return f"<= {self.profile[1]:.3g}"

    @property
    def wald_ci95(self) -> tuple[float, float] | None:
        """The Wald 95 % confidence interval (value ± 1.96 stderr)."""
        if self.stderr is None or not np.isfinite(self.stderr):
            return None
        return (self.value - 1.96 * self.stderr, self.value + 1.96 * self.stderr)

    @property
    def ci95(self) -> tuple[float, float] | None:
        """The 95 % confidence interval: the profile one when computed, else Wald's."""
        return self.profile if self.profile is not None else self.wald_ci95

    @property
    def ci95_method(self) -> str | None:
        """``"profile"`` or ``"wald"`` (None without an interval)."""
        if self.profile is not None:
            return "profile"
        return "wald" if self.wald_ci95 is not None else None

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "value": self.value,
            "stderr": self.stderr,
            "unit": self.unit,
            "vary": self.vary,
            "ci95": list(self.ci95) if self.ci95 else None,
            "ci95_method": self.ci95_method,
            "at_bound": self.at_bound,
            "not_reached": self.not_reached,
            "claim": self.claim,
        }


@dataclass(repr=False)
class MatchResult(Displayable):
    """The outcome of :func:`match_trials`."""

    model: Model
    parameters: dict[str, ParameterEstimate]
    correlations: dict[str, dict[str, float]]
    metrics: dict[str, float]
    trial_rmse: list[float]
    y: np.ndarray
    y_model: np.ndarray
    data: FitData
    success: bool
    message: str
    nfev: int
    warnings: list[Note | str] = field(default_factory=list)
    #: The distinct optima of a multi-start fit, best first (empty for one start).
    optima: list[basins.Optimum] = field(default_factory=list)
    #: Rival explanations that fit as well and move a trusted value
    #: (:class:`~balancer_id.identify.rivals.Rival`, from
    #: :func:`~balancer_id.identify.rivals.check_rivals`).
    rivals: list[Any] = field(default_factory=list)
    _sealed: bool = field(default=False, init=False, repr=False, compare=False)

    def __setattr__(self, name: str, value: object) -> None:
        if getattr(self, "_sealed", False):
            raise FrozenInstanceError(f"a MatchResult is sealed in a FitResult; cannot set {name}")
        object.__setattr__(self, name, value)

    def seal(self) -> MatchResult:
        """Make the fit complete: no field can be set and its tables (parameters, metrics,
        correlations) and lists (warnings, optima, per-trial RMSE) are read-only.

        The checks that follow the optimizer (the settled limits, the trials' scatter,
        the timing, the profile intervals) annotate a match before it is sealed; a
        :class:`~balancer_id.identify.result.FitResult` seals the match it holds.

        Returns
        -------
        MatchResult
            This match.
        """
        if self._sealed:
            return self
        tables = {
            "parameters": FrozenDict({k: e.seal() for k, e in self.parameters.items()}),
            "metrics": FrozenDict(self.metrics),
            "correlations": None
            if self.correlations is None
            else FrozenDict({k: FrozenDict(row) for k, row in self.correlations.items()}),
            "warnings": tuple(self.warnings),
            "optima": tuple(self.optima),
            "rivals": tuple(self.rivals),
            "trial_rmse": tuple(self.trial_rmse),
            "_sealed": True,
        }
        for name, value in tables.items():
            object.__setattr__(self, name, value)
        return self

    def _shown_match(self) -> MatchResult:
        return self

    @property
    def trusted(self) -> bool:
        """False when a note says the fit cannot be trusted (severity ``error``)."""
        return not any(isinstance(n, Note) and n.severity == "error" for n in self.warnings)

    def _headline(self) -> str:
        values = ", ".join(f"{k}={p.value:.4g}" for k, p in list(self.parameters.items())[:4])
        fit = self.metrics.get("nrmse_fit_percent", float("nan"))
        return f"{self.model.spec}: {values}; fit {fit:.1f} %"

    def values(self) -> dict[str, float]:
        """Parameter name -> value."""
        return {k: p.value for k, p in self.parameters.items()}

    @property
    def residual(self) -> np.ndarray:
        """Measured minus simulated acceleration over all samples."""
        return self.y - self.y_model


@dataclass
class _Outcome:
    """One optimizer run: the point, its residual, ``J^T J`` there, and how it ended."""

    x: np.ndarray
    residual: np.ndarray
    jtj: np.ndarray
    success: bool
    message: str
    nfev: int

    @property
    def chisqr(self) -> float:
        return _sumsq(self.residual)


def _residual_and_sens(out: np.ndarray, y: np.ndarray, sens: np.ndarray) -> tuple[np.ndarray, bool]:
    """The residual ``out[:, 0] - y`` and whether it is finite; rows where it or the
    sensitivities are not finite get residual 1e3 and a zero Jacobian (``sens`` in place)."""
    r = out[:, 0] - y
    finite = bool(np.isfinite(r).all())
    if not (finite and np.isfinite(sens).all()):
        bad = ~np.isfinite(r) | ~np.all(np.isfinite(sens), axis=1)
        r[bad] = 1e3
        sens[bad] = 0.0
    return r, finite


def _padded(r: np.ndarray, rows: int) -> np.ndarray:
    """``r`` with zero rows added to ``rows`` (fewer samples than unknowns)."""
    return np.vstack([r, np.zeros((rows - r.shape[0], r.shape[1]))])


def _sumsq(x: np.ndarray) -> float:
    """``x @ x`` without BLAS (a threaded BLAS dot of 10,000 samples can take 10 ms)."""
    return float(np.einsum("i,i", x, x))


def _gram(a: np.ndarray, r: np.ndarray, rows: int = 2048) -> np.ndarray:
    """``[a | r]^T [a | r]`` in blocks of rows, each too small for BLAS to start its threads."""
    k = a.shape[1]
    g = np.zeros((k + 1, k + 1))
    with np.errstate(over="ignore", invalid="ignore"):  # far from the data (a profile's end)
        _accumulate_gram(g, a, r, rows)
    return g


def _accumulate_gram(g: np.ndarray, a: np.ndarray, r: np.ndarray, rows: int) -> None:
    """Add ``[a | r]^T [a | r]`` to ``g`` block by block (see :func:`_gram`)."""
    k = a.shape[1]
    for i in range(0, a.shape[0], rows):
        block = a[i : i + rows]
        rb = r[i : i + rows]
        g[:k, :k] += block.T @ block
        g[k, :k] += rb @ block
        g[k, k] += rb @ rb
    g[:k, k] = g[k, :k]


def _triangular(jac: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Upper-triangular ``R`` (``k+1`` square) with ``R^T R = [J | r]^T [J | r]``.

    The Cholesky factor of the small Gram matrix (cheap, one pass over the samples); the
    QR factorization of ``[J | r]`` where the Gram matrix is too ill-conditioned for it.
    """
    chol = _cholesky_of_gram(_gram(jac, r))
    if chol is not None:
        return chol
    return np.asarray(np.linalg.qr(np.column_stack([jac, r]), mode="r"))


def _cholesky_of_gram(gram: np.ndarray) -> np.ndarray | None:
    """Upper ``R`` with ``R^T R = gram`` (equilibrated), or None where ``gram`` is too
    ill-conditioned for it (its factor would lose the small directions)."""
    d = np.sqrt(np.diag(gram))
    if not (np.all(d > 0) and np.all(np.isfinite(gram))):  # an overflowed column: QR says
        return None
    try:
        chol = np.linalg.cholesky(gram / np.outer(d, d))
    except np.linalg.LinAlgError:
        return None
    if np.min(np.abs(np.diag(chol))) > 1e-5:
        return np.asarray(chol.T * d)
    return None


def _merged_r(r_so_far: np.ndarray, block: np.ndarray) -> np.ndarray:
    """The triangular factor of ``[r_so_far; block]`` (a QR merge, block by block)."""
    return np.asarray(np.linalg.qr(np.vstack([r_so_far, block]), mode="r"))


#: A fit stops when the Gauss-Newton step left is below this fraction of every parameter's
#: standard error (the noise's own scale): further iterations would move no estimate by
#: more than 1 % of its uncertainty, which adds 0.005 % to its variance. scipy's own
#: tolerances (``ftol`` etc.) still stop a fit this test does not (at a bound, singular).
STOP_STEP = 0.01

#: A fit also stops when taking the Gauss-Newton step on the linear model is estimated to
#: leave less than this many standard errors (see :meth:`_Problem.converged`): 0.05 adds
#: 0.25 % to an estimate's variance and saves the last simulation.
STOP_LINEAR = 0.05

#: The best evaluation's residual and Jacobian are kept for reuse up to this size; beyond
#: it (a shift-long session) they are simulated again when needed, so that the fit holds
#: one evaluation's arrays at a time, not two.
BEST_KEPT_BYTES = 64 * 2**20

#: An evaluation whose arrays (rows x (outputs + free parameters)) would exceed this
#: streams instead: the samples are simulated :data:`STREAM_ROWS` at a time (the state
#: and its sensitivities running on across the blocks) and reduced block by block to the
#: compressed problem, so that a shift-long log's fit never holds its Jacobian.
STREAM_BYTES = 96 * 2**20
STREAM_ROWS = 1 << 16

CONVERGED = "converged: the step left is a small fraction of every standard error"


class _Problem:
    """Residual and Jacobian of one fit, from one simulation with sensitivities.

    Each evaluation simulates once with forward sensitivities, giving the residual ``r``
    (``n`` samples) and its Jacobian ``J`` (``n x k``) together. The optimizer is handed
    the same least-squares problem compressed to ``k + 1`` rows: the QR factorization
    ``[J | r] = Q R`` gives ``r~ = R[:, k]`` and ``J~ = R[:, :k]`` with
    ``|r~| = |r|``, ``J~^T J~ = J^T J`` and ``J~^T r~ = J^T r``, so every step,
    cost and stopping test is the full problem's, at a fraction of the optimizer's
    per-iteration cost on ``n x k`` matrices.
    """

    def __init__(self, model: Model, data: FitData, base: np.ndarray, free: list[int]):
        self.model = model
        self.data = data
        self.base = base
        self.free = free
        self.nfev = 0
        #: Whether the last evaluation gave a finite simulated output everywhere.
        self.finite = True
        self._key: bytes | None = None
        self._jac = np.zeros((len(free) + 1, len(free)))
        self._fun = np.zeros(len(free) + 1)
        self._best: tuple[float, bytes, np.ndarray, np.ndarray] | None = None
        self.n_samples = int(data.y.size)
        #: Whether evaluations stream over blocks of rows (see :data:`STREAM_BYTES`).
        self.stream = self.n_samples * (len(OUT_COLUMNS) + len(free)) * 8 > STREAM_BYTES
        self._last_key: bytes | None = None
        self._last_q: float | None = None
        #: The Gauss-Newton step from the point :meth:`converged` last looked at.
        self.gn_step: np.ndarray | None = None
        #: The fit's bounds of the free parameters, the names bounded by the user and
        #: the shortest drive lag the samples resolve (set by :func:`match_trials`).
        self.lo = np.full(len(free), -np.inf)
        self.hi = np.full(len(free), np.inf)
        self.user_bounds: set[str] = set()
        self.lag_floor = 0.0

    def full(self, x: np.ndarray) -> np.ndarray:
        """The whole parameter vector with the free ones set to ``x``."""
        p = self.base.copy()
        p[self.free] = x
        return p

    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual and Jacobian over every sample at ``x`` (one simulation)."""
        self.nfev += 1
        out, sens = self.data.packed.run_sens(self.model, self.full(x), self.free)
        r, self.finite = _residual_and_sens(out, self.data.y, sens)
        keep = r.nbytes + sens.nbytes <= BEST_KEPT_BYTES  # a long session: simulate again
        self._remember(x, _sumsq(r), (r, sens) if keep else None)
        return r, sens

    def _remember(
        self, x: np.ndarray, cost: float, arrays: tuple[np.ndarray, np.ndarray] | None
    ) -> None:
        """Keep ``x`` as the best point evaluated when its cost is the lowest so far,
        with its residual and Jacobian when ``arrays`` holds them (None: not kept)."""
        if self._best is not None and cost >= self._best[0]:
            return
        if arrays is None:
            arrays = np.empty(0), np.empty((0, len(self.free)))
        self._best = (cost, np.asarray(x, dtype=float).tobytes(), *arrays)

    def at(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual and Jacobian at ``x``, reusing the best evaluation when it is there."""
        best = self._best
        if best is not None and best[1] == np.asarray(x, dtype=float).tobytes():
            if best[2].size == self.n_samples:  # kept (see BEST_KEPT_BYTES)
                return best[2], best[3]
        return self.evaluate(x)

    def residual(self, x: np.ndarray) -> np.ndarray:
        """The residual over every sample at ``x`` (a plain simulation)."""
        y = self.data.y
        if not self.stream:
            r = self.data.packed.run(self.model, self.full(x))[:, 0] - y
        else:
            r = np.empty(self.n_samples)
            for first, out in self.data.packed.stream(self.model, self.full(x), STREAM_ROWS):
                stop = first + out.shape[0]
                np.subtract(out[:, 0], y[first:stop], out=r[first:stop])
        return np.where(np.isfinite(r), r, 1e3)

    def _compressed(self, x: np.ndarray, *, by_qr: bool = False) -> np.ndarray:
        """``R`` of ``[J | r]`` at ``x``, streamed over blocks of rows (one simulation).

        The Gram matrix is summed block by block and factored as :func:`_triangular`
        does; where it is too ill-conditioned, the evaluation is made again merging each
        block's QR factor instead (``by_qr``).
        """
        self.nfev += 1
        k = len(self.free)
        gram = np.zeros((k + 1, k + 1))
        merged = np.zeros((0, k + 1))
        cost = 0.0
        finite = True
        y = self.data.y
        blocks = self.data.packed.stream_sens(self.model, self.full(x), self.free, STREAM_ROWS)
        for first, out, sens in blocks:
            r, finite_here = _residual_and_sens(out, y[first : first + out.shape[0]], sens)
            finite = finite and finite_here
            cost += _sumsq(r)
            if by_qr:
                merged = _merged_r(merged, np.column_stack([sens, r]))
            else:
                with np.errstate(over="ignore", invalid="ignore"):
                    _accumulate_gram(gram, sens, r, 2048)
        self.finite = finite
        self._remember(x, cost, None)
        if by_qr:
            return merged if merged.shape[0] == k + 1 else _padded(merged, k + 1)
        chol = _cholesky_of_gram(gram)
        if chol is None:
            self.nfev -= 1
            return self._compressed(x, by_qr=True)
        return chol

    def fun(self, x: np.ndarray) -> np.ndarray:
        key = np.asarray(x, dtype=float).tobytes()
        if key != self._key:
            k = len(self.free)
            if self.stream:
                aug = self._compressed(x)
            else:
                r, sens = self.evaluate(x)
                aug = _triangular(sens, r)
            self._key = key
            self._jac = aug[:, :k].copy()
            self._fun = aug[:, k].copy()
        return self._fun.copy()

    def jtj(self, x: np.ndarray) -> np.ndarray:
        """``J^T J`` at ``x`` (from the compressed problem)."""
        if np.asarray(x, dtype=float).tobytes() != self._key:
            self.fun(x)
        return self._jac.T @ self._jac

    def outcome(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The residual over every sample at ``x`` and ``J^T J`` there."""
        if self.stream:
            return self.residual(x), self.jtj(x)
        r, jac = self.at(x)
        return r, _gram(jac, r)[:-1, :-1]

    def jac(self, x: np.ndarray, *_: object) -> np.ndarray:
        if np.asarray(x, dtype=float).tobytes() != self._key:
            self.fun(x)
        return self._jac

    def converged(self, x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
        """The last step of a fit that has converged at ``x``, or None to go on.

        With ``R`` of the last evaluation (the compressed problem), the Gauss-Newton step
        ``d`` from ``x`` and each parameter's standard error ``s`` are cheap. Measured in
        standard errors (``q = max |d| / s``), the fit has converged when

        * ``q <= STOP_STEP``: one more iteration would move no estimate by more than that
          fraction of its own uncertainty; the fit stops at ``x`` (a zero step); or
        * ``q <= 1`` and ``q * (q / q_prev) <= STOP_LINEAR``, with ``q_prev`` the step at
          the previous point: the iterations contract by ``q / q_prev`` each, so taking
          ``d`` leaves an error of about ``q * q / q_prev`` standard errors. ``d`` is then
          taken on the linear model (``r + J d``) without another simulation.

        Only for the best point evaluated, with the step inside the bounds.
        """
        key = np.asarray(x, dtype=float).tobytes()
        k = len(self.free)
        if key != self._key or key == self._last_key:
            return None
        self.gn_step = None
        if self.n_samples <= k:
            return None
        with np.errstate(all="ignore"):
            try:
                inv = np.linalg.inv(self._jac[:k, :k])
            except np.linalg.LinAlgError:
                return None
            step = -inv @ self._fun[:k]
            s2 = _sumsq(self._fun) / (self.n_samples - k)
            se = np.sqrt(s2 * np.einsum("ij,ij->i", inv, inv))
            q = float(np.max(np.abs(step) / se))
        prev, self._last_key, self._last_q = self._last_q, key, q
        self.gn_step = step
        new = x + step
        if not (np.isfinite(q) and np.all(new > lo) and np.all(new < hi)):
            return None
        if self._best is None or self._best[1] != key:
            return None
        if q <= STOP_STEP:
            return np.zeros(k)
        if prev is not None and q <= 1.0 and q * q / prev <= STOP_LINEAR:
            return step
        return None

    def restart(self) -> None:
        """Forget the step history (a new start)."""
        self._last_key = None
        self._last_q = None
        self.gn_step = None

    def gauss_newton(
        self, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_nfev: int
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Plain Gauss-Newton steps from ``x0`` while they behave; the converged point.

        The common case of a fit costs no optimizer bookkeeping: each full step is taken
        while it stays strictly inside the bounds and lowers the cost, until
        :meth:`converged` stops it. Returns ``(x, last_step)`` as :meth:`converged` gives
        them, or ``(x, None)`` with the last point reached as soon as a step misbehaves
        (out of bounds, cost up, not finite, singular, the budget spent): the caller goes
        on from there with a trust-region method.
        """
        x = np.asarray(x0, dtype=float)
        if not (np.all(x > lo) and np.all(x < hi)):
            return x, None
        self.restart()
        self.fun(x)
        cost = _sumsq(self._fun)
        while True:
            last = self.converged(x, lo, hi)
            if last is not None:
                return x, last
            step = self.gn_step
            if step is None or self.nfev >= max_nfev or self._key != x.tobytes():
                return x, None
            new = x + step
            if not (np.all(np.isfinite(new)) and np.all(new > lo) and np.all(new < hi)):
                return x, None
            self.fun(new)
            new_cost = _sumsq(self._fun)
            if not (self.finite and new_cost < cost):
                return x, None
            x, cost = new, new_cost

    def linear_step(self, x: np.ndarray, step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual at ``x + step`` from the linear model at ``x``, and ``J^T J`` there.

        A streamed problem (which holds no Jacobian) simulates the residual at
        ``x + step`` instead; ``J^T J`` is the one at ``x`` (the step is a small fraction
        of every standard error).
        """
        if self.stream:
            return self.residual(x + step), self.jtj(x)
        r, jac = self.at(x)
        return r + jac @ step, _gram(jac, r)[:-1, :-1]


def match_trials(
    model: Model,
    trials: Sequence[TrialData],
    *,
    start: Mapping[str, float] | None = None,
    fixed: Mapping[str, float] | None = None,
    n_starts: int | None = 1,
    seed: int = 0,
    max_nfev: int = 2000,
    diff_step: float | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
) -> MatchResult:
    """Fit every free parameter of ``model`` to all ``trials`` at once.

    The stages: hold what one thrust level cannot determine
    (:func:`_hold_single_level`), place the start inside the bounds (:class:`_Box`), set
    up the problem (:func:`_problem`), run the starts (:class:`_StartSearch`), collect
    the best end and say where the starts disagree (:func:`_note_optima`).

    Parameters
    ----------
    model : Model
        The model to fit.
    trials : sequence of TrialData
        Step trials (any number of logs).
    start : mapping, optional
        Start values (the paper's method gives ``m_a`` and ``T_a``).
    fixed : mapping, optional
        Parameters held at the given values (``--fix``).
    n_starts : int or None
        Starts in all; the extra ones are spread around ``start``
        (:func:`~balancer_id.identify.basins.spread_starts`) and the lowest cost wins,
        for costs with more than one minimum. None: the default search, one start plus
        :data:`~balancer_id.identify.basins.DEFAULT_SPREAD` spread ones where the model
        has limits, friction or delays, or where the first ends on a bound it did not
        choose or undetermined.
    seed : int
        Seed of the extra starts.
    max_nfev : int
        Budget of model evaluations per start.
    diff_step : float, optional
        None (default) takes the Jacobian from the kernel's forward sensitivities (one
        simulation gives the residual and its Jacobian); a value uses two-point finite
        differences of relative step ``diff_step`` instead (see
        :func:`scipy.optimize.least_squares`).
    bounds : mapping of str to (float, float), optional
        Narrower bounds of some parameters (``--bounds NAME=MIN:MAX``), inside the
        model's own.

    Returns
    -------
    MatchResult

    Raises
    ------
    IdentificationError
        No trial, or the optimizer failed on every start.
    """
    if not trials:
        raise IdentificationError("no trial to fit; check the log with 'balancer-id inspect'")
    held = dict(fixed or {})
    notes = _hold_single_level(model, trials, start, held)
    box = _Box.of(model, trials, start, held, bounds)
    data = FitData.build(trials)
    problem = _problem(model, data, box, bounds, diff_step)
    search = _StartSearch(problem, model, trials, box, n_starts, seed, max_nfev, diff_step, notes)
    best, ends = search.run()
    result = _collect(model, best, problem, data, notes)
    _note_optima(result, best, ends, box.free_names)
    return result


def _hold_single_level(
    model: Model,
    trials: Sequence[TrialData],
    start: Mapping[str, float] | None,
    fixed: dict[str, float],
) -> list[Note | str]:
    """Hold (in ``fixed``) each thrust-level parameter that fewer than two thrust levels
    cannot determine, at its start value, with a note saying so.

    At 0 N only (a robot's moves) a thrust-level parameter changes nothing: D0 is the
    viscosity seen, and holding it at a guess costs no identification (an ``info`` note);
    with a push it is a guess the others trade with (an ``error`` note).

    Returns
    -------
    list of Note
    """
    notes: list[Note | str] = []
    levels = thrust_levels(trials)
    pushed = any(abs(x) > 0 for x in levels)
    for name in model.thrust_level_names:
        if name in model.param_names and name not in fixed and len(levels) < 2:
            value = dict(start or {}).get(name, model.param(name).value)
            fixed[name] = value
            notes.append(
                Note(
                    "fit.not_identifiable",
                    f"{name} is only identifiable from trials at two or more thrust levels "
                    f"(found {len(levels)}: {', '.join(f'{x:g} N' for x in levels)}); "
                    f"held at {value:g}"
                    + (
                        ", a guess: the values it trades with (D0) are no identification; "
                        "give --fix with a known value or record more levels"
                        if pushed
                        else " (with no operating force it changes nothing here)"
                    ),
                    subject=name,
                    severity="error" if pushed else "info",
                )
            )
    return notes


@dataclass
class _Box:
    """The start and the bounds of a fit: the whole parameter vector ``base`` (held
    values in place, free ones strictly inside their bounds), the free indices and their
    bounds ``lo``, ``hi``, and the shortest drive lag the samples resolve."""

    names: list[str]
    base: np.ndarray
    free: list[int]
    lo: np.ndarray
    hi: np.ndarray
    floor: float

    @property
    def free_names(self) -> list[str]:
        """The free parameters' names."""
        return [self.names[i] for i in self.free]

    @classmethod
    def of(
        cls,
        model: Model,
        trials: Sequence[TrialData],
        start: Mapping[str, float] | None,
        fixed: Mapping[str, float],
        bounds: Mapping[str, tuple[float, float]] | None,
    ) -> _Box:
        """The box of a fit: the model's bounds, narrowed by ``bounds`` (checked) and by
        the lag floor, with the start clipped strictly inside.

        Raises
        ------
        UsageError
            A ``--bounds`` range that is empty or outside the parameter's own.
        """
        values = dict(start or {})
        values.update(fixed)
        full = model.resolve(values)
        names = model.param_names
        base = np.array([full[n] for n in names], dtype=float)
        free = [i for i, n in enumerate(names) if n not in fixed]
        lo = np.array([model.params[i].min for i in free], dtype=float)
        hi = np.array([model.params[i].max for i in free], dtype=float)
        for name, (b_lo, b_hi) in (bounds or {}).items():
            spec = model.param(name)
            if not (spec.min <= b_lo < b_hi <= spec.max):  # NaN fails too
                raise UsageError(
                    f"--bounds {name}={b_lo:g}:{b_hi:g}: give MIN < MAX inside the "
                    f"parameter's own range {spec.min:g}:{spec.max:g}"
                )
            i = names.index(name)
            base[i] = float(np.clip(base[i], b_lo, b_hi))
            if i in free:
                lo[free.index(i)], hi[free.index(i)] = b_lo, b_hi
        floor = lag_floor(trials)  # a drive lag shorter than the samples resolve is not fitted
        for name in model.drive_lag_names:
            i = names.index(name) if name in names else -1
            if i in free and name not in (bounds or {}):
                j = free.index(i)
                lo[j] = max(lo[j], floor)
        for j, i in enumerate(free):  # starts strictly inside the bounds
            inner = 1e-3 * (hi[j] - lo[j]) if np.isfinite(hi[j] - lo[j]) else 1e-3
            base[i] = float(np.clip(base[i], lo[j] + min(inner, abs(lo[j]) + 1e-9), hi[j] - inner))
        return cls(list(names), base, free, lo, hi, floor)


def _problem(
    model: Model,
    data: FitData,
    box: _Box,
    bounds: Mapping[str, tuple[float, float]] | None,
    diff_step: float | None,
) -> _Problem:
    """The fit's :class:`_Problem`, its first start evaluated.

    Raises
    ------
    IdentificationError
        The model's acceleration is not finite at the start values.
    """
    problem = _Problem(model, data, box.base, box.free)
    problem.lo, problem.hi = box.lo.copy(), box.hi.copy()
    problem.user_bounds = set(bounds or {})
    problem.lag_floor = box.floor
    if box.free and diff_step is None:
        problem.fun(box.base[box.free])  # the first start's evaluation, kept for the optimizer
        finite = problem.finite
    else:
        finite = bool(np.all(np.isfinite(data.packed.run(model, box.base)[:, 0])))
    if not finite:
        raise IdentificationError(
            f"model '{model.spec}' gives a non-finite acceleration at its start values; "
            "check the effects' terms (a user effect returning NaN or inf?)"
        )
    return problem


class _StartSearch:
    """The starts of one fit, run one after another, the lowest cost kept.

    The designed starts first (the given one and, for a default search on a cost with
    basins, spread ones); then the mirror of the best end (the lag and the viscous time
    swapped answer a step alike), a polish of a best end cut at its budget, and, while a
    default search's best end stays suspect (:func:`_suspect`), rounds of random starts.
    """

    def __init__(
        self,
        problem: _Problem,
        model: Model,
        trials: Sequence[TrialData],
        box: _Box,
        n_starts: int | None,
        seed: int,
        max_nfev: int,
        diff_step: float | None,
        notes: list[Note | str],
    ) -> None:
        self.problem, self.model, self.trials, self.box = problem, model, trials, box
        self.seed, self.max_nfev, self.diff_step, self.notes = seed, max_nfev, diff_step, notes
        self.free_names = box.free_names
        self.auto = n_starts is None
        wants = self.auto and basins.wants_spread(model, self.free_names)
        self.spread = basins.DEFAULT_SPREAD if wants else 0
        count = self.spread if self.auto else max(int(n_starts or 1), 1) - 1
        x0 = box.base[box.free]
        self.starts = [x0, *self._spread_starts(count)]
        # the mirror of the best end, again where a later start found a better one (the
        # first best may have no mirror: a start lost at a bound)
        self.mirrors_left = MIRRORS if self.auto else 0
        self.mirrored_x: np.ndarray | None = None
        self.rounds = 0  # rounds of random starts after the designed ones
        self.polish: int | None = None  # the start that goes on from a best end cut short
        self.best: _Outcome | None = None
        self.ends: list[_Outcome] = []
        self._stopped: list[np.ndarray] = []

    def _spread_starts(self, count: int) -> list[np.ndarray]:
        box = self.box
        return list(basins.spread_starts(
            self.model, self.free_names, box.base[box.free], box.lo, box.hi, count,
            self.trials, self.seed,
        ))  # fmt: skip

    def run(self) -> tuple[_Outcome, list[_Outcome]]:
        """Run the starts.

        Returns
        -------
        (_Outcome, list of _Outcome)
            The best end (its ``nfev`` the whole search's) and every start's end.

        Raises
        ------
        IdentificationError
            The optimizer failed on every start.
        """
        box, problem = self.box, self.problem
        if not box.free:
            r = problem.residual(box.base[box.free])
            self.best = _Outcome(
                box.base[box.free], r, np.zeros((0, 0)), True, "no free parameter", 1
            )
        k = 0
        while box.free and self._has_start(k):
            k += 1
            if len(self.starts) > 1:
                tell(f"start {k}/{len(self.starts)}")
            self._run_start(self.starts[k - 1], k)
        if self.best is None:
            raise IdentificationError(
                f"fit of '{self.model.spec}' did not converge from any start; "
                "check the trials with 'balancer-id inspect' or fix known parameters with --fix"
            )
        self.best.nfev = problem.nfev
        return self.best, self.ends

    def _has_start(self, k: int) -> bool:
        """Whether there is a ``k``-th start, adding the mirror, the polish or a round
        of random starts once the ones before have run."""
        best = self.best
        if (
            k == len(self.starts)
            and self.mirrors_left > 0
            and best is not None
            and (self.mirrored_x is None or not np.allclose(best.x, self.mirrored_x, rtol=1e-3))
        ):
            self.mirrors_left -= 1  # the lag and the viscous time swapped answer a step alike
            self.mirrored_x = np.array(best.x, dtype=float)
            mirror = basins.mirror_start(self.model, self.free_names, best.x, self.trials)
            if mirror is not None:
                self.starts.append(basins.inside(mirror, self.box.lo, self.box.hi))
        if (
            k == len(self.starts)
            and self.auto
            and self.polish is None
            and best is not None
            and not best.success
        ):
            self.polish = len(self.starts)  # the best end ran out of its budget: go on
            self.starts.append(best.x)
        if k < len(self.starts):
            return True
        if not (self.auto and _suspect(self.problem, best, self.free_names)):
            return False
        if not self.spread:
            self.spread = basins.DEFAULT_SPREAD  # a suspect end: look for another basin
            self.starts += self._spread_starts(self.spread)
        elif self.rounds < basins.MORE_ROUNDS and basins.wants_spread(self.model, self.free_names):
            # still suspect after the designed starts, on a cost with basins (limits,
            # friction, lags): more starts drawn at random, a round at a time
            self.rounds += 1
            drawn = self._spread_starts(self.spread + basins.MORE_STARTS)
            self.starts += drawn[self.spread :]
            self.spread += basins.MORE_STARTS
        else:
            return False
        return True

    def _keep(self, outcome: _Outcome) -> None:
        self.ends.append(outcome)
        if self.best is None or outcome.chisqr < self.best.chisqr:
            self.best = outcome

    def _run_start(self, x0: np.ndarray, k: int) -> None:
        """Run the ``k``-th start (from 1): Gauss-Newton steps while they converge, then
        the trust-region optimizer; keep its end."""
        problem = self.problem
        used = problem.nfev
        # a default search's other starts look for a basin, not a last digit
        whole = k == 1 or not self.auto or k - 1 == self.polish
        budget = self.max_nfev if whole else min(self.max_nfev, basins.SPREAD_NFEV)
        if self.diff_step is None:
            x0, last = problem.gauss_newton(x0, self.box.lo, self.box.hi, used + budget)
            if last is not None:
                r, jtj = problem.linear_step(x0, last)
                self._keep(_Outcome(x0 + last, r, jtj, True, CONVERGED, problem.nfev - used))
                return
        problem.restart()
        outcome = self._least_squares(x0, max(budget - (problem.nfev - used), 1))
        if outcome is not None:
            self._keep(outcome)

    def _callback(self, intermediate_result: Any) -> None:
        x = np.asarray(intermediate_result.x, dtype=float)
        last = self.problem.converged(x, self.box.lo, self.box.hi)
        if last is not None:
            self._stopped.append(x)
            self._stopped.append(last)
            raise StopIteration

    def _least_squares(self, x0: np.ndarray, max_nfev: int) -> _Outcome | None:
        """One trust-region run from ``x0``, stopped where a Gauss-Newton step converges;
        None (with a note) when it fails."""
        from scipy.optimize import least_squares

        problem, diff_step = self.problem, self.diff_step
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                ret = least_squares(
                    problem.fun if diff_step is None else problem.residual,
                    x0,
                    jac=problem.jac if diff_step is None else "2-point",
                    bounds=(self.box.lo, self.box.hi),
                    method="trf",
                    x_scale="jac",
                    ftol=1e-8,
                    xtol=1e-8,
                    gtol=1e-8,
                    max_nfev=max_nfev,
                    diff_step=diff_step,
                    callback=self._callback if diff_step is None else None,
                )
            except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
                self.notes.append(Note("fit.other", f"a start failed: {exc}"))
                return None
        x_end = ret.x
        message = str(ret.message)
        if self._stopped:
            x_end, last = self._stopped[0], self._stopped[1]
            self._stopped.clear()
            r, jtj = problem.linear_step(x_end, last)
            x_end = x_end + last
            message = CONVERGED
        else:
            r, jtj = problem.outcome(x_end)
        return _Outcome(x_end, r, jtj, ret.status > 0 or message == CONVERGED, message, ret.nfev)


def _note_optima(
    result: MatchResult, best: _Outcome, ends: list[_Outcome], free_names: list[str]
) -> None:
    """Say where the starts disagree (first) and keep the distinct optima of a
    multi-start fit (with a note when there are several)."""
    disagreement = _starts_disagree(result, best, ends, free_names)
    if disagreement is not None:
        result.warnings.insert(0, disagreement)
    if len(ends) > 1:
        stderr = [result.parameters[n].stderr or np.nan for n in free_names]
        result.optima = basins.distinct_optima(
            [(e.x, e.chisqr) for e in ends], free_names, stderr, result.y.size
        )
        if len(result.optima) > 1:
            result.warnings.append(_optima_note(result.optima, len(ends)))


#: A residual correlated over more samples than this after the first start: the model
#: may follow the trials from the wrong basin (the default fit then spreads its starts).
TAU_SUSPECT = 3.0


def _suspect(problem: _Problem, out: _Outcome | None, free_names: list[str]) -> bool:
    """Whether a start's end may be the wrong basin: a parameter on a bound the user did
    not set (a drive lag at the samples' floor too: a heavy load with no lag can mimic a
    light one with a long lag), one whose standard error exceeds its value, or a residual
    correlated over more than :data:`TAU_SUSPECT` samples."""
    if out is None:
        return True
    for j, name in enumerate(free_names):
        side = _at_bound(float(out.x[j]), float(problem.lo[j]), float(problem.hi[j]))
        if side and name not in problem.user_bounds:
            return True
        if name in problem.model.drive_lag_names and out.x[j] < 2 * problem.lag_floor:
            return True
    if out.residual.size == problem.n_samples:
        slices = problem.data.slices()
        if correlation_time([out.residual[sl] for sl in slices], removed=0) > TAU_SUSPECT:
            return True
    cov = _covariance(out)
    if cov is None:
        return True
    se = np.sqrt(np.abs(np.diag(cov)))
    return bool(np.any(~np.isfinite(se) | (se > np.abs(out.x))))


def _optima_note(optima: list[basins.Optimum], n_starts: int) -> Note:
    """The distinct optima the starts ended at, best first, with their costs."""
    best = optima[0]
    others = "; ".join(
        ", ".join(f"{k} {v:.4g}" for k, v in list(o.values.items())[:3])
        + f" (cost +{o.delta_sigma2:.3g} noise variances)"
        for o in optima[1:4]
    )
    lead = ", ".join(f"{k} {v:.4g}" for k, v in list(best.values.items())[:3])
    return Note(
        "fit.optima",
        f"{n_starts} starts ended at {len(optima)} distinct optima: the best ({lead}) is "
        f"reported; the others: {others}",
        severity="info",
    )


def residual_around_steps(match: MatchResult) -> list[tuple[TrialData, np.ndarray, np.ndarray]]:
    """Each trial that starts from rest, with its residual before its step and after.

    Parameters
    ----------
    match : MatchResult
        The fit.

    Returns
    -------
    list of (TrialData, numpy.ndarray, numpy.ndarray)
        The trial, its residual at rest and its residual in motion, in the fit's order.
    """
    out = []
    residual = match.residual
    for td, sl in zip(match.data.trials, match.data.slices(), strict=True):
        if td.continues or td.input.x0 is not None:
            continue
        r = residual[sl]
        t = np.asarray(td.time, dtype=float)
        if t.size != r.size:
            continue
        before = t < td.t_step
        out.append((td, r[before], r[~before]))
    return out


def residual_continuing(match: MatchResult) -> list[np.ndarray]:
    """The residuals of the trials that continue a session (the thrust changed while the
    load moved): motion with no rest of its own, held to the other trials' rests.

    Parameters
    ----------
    match : MatchResult
        The fit.

    Returns
    -------
    list of numpy.ndarray
        One residual per continuing trial, in the fit's order.
    """
    return [
        match.residual[sl]
        for td, sl in zip(match.data.trials, match.data.slices(), strict=True)
        if td.continues
    ]


def _sensor_tau(result: MatchResult) -> float:
    """The sensor's noise correlation time (samples, >= 1): the residual's at rest before
    the steps where there are 50 resting samples, at most the whole residual's.

    A model's misfit correlates the residual in motion too (a friction it lacks: tens of
    samples); counting that as the sensor's colour made every other optimum "about as
    good" and untrusted the misfit fits whose refits diagnose compares (a Stribeck law on
    a heavy balancer went undiscovered).
    """
    whole = max(float(result.metrics.get("residual_tau", 1.0) or 1.0), 1.0)
    try:
        rests = [r for _, r, _ in residual_around_steps(result) if r.size >= 20]
    except (AttributeError, ValueError):
        return whole
    if sum(r.size for r in rests) < 50:
        return whole
    return float(min(max(correlation_time(rests, removed=1), 1.0), whole))


def _starts_disagree(
    result: MatchResult, best: _Outcome, ends: list[_Outcome], free_names: list[str]
) -> Note | None:
    """A note when another start ended about as well at another point (several optima).

    "About as well": its cost exceeds the best by less than 10 times the noise variance
    (a chi-square difference of 10: not told apart by the data), counted on independent
    samples: a residual correlated over ``tau`` samples (a coloured sensor) tells ``tau``
    times less, as the standard errors are widened (issue 31: a coloured 50 Hz log ended
    in the mirror basin, m_a 3.8 against 9.5, trusted, its truth-like rival 10.7 noise
    variances behind on a residual correlated over 8.7 samples); "another point": some
    parameter more than 3 standard errors (and 1 %) away.
    """
    n = result.y.size
    k = len(free_names)
    if len(ends) < 2 or n <= k:
        return None
    tau = _sensor_tau(result)
    s2 = best.chisqr / (n - k) * tau
    for other in ends:
        if other is best or not np.isfinite(other.chisqr) or other.chisqr - best.chisqr > 10 * s2:
            continue
        for j, name in enumerate(free_names):
            se = result.parameters[name].stderr or 0.0
            a, b = float(best.x[j]), float(other.x[j])
            if abs(a - b) > max(3 * se, 0.01 * max(abs(a), abs(b))):
                apart = (
                    f"{abs(a - b) / se:.3g} standard errors apart"
                    if np.isfinite(se) and se > 0
                    else "its standard error undefined"
                )
                return Note(
                    "fit.starts_disagree",
                    f"starts ended at different optima about as good as each other ({name} "
                    f"{a:.4g} and {b:.4g}, {apart}): the trials do not decide between them; "
                    "the fit cannot be trusted "
                    "until more trials (other thrust levels, longer motions) or --fix settle it",
                    subject=name,
                    severity="error",
                )
    return None


def evaluate_trials(
    model: Model, trials: Sequence[TrialData], values: Mapping[str, float]
) -> MatchResult:
    """Simulate ``model`` at known ``values`` on ``trials``, without fitting (validation).

    What MATLAB's ``compare(valdata, sys)`` does: a model identified on some logs, run on
    others; its errors (fit %, RMSE) and residual say whether it still holds.

    Parameters
    ----------
    model : Model
        The identified model.
    trials : sequence of TrialData
        New trials.
    values : mapping of str to float
        Every parameter of ``model`` (those missing take their defaults).

    Returns
    -------
    MatchResult
        Every parameter held (``vary`` False, no standard error), one evaluation.

    Raises
    ------
    IdentificationError
        No trial, or the model gives a non-finite acceleration at ``values``.
    """
    if not trials:
        raise IdentificationError("no trial to simulate; check the log with 'balancer-id inspect'")
    full = model.resolve(dict(values))
    held = {n: full[n] for n in model.param_names}
    return match_trials(model, trials, start=held, fixed=held)


def _at_bound(value: float, lo: float, hi: float) -> str | None:
    """``"min"``/``"max"`` when ``value`` sits on that bound (relative to its own scale)."""
    span = hi - lo if np.isfinite(hi - lo) else abs(lo) + 1.0
    for bound, side in ((lo, "min"), (hi, "max")):
        if abs(value - bound) <= max(1e-3 * max(abs(bound), abs(value)), 1e-9 * span):
            return side
    return None


#: A parameter on its physical limit (0) whose unconstrained estimate lies more than this
#: many standard errors past it is held there against the data, not "none of it".
PULL_PAST_LIMIT = 3.0


def _pull_past(problem: _Problem, out: _Outcome, j: int, tau: float) -> float:
    """How many standard errors past its bound the ``j``-th free parameter's
    unconstrained Gauss-Newton estimate lies (its step over its standard error, signed
    away from the bound: positive means the data would take it further)."""
    try:
        problem.fun(out.x)
        jac, fun = problem._jac, problem._fun
        with np.errstate(all="ignore"):
            hess = jac.T @ jac
            step = -np.linalg.solve(hess, jac.T @ fun)
            n, k = out.residual.size, len(problem.free)
            var = np.linalg.inv(hess)[j, j] * out.chisqr / max(n - k, 1) * max(tau, 1.0)
    except (np.linalg.LinAlgError, ValueError):
        return 0.0
    if not (np.isfinite(var) and var > 0 and np.isfinite(step[j])):
        return 0.0
    side = -1.0 if out.x[j] - problem.lo[j] <= problem.hi[j] - out.x[j] else 1.0
    return float(side * step[j] / np.sqrt(var))


def _bound_note(
    model: Model, name: str, value: float, side: str, problem: _Problem, pull: float = 0.0
) -> Note:
    """What a parameter at a bound means: below resolution, absent, chosen, or untrusted.

    ``pull`` is :func:`_pull_past`: a parameter on its physical limit that the data would
    take more than :data:`PULL_PAST_LIMIT` standard errors further is held there against
    them (a wrong basin, or a force the model lacks), not absent.
    """
    spec = model.param(name)
    where = f"{name} = {value:.4g} {spec.unit}"
    if name in problem.user_bounds:
        return Note(
            "fit.at_bound",
            f"{where} is at the {side}imum you set with --bounds; the data would take it "
            "further: widen the bound or check that value",
            subject=name,
        )
    if side == "min" and name in model.drive_lag_names and problem.lag_floor > 0:
        return _unresolved_lag_note(name, value, problem.lag_floor)
    if side == "min" and spec.min == 0.0 and pull > PULL_PAST_LIMIT:
        return Note(
            "fit.held_at_limit",
            f"{name} = 0 {spec.unit} is held at its physical limit against the data (they "
            f"would take it {pull:.0f} standard errors below 0): the model cannot follow "
            "these trials at this optimum (another basin, or a force the model lacks); "
            "this fit cannot be trusted: try --starts 8, or 'balancer-id diagnose'",
            subject=name,
            severity="error",
        )
    if side == "min" and spec.min == 0.0:
        return Note(
            "fit.at_bound",
            f"{name} = 0 {spec.unit}: at its physical limit, the data show none of it "
            f"({spec.description})",
            subject=name,
            severity="info",
        )
    return Note(
        "fit.at_bound",
        f"{where} ended at its {side}imum bound, a limit the data did not choose: this fit "
        f"cannot be trusted (the model does not describe these trials, or they do not "
        f"determine {name}); check the trials with 'balancer-id inspect --plot', or hold "
        f"known values with --fix",
        subject=name,
        severity="error",
    )


def _unresolved_lag_note(name: str, value: float, floor: float) -> Note:
    """A drive lag shorter than one sample interval: an upper bound, not a measurement."""
    interval = 2 * floor
    return Note(
        "fit.below_resolution",
        f"{name} = {value * 1e3:.2g} ms is below what the {1 / interval:.0f} Hz samples "
        f"resolve (one sample interval, {interval * 1e3:.2g} ms): read it as {name} < "
        f"{interval * 1e3:.2g} ms (no drive lag seen), not as a measured value",
        subject=name,
        severity="info",
    )


def _covariance(out: _Outcome, tau: float = 1.0) -> np.ndarray | None:
    """Parameter covariance ``inv(J^T J) * chisqr / (n - k) * tau``.

    ``inv(J^T J) * chisqr / (n - k)`` (as lmfit computes it) holds for independent
    samples. A residual correlated over ``tau`` samples (its integrated autocorrelation
    time: a sensor's low-pass, a phone's filtering, or a force the model lacks) carries
    about ``1 / tau`` of the information per sample for parameters whose sensitivities
    vary slowly against it (a step response's, over T_a): the covariance is the
    long-run-variance sandwich, which for such sensitivities is ``tau`` times the white
    one (never less).
    """
    n, k = out.residual.size, out.jtj.shape[0]
    if k == 0 or n <= k:
        return None
    try:
        cov = np.linalg.inv(out.jtj)
    except np.linalg.LinAlgError:
        return None
    cov *= out.chisqr / (n - k) * max(tau, 1.0)
    return cov


#: A residual correlation time (samples) above which the widening is said in a note.
TAU_NOTE = 1.5


def _correlated_note(tau: float) -> Note:
    """Standard errors widened for a correlated residual."""
    return Note(
        "fit.correlated_residual",
        f"the residual is correlated over {tau:.1f} samples (a sensor's filter, or a force "
        f"the model lacks): standard errors are widened {np.sqrt(tau):.1f}x, as "
        "independent samples would overstate what the log tells",
        severity="info",
    )


def _estimates(
    model: Model, problem: _Problem, values: np.ndarray, free_names: list[str],
    cov: np.ndarray | None,
) -> tuple[dict[str, ParameterEstimate], dict[str, dict[str, float]]]:
    """Every parameter's estimate (held ones without an error) and the free ones'
    correlations."""
    sd = np.sqrt(np.abs(np.diag(cov))) if cov is not None else None
    n_free = len(free_names)
    estimates: dict[str, ParameterEstimate] = {}
    correlations: dict[str, dict[str, float]] = {}
    for i, spec in enumerate(model.params):
        vary = i in problem.free
        value = float(values[i])
        at_bound = None
        if vary:
            j = problem.free.index(i)
            at_bound = _at_bound(value, float(problem.lo[j]), float(problem.hi[j]))
        stderr = None
        if vary and sd is not None and cov is not None:
            j = free_names.index(spec.name)
            stderr = float(sd[j])
            if n_free > 1:
                with np.errstate(divide="ignore", invalid="ignore"):
                    correlations[spec.name] = {
                        other: float(cov[j, m] / (sd[j] * sd[m]))
                        for m, other in enumerate(free_names)
                        if m != j
                    }
        estimates[spec.name] = ParameterEstimate(
            spec.name, value, stderr, spec.unit, vary, at_bound
        )
    return estimates, correlations


def _bound_notes(
    model: Model, estimates: dict[str, ParameterEstimate], problem: _Problem, out: _Outcome,
    tau: float,
) -> list[Note | str]:
    """A note for each estimate on a bound (with the pull past it), and for each drive lag
    below two sample intervals."""
    notes: list[Note | str] = []
    for i, spec in enumerate(model.params):
        e = estimates[spec.name]
        if e.at_bound:
            pull = _pull_past(problem, out, problem.free.index(i), tau)
            notes.append(_bound_note(model, spec.name, e.value, e.at_bound, problem, pull))
        elif e.vary and spec.name in model.drive_lag_names and e.value < 2 * problem.lag_floor:
            notes.append(_unresolved_lag_note(spec.name, e.value, problem.lag_floor))
    return notes


def _poorly_note(
    model: Model, estimates: dict[str, ParameterEstimate], lag_floor: float
) -> Note | None:
    """The free parameters the data cannot determine (standard error beyond the value)."""
    poorly = [
        e.name
        for e in estimates.values()
        if e.vary
        and e.at_bound is None
        and (e.stderr is None or not np.isfinite(e.stderr) or e.stderr > abs(e.value))
        and not (e.name in model.drive_lag_names and e.value < 2 * lag_floor)
    ]  # a lag below one sample interval is a bound (fit.below_resolution), not a value
    if not poorly:
        return None
    return Note(
        "fit.not_identifiable",
        f"the data cannot determine {', '.join(poorly)} (standard error larger than "
        "the value or undefined); fix them with --fix NAME=VALUE or add trials that "
        "excite them",
        subject=poorly[0] if len(poorly) == 1 else None,
        severity="error",
    )


def _worse_than_mean_note(metrics: Mapping[str, float], n_free: int) -> Note | None:
    """An error note where the model follows the acceleration worse than its mean."""
    fit_percent = float(metrics.get("nrmse_fit_percent", np.nan))
    if not (n_free and np.isfinite(fit_percent) and fit_percent < 0):
        return None
    return Note(
        "fit.worse_than_mean",
        f"fit {fit_percent:.1f} %: the model follows the acceleration worse than its "
        "mean does, so its values describe nothing measured; check the trials with "
        "'balancer-id inspect --plot' and the model with 'balancer-id diagnose'",
        severity="error",
    )


def _correlation_notes(correlations: Mapping[str, Mapping[str, float]]) -> list[Note | str]:
    """A note for each pair of parameters almost fully correlated."""
    strong = sorted(
        {
            tuple(sorted((a, b)))
            for a, row in correlations.items()
            for b, c in row.items()
            if abs(c) > 0.98
        }
    )
    return [
        Note(
            "fit.not_identifiable",
            f"{a} and {b} are almost fully correlated ({correlations[a][b]:+.3f})",
            subject=a,
            severity="info",
        )
        for a, b in strong
    ]


def _collect(
    model: Model, out: _Outcome, problem: _Problem, data: FitData, notes: list[Note | str]
) -> MatchResult:
    y_model = data.y + out.residual
    free_names = [model.param_names[i] for i in problem.free]
    n_free = len(free_names)
    metrics = error_metrics(data.y, y_model, n_free)
    tau = correlation_time([out.residual[sl] for sl in data.slices()], removed=0)
    metrics["residual_tau"] = tau
    if tau > TAU_NOTE and n_free:
        notes.append(_correlated_note(tau))
    cov = _covariance(out, tau)
    estimates, correlations = _estimates(model, problem, problem.full(out.x), free_names, cov)
    notes.extend(_bound_notes(model, estimates, problem, out, tau))
    for note in (
        _poorly_note(model, estimates, problem.lag_floor),
        _worse_than_mean_note(metrics, n_free),
    ):
        if note is not None:
            notes.append(note)
    notes.extend(_correlation_notes(correlations))
    trial_rmse = [float(np.sqrt(np.mean((data.y[s] - y_model[s]) ** 2))) for s in data.slices()]
    return MatchResult(
        model=model,
        parameters=estimates,
        correlations=correlations,
        metrics=metrics,
        trial_rmse=trial_rmse,
        y=data.y,
        y_model=y_model,
        data=data,
        success=bool(out.success),
        message=str(out.message),
        nfev=int(out.nfev),
        warnings=notes,
    )
