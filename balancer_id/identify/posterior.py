"""Posterior sampling of a fit's parameters (issue 34.2): the shape the Wald interval hides.

The likelihood is the fit's own least-squares one with the noise variance it estimated,
each sample counting ``1 / tau`` for a residual correlated over ``tau`` samples (as the
standard errors do, ``matching._covariance``):

    log L(theta) = -S(theta) / (2 sigma^2 tau),   sigma^2 = S_min / (n - k)

times a prior: a reference prior over the parameters the user gives no prior for, inside
each parameter's bounds (a positive one's within a factor 100 of its fitted value,
:func:`support`), and, where the user gives one, a normal prior ``NAME=normal:MU,SD``.
A flat prior over those bounds put most of its volume where the data cannot tell the
parameters apart (on a short log, ``D0`` large with ``A`` large: no viscosity at any
level reached), and the posterior sat there, its intervals missing the truth; Jeffreys'
prior ``sqrt(det S^T S)`` (``S`` the simulated response's sensitivities) vanishes there,
but it also grows with the information's size, and leaned (against ``A`` by
``exp(-A sum |h|)``, towards light masses) so that the short logs' intervals missed on
that side. The reference prior keeps Jeffreys' shape part (the information's correlation
matrix: nothing where two parameters move the response alike) and is flat in the
sampler's coordinates (a positive parameter's logarithm, :func:`_logged`) while the data
pin each parameter within its support, falling as Jeffreys' does only beyond
(:func:`_log_reference`). emcee's ensemble sampler draws from it, started
around the optimum, moved by differential evolution (a positive parameter as its logarithm);
the chain runs until it is 50
autocorrelation times long or 5000 steps (counted in steps, so a seed gives the same
answer on any machine; a wall clock only as a named safety net), the first two autocorrelation times
are dropped and the rest thinned by half of one. Credible intervals are the highest-density
ones (the shortest holding 95 % of the samples; the equal-tailed ones missed the truth on
the sharp side of a skewed marginal), or, where the posterior piles against a bound, from
the bound to the 95 % quantile.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from balancer_id.errors import UsageError
from balancer_id.identify.band import covariance_of
from balancer_id.identify.matching import MatchResult
from balancer_id.identify.posterior_modes import (
    bridge_weights,
    posterior_modes,
    region_of,
    valleys,
)
from balancer_id.notes import Note

__all__ = ["Posterior", "Prior", "highest_density", "parse_prior", "sample_posterior"]

#: A chain this many autocorrelation times long gives stable quantiles (emcee's advice).
CHAIN_TAUS = 50
#: The wall-clock safety net of :func:`sample_posterior` (s): chains are measured in
#: steps, so a seed gives the same answer on any machine; this only stops a sampler that
#: would run for hours (a shift-long session), and the result then says so.
SAFETY_SECONDS = 1800.0
#: A credible end this far (a share of the Wald width) from the Wald end disagrees.
DISAGREE_SHARE = 0.25
#: The posterior piles against a bound (its credible interval is one-sided) when its
#: ``PILE_QUANTILE`` quantile lies within ``PILE_SHARE`` of the equal-tailed interval's
#: width from the bound: a density there of at least a quarter of the interval's mean.
#: (A posterior that only tails off towards the bound, as one spanning two valleys of
#: m_a from 0.6 to 15 kg above a support from 0.013 kg, keeps both tails.)
PILE_QUANTILE = 0.5
PILE_SHARE = 0.02
#: A valley with less than this share of the samples does not judge the convergence.
WEIGHTY = 0.01
#: Another valley of the posterior with at least this share of the samples is named.
MODE_NOTE_WEIGHT = 0.05
#: An optimum whose log posterior density is this far below the best optimum's is not
#: sampled (a share below e^-30 unless its valley were e^30 times wider).
MODE_DROP = 30.0
#: Acceptance fractions outside this range say the sampler is not mixing well. The floor
#: was 0.15 (the stretch move's rule of thumb); differential-evolution moves in a valley
#: cut by a bound (a short log's mirror, the lag at its 10 s bound) accept 0.13-0.14 while
#: their chains are 50 autocorrelation times long with a split R-hat of 1.0x: the
#: acceptance says only whether walkers are stuck, the autocorrelation time and R-hat
#: whether the chain mixed.
ACCEPTANCE_RANGE = (0.10, 0.75)
#: The split R-hat (Gelman-Rubin, each walker's chain after burn-in cut in halves, BDA3
#: 11.4) above which the walkers have not forgotten where they started.
RHAT_MAX = 1.05


@dataclass(frozen=True)
class Prior:
    """A normal prior on one parameter (``NAME=normal:MU,SD``).

    Attributes
    ----------
    name : str
        The parameter.
    mu, sd : float
        Mean and standard deviation (the parameter's unit).
    """

    name: str
    mu: float
    sd: float
    kind: str = "normal"

    def log_density(self, value: float) -> float:
        """Log density up to a constant.

        Parameters
        ----------
        value : float
            The parameter's value.

        Returns
        -------
        float
        """
        return -0.5 * ((value - self.mu) / self.sd) ** 2

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {"name": self.name, "kind": self.kind, "mu": self.mu, "sd": self.sd}


_PRIOR = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*normal\s*:\s*([^,]+),([^,]+)$")


def parse_prior(text: str) -> Prior:
    """``NAME=normal:MU,SD`` as a :class:`Prior`.

    Parameters
    ----------
    text : str
        The option's value.

    Returns
    -------
    Prior

    Raises
    ------
    UsageError
        Any other form, a value that is not a finite number, or SD <= 0.
    """
    m = _PRIOR.match(text)
    if m is None:
        raise UsageError(f"--prior '{text}': expected NAME=normal:MU,SD, e.g. m_a=normal:15,1")
    try:
        mu, sd = float(m.group(2)), float(m.group(3))
    except ValueError:
        raise UsageError(f"--prior '{text}': MU and SD must be numbers") from None
    if not (math.isfinite(mu) and math.isfinite(sd) and sd > 0):
        raise UsageError(f"--prior '{text}': give a finite MU and a positive SD")
    return Prior(m.group(1), mu, sd)


@dataclass(frozen=True)
class Posterior:
    """Samples of the posterior of a fit's free parameters, and how well they mixed.

    Attributes
    ----------
    names : list of str
        The sampled parameters (the fit's free ones).
    samples : numpy.ndarray
        ``m x len(names)``: the chain after burn-in, thinned, walkers pooled.
    fitted : dict of str to float
        The least-squares optimum.
    wald : dict of str to (float, float) or None
        Each parameter's Wald 95 % interval (None where undefined).
    profile : dict of str to (float, float)
        Profile-likelihood intervals where the fit computed them.
    tau : dict of str to float
        Integrated autocorrelation time of each parameter's chain (steps).
    acceptance : float
        Mean acceptance fraction of the walkers.
    n_walkers, n_steps, burn, thin : int
        The ensemble's size, the steps taken, dropped and the thinning.
    priors : list of Prior
        The normal priors given (the rest: the reference prior within the bounds).
    seed : int
        The sampler's seed.
    notes : list of Note
        Convergence and disagreement with the Wald intervals.
    bounds : dict of str to (float, float)
        Each parameter's bounds (the prior's support).
    modes : list of dict
        The valleys sampled (the fit's optimum first, then its other optima that fit
        about alike): each one's ``values`` and ``weight`` (its share of the samples).
    stopped_by_time : bool
        A chain was cut short by the wall-clock safety net (:data:`SAFETY_SECONDS`): not
        converged, whatever its length says.
    rhat : dict of str to float
        Each parameter's split R-hat (the largest over the valleys that hold samples;
        :data:`RHAT_MAX`).
    added_sd : dict of str to float
        The spread added to each parameter's samples for what the fit's standard error
        holds and the likelihood does not (:func:`unmodelled_spread`).
    """

    names: list[str]
    samples: np.ndarray
    fitted: dict[str, float]
    wald: dict[str, tuple[float, float] | None]
    profile: dict[str, tuple[float, float]]
    tau: dict[str, float]
    acceptance: float
    n_walkers: int
    n_steps: int
    burn: int
    thin: int
    priors: list[Prior] = field(default_factory=list)
    seed: int = 0
    notes: list[Note] = field(default_factory=list)
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    modes: list[dict[str, object]] = field(default_factory=list)
    stopped_by_time: bool = False
    rhat: dict[str, float] = field(default_factory=dict)
    added_sd: dict[str, float] = field(default_factory=dict)

    @property
    def converged(self) -> bool:
        """Whether the chain is :data:`CHAIN_TAUS` autocorrelation times long, the
        acceptance fraction is in :data:`ACCEPTANCE_RANGE`, every split R-hat is at most
        :data:`RHAT_MAX` and no chain was stopped by the wall-clock safety net."""
        if self.stopped_by_time:
            return False
        longest = max(self.tau.values(), default=0.0)
        ok_len = np.isfinite(longest) and self.n_steps >= CHAIN_TAUS * longest
        worst = max(self.rhat.values(), default=1.0)
        ok_rhat = bool(np.isfinite(worst) and worst <= RHAT_MAX)
        return bool(
            ok_len and ok_rhat and ACCEPTANCE_RANGE[0] <= self.acceptance <= ACCEPTANCE_RANGE[1]
        )

    def credible(
        self, level: float = 0.95, kind: str = "hdi"
    ) -> dict[str, tuple[float, float]]:
        """Credible intervals: the highest-density ones, or one-sided where the posterior
        piles against a bound.

        The highest-density interval (``kind="hdi"``, the shortest holding ``level`` of
        the samples, in the parameter's own unit, as ArviZ reports) and not the
        equal-tailed one: on a marginal the data close sharply on one side and leave open
        on the other (a short log's D0 and A, up the ridge where the viscosity at the
        heavier levels vanishes), the equal-tailed interval cuts 2.5 % of the long side's
        mass off the sharp side and moves its end past the edge where the likelihood
        drops, and missed the truth there (DECISIONS.md). Where the posterior piles
        against a parameter's bound (its :data:`PILE_QUANTILE` % quantile within
        :data:`PILE_SHARE` of the equal-tailed interval's width from it: D0 near 0), the
        interval runs from the bound to the ``level`` quantile, as the profile interval
        ends at a bound the data do not exclude.

        Parameters
        ----------
        level : float
            Probability inside.
        kind : {"hdi", "equal"}
            Highest-density or equal-tailed (the 2.5 and 97.5 % quantiles) away from a
            bound.

        Returns
        -------
        dict of str to (float, float)
        """
        out = {}
        tail = 50 * (1 - level)
        for j, n in enumerate(self.names):
            x = self.samples[:, j]
            lo, hi = (float(v) for v in np.percentile(x, [tail, 100 - tail]))
            b_lo, b_hi = self.bounds.get(n, (-np.inf, np.inf))
            width = hi - lo
            edge_lo, edge_hi = np.percentile(x, [PILE_QUANTILE, 100 - PILE_QUANTILE])
            if edge_lo - b_lo < PILE_SHARE * width:
                lo, hi = b_lo, float(np.percentile(x, 100 * level))
            elif b_hi - edge_hi < PILE_SHARE * width:
                lo, hi = float(np.percentile(x, 100 * (1 - level))), b_hi
            elif kind == "hdi":
                lo, hi = highest_density(x, level)
            out[n] = (lo, hi)
        return out

    def median(self) -> dict[str, float]:
        """Posterior medians."""
        return {
            n: float(v) for n, v in zip(self.names, np.median(self.samples, axis=0), strict=True)
        }

    def diagnostics_text(self) -> str:
        """One line: the ensemble, the chain's length against its autocorrelation time,
        the acceptance, the split R-hat and whether that counts as converged."""
        longest = max(self.tau.values(), default=float("nan"))
        ratio = self.n_steps / longest if math.isfinite(longest) and longest > 0 else float("nan")
        rhat = max(self.rhat.values(), default=float("nan"))
        verdict = (
            "converged"
            if self.converged
            else "NOT converged" + (": stopped by time" if self.stopped_by_time else "")
        )
        return (
            f"emcee, {self.n_walkers} walkers x {self.n_steps} steps "
            f"({self.samples.shape[0]} samples kept after {self.burn} burn-in, thinned by "
            f"{self.thin}); autocorrelation time {longest:.0f} steps ({ratio:.0f} of them "
            f"run, {CHAIN_TAUS} wanted); acceptance {self.acceptance:.2f}"
            + (f"; split R-hat {rhat:.3f} (at most {RHAT_MAX} wanted)" if self.rhat else "")
            + f": {verdict}"
        )

    def lines(self) -> list[str]:
        """The ``[[Posterior]]`` block of ``summary()``: intervals of each kind side by side."""
        cred, med = self.credible(), self.median()
        out = ["[[Posterior]]", f"    {self.diagnostics_text()}"]
        if self.added_sd:
            spread = ", ".join(f"{n} {v:.3g}" for n, v in self.added_sd.items())
            out.append(
                f"    samples spread by the steps' places between samples and the trials' "
                f"scatter, which the likelihood lacks (sd {spread})"
            )
        if self.priors:
            given = ", ".join(f"{p.name} ~ N({p.mu:g}, {p.sd:g})" for p in self.priors)
            out.append(f"    priors: {given}; the others the reference prior within their bounds")
        width = max(len(n) for n in self.names)

        def span(iv: tuple[float, float] | None) -> str:
            return f"[{iv[0]:.4g}, {iv[1]:.4g}]" if iv else "-"

        for n in self.names:
            out.append(
                f"    {n:<{width}}  median {med[n]:.5g}  credible 95% {span(cred[n])}  "
                f"Wald {span(self.wald.get(n))}  profile {span(self.profile.get(n))}"
            )
        return out

    def to_dict(self) -> dict[str, object]:
        """The ``posterior`` object of ``fit --json`` (CONTRACT.md)."""
        cred = self.credible()
        med = self.median()
        return {
            "method": "emcee",
            "parameters": {
                n: {
                    "median": med[n],
                    "credible95": None if cred[n] is None else list(cred[n]),
                    "wald95": list(w) if (w := self.wald.get(n)) else None,
                    "profile95": list(self.profile[n]) if n in self.profile else None,
                    "tau_steps": self.tau.get(n),
                    "rhat": self.rhat.get(n),
                    "added_sd": self.added_sd.get(n, 0.0),
                }
                for n in self.names
            },
            "acceptance": self.acceptance,
            "n_walkers": self.n_walkers,
            "n_steps": self.n_steps,
            "burn": self.burn,
            "thin": self.thin,
            "n_samples": int(self.samples.shape[0]),
            "converged": self.converged,
            "stopped_by_time": self.stopped_by_time,
            "priors": [p.to_dict() for p in self.priors],
            "seed": self.seed,
            "modes": [dict(m) for m in self.modes],
        }


def highest_density(x: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    """The shortest interval holding ``level`` of the samples ``x``.

    Parameters
    ----------
    x : numpy.ndarray
        Samples of one parameter.
    level : float
        The share inside.

    Returns
    -------
    (float, float)
    """
    xs = np.sort(np.asarray(x, float))
    n = xs.size
    m = min(n, max(1, math.ceil(level * n)))
    spans = xs[m - 1 :] - xs[: n - m + 1]
    i = int(np.argmin(spans))
    return float(xs[i]), float(xs[i + m - 1])


def support(
    match: MatchResult, names: Sequence[str], modes: Sequence[np.ndarray] = ()
) -> tuple[np.ndarray, np.ndarray]:
    """The prior's support: the bounds, a positive parameter's within a factor
    :data:`~balancer_id.identify.intervals.PROFILE_FACTOR` of its fitted value (as the
    profile is followed; 0 stays reachable where it is the bound), or of any other
    optimum's value in ``modes``.

    The model's bounds hold any balancer (0.01 kg to 1e5 kg, D0 to 1e6 kg/s); flat over
    them, a ridge the data do not close (D0 and A both large) holds most of the prior's
    volume and the posterior follows it there, not the data.

    Parameters
    ----------
    match : MatchResult
        The fit.
    names : sequence of str
        Its free parameters.
    modes : sequence of numpy.ndarray
        Other optima (values of ``names``) the support must hold too.

    Returns
    -------
    (lo, hi) : numpy.ndarray
    """
    from balancer_id.identify.intervals import PROFILE_FACTOR

    lo, hi = [], []
    for j, n in enumerate(names):
        spec = match.model.param(n)
        est = match.parameters[n]
        a, b = spec.min, spec.max
        if a >= 0:
            values = [abs(est.value), *(abs(float(m[j])) for m in modes)]
            scale = max(max(values), est.stderr or 0.0, 1e-12)
            b = min(b, scale * PROFILE_FACTOR)
            if a > 0:
                a = max(a, min(values) / PROFILE_FACTOR)
        lo.append(a)
        hi.append(b)
    return np.array(lo, float), np.array(hi, float)


def unmodelled_spread(
    match: MatchResult,
    names: Sequence[str],
    lo: np.ndarray | None = None,
    hi: np.ndarray | None = None,
) -> dict[str, float]:
    """The spread of each parameter the fit's standard error holds and the likelihood does
    not: the steps' places between samples (``phase_se``) and the trials' scatter beyond
    the noise (``scatter_ratio``).

    The standard error is ``hypot(se * r, phase_se)`` (``se`` the likelihood's, ``r`` the
    scatter's widening, at least 1); the likelihood holds ``se`` only. On a 0.2 kg cart at
    200 Hz the steps' places are most of T_a's standard error (1.59 of 1.62 ms) and its
    trials scatter 2-5x the noise's: credible intervals from the likelihood alone were a
    fraction of the Wald ones and missed.

    Only where the standard error describes the parameter (its Wald interval inside the
    support ``lo``-``hi``): on a ridge the data leave open (a short log's D0, Wald's
    reaching below 0 and its error thousands) the posterior's own shape is the
    uncertainty, and spread by that error the samples left it (D0's median sank to 0).

    Parameters
    ----------
    match : MatchResult
        The fit.
    names : sequence of str
        Its sampled parameters.
    lo, hi : numpy.ndarray, optional
        The posterior's support (default: no limit).

    Returns
    -------
    dict of str to float
        ``sqrt(stderr^2 - se^2)`` per parameter (0 where nothing is added).
    """
    out = {}
    for j, n in enumerate(names):
        p = match.parameters[n]
        se_all = p.stderr
        wald = p.wald_ci95
        inside = wald is not None and (lo is None or wald[0] > lo[j]) and (
            hi is None or wald[1] < hi[j]
        )
        if se_all is None or not math.isfinite(se_all) or se_all <= 0 or not inside:
            out[n] = 0.0
            continue
        phase = float(p.phase_se or 0.0)
        se = math.sqrt(max(se_all**2 - phase**2, 0.0)) / max(float(p.scatter_ratio), 1.0)
        out[n] = math.sqrt(max(se_all**2 - se**2, 0.0))
    return out


def _spread(
    samples: np.ndarray, sd: np.ndarray, lo: np.ndarray, hi: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Each column of ``samples`` plus independent normal noise of ``sd`` (the spread the
    likelihood lacks: the posterior convolved with it), reflected into ``(lo, hi)``."""
    if not np.any(sd > 0):
        return samples
    out = samples + rng.normal(size=samples.shape) * sd
    out = np.where(out < lo, 2 * lo - out, out)
    out = np.where(out > hi, 2 * hi - out, out)
    return np.clip(out, lo, hi)


def _log_posterior_fn(
    match: MatchResult,
    names: list[str],
    priors: Sequence[Prior],
    modes: Sequence[np.ndarray] = (),
    logged: np.ndarray | None = None,
):
    """``log p(theta)`` of the free parameters ``names`` (a callable for emcee), the
    reference prior's density taken in the sampler's coordinates (``logged``: which
    parameters are sampled as their logarithm; :func:`_log_reference`)."""
    model = match.model
    base = np.asarray(model.vector(match.values()), float)
    idx = [list(model.param_names).index(n) for n in names]
    lo, hi = support(match, names, modes)
    if logged is None:
        logged = np.zeros(len(names), bool)
    n = match.y.size
    k = len(names)
    s_min = float(np.sum(match.residual**2))
    tau = max(float(match.metrics.get("residual_tau", 1.0)), 1.0)
    scale = 1.0 / (2.0 * s_min / max(n - k, 1) * tau)
    y = match.y
    packed = match.data.packed
    by_name = {p.name: p for p in priors}
    prior_at = [(j, by_name[nm]) for j, nm in enumerate(names) if nm in by_name]
    # the reference prior's parameters: those without a prior of the user's
    ref_cols = [idx[j] for j, nm in enumerate(names) if nm not in by_name]
    ref_at = [j for j, nm in enumerate(names) if nm not in by_name]
    # each reference parameter's support's width in the sampler's coordinate
    # (a logged one's from its bound, or, where that is 0, from a factor PROFILE_FACTOR
    # below its smallest optimum: flat in the logarithm down to 0 is a volume without end,
    # the corner with no viscosity where a short log's D0 sank)
    from balancer_id.identify.intervals import PROFILE_FACTOR

    def log_width(j: int) -> float:
        least = min(
            (v for v in (abs(match.parameters[names[j]].value), *(abs(m[j]) for m in modes))
             if v > 0),
            default=hi[j] / PROFILE_FACTOR**2,
        )
        return math.log(hi[j] / max(lo[j], least / PROFILE_FACTOR))

    width = np.array([log_width(j) if logged[j] else hi[j] - lo[j] for j in ref_at], float)
    ref_logged = logged[ref_at]
    sigma = math.sqrt(s_min / max(n - k, 1) * tau)

    runner = packed.sens_runner(model, ref_cols) if ref_cols else None
    n_ref = len(ref_cols)

    def log_p(thetas: np.ndarray) -> np.ndarray:
        """The log posterior of each row of ``thetas`` (``m x k``; -inf outside the
        support): one simulation per row, the reference prior for all rows at once."""
        thetas = np.atleast_2d(thetas)
        m = thetas.shape[0]
        out = np.full(m, -np.inf)
        inside = np.flatnonzero(np.all(thetas > lo, axis=1) & np.all(thetas < hi, axis=1))
        cost = np.full(m, np.inf)
        info = np.zeros((m, n_ref, n_ref))
        p = base.copy()
        with np.errstate(all="ignore"):
            for i in inside:
                p[idx] = thetas[i]
                if runner is not None:
                    sim, sens = runner(p)
                    info[i] = sens.T @ sens
                else:
                    sim = packed.run(model, p)
                r = sim[:, 0] - y
                cost[i] = float(r @ r)
            ref = (
                _log_reference_info(info, thetas[:, ref_at], ref_logged, width, sigma)
                if ref_cols
                else np.zeros(m)
            )
            for j, pr in prior_at:
                ref = ref - 0.5 * ((thetas[:, j] - pr.mu) / pr.sd) ** 2
            lp = -cost * scale + ref
        good = inside[np.isfinite(lp[inside])]
        out[good] = lp[good]
        return out

    return log_p, lo, hi


#: Smallest eigenvalue of the information's correlation matrix counted by the reference prior.
JEFFREYS_FLOOR = 1e-14


def _log_reference(
    sens: np.ndarray, theta: np.ndarray, logged: np.ndarray, width: np.ndarray, sigma: float
) -> float:
    """Log of the reference prior in the sampler's coordinates ``u`` (a parameter or its
    logarithm): ``0.5 log det R`` (``R`` the correlation matrix of the information: it
    vanishes where two parameters move the response alike, the ridge of a short log)
    plus, for each parameter ``j``, ``min(0, log(s_j W_j / sigma))``: flat while the
    data pin ``u_j`` to within its support's width ``W_j`` (``sigma / s_j``, ``s_j`` its
    sensitivity's norm, is its standard error with the others held), falling as
    Jeffreys' prior does where they stop telling it (no viscosity: ``A`` when ``D0`` is 0).

    Jeffreys' prior ``sqrt(det S^T S)`` is this with every ``s_j`` counted (the
    information's size as well as its shape): where the
    information grows (light masses, the effective viscosities ``D0 exp(-A h)`` at the
    levels recorded) it leans, against ``A`` by ``exp(-A sum |h|)`` and towards light
    masses, and the credible intervals of short logs missed on that side
    (DECISIONS.md)."""
    if not np.all(np.isfinite(sens)):
        return -math.inf
    with np.errstate(all="ignore"):
        info = sens.T @ sens
    return float(_log_reference_info(info[None], theta[None], logged, width, sigma)[0])


def _log_reference_info(
    info: np.ndarray, theta: np.ndarray, logged: np.ndarray, width: np.ndarray, sigma: float
) -> np.ndarray:
    """:func:`_log_reference` of many points from their information ``S^T S``
    (``m x k x k``) and values ``theta`` (``m x k``); -inf where the information is not
    finite or a parameter moves nothing."""
    m = info.shape[0]
    out = np.full(m, -np.inf)
    d = np.sqrt(np.abs(np.diagonal(info, axis1=1, axis2=2)))
    ok = np.all(np.isfinite(info), axis=(1, 2)) & np.all(d > 0, axis=1)
    if not np.any(ok):
        return out
    d_ok = d[ok]
    try:
        eig = np.linalg.eigvalsh(info[ok] / (d_ok[:, :, None] * d_ok[:, None, :]))
    except np.linalg.LinAlgError:
        return out
    shape = 0.5 * np.sum(np.log(np.maximum(eig, JEFFREYS_FLOOR)), axis=1)
    s_u = d_ok * np.where(logged, np.abs(theta[ok]), 1.0)
    with np.errstate(divide="ignore"):
        told = np.log(s_u * width / sigma)
    out[ok] = shape + np.sum(np.minimum(told, 0.0), axis=1)
    return out


def _start_ensemble(
    center: np.ndarray,
    cov: np.ndarray | None,
    lo: np.ndarray,
    hi: np.ndarray,
    n_walkers: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Walkers around an optimum: a tenth of the Wald spread (or 1 %; at most 5 % of a
    positive parameter's value there), reflected into the bounds."""
    k = center.size
    if cov is not None and np.all(np.isfinite(cov)) and np.all(np.diag(cov) > 0):
        sd = np.sqrt(np.diag(cov))
    else:
        sd = 0.01 * np.maximum(np.abs(center), 1e-6)
    span = np.where(np.isfinite(hi - lo), hi - lo, np.inf)
    sd = np.minimum(0.1 * sd, 0.01 * span)
    # another optimum than the fit's may sit at a smaller scale than the fit's errors
    sd = np.where((lo >= 0) & (center > 0), np.minimum(sd, 0.05 * center), sd)
    sd = np.where(sd > 0, sd, 0.01 * np.maximum(np.abs(center), 1e-6))
    pos = center + rng.normal(size=(n_walkers, k)) * sd
    # reflected at the bounds (an optimum on a bound gets walkers on its inner side)
    pos = np.where(pos <= lo, 2 * lo - pos, pos)
    pos = np.where(pos >= hi, 2 * hi - pos, pos)
    margin = 1e-9 * np.where(np.isfinite(span), span, np.maximum(np.abs(center), 1.0))
    return np.clip(pos, lo + margin, hi - margin)


#: The walkers start within this share of the valley's Laplace spread (a ball the full
#: width put walkers where the posterior is e^-2 of its peak, or past a bound).
START_SHARE = 0.3


def _laplace_shape(match: MatchResult, names: Sequence[str], logged: np.ndarray):
    """A callable: a point in the sampler's coordinates to the Laplace covariance there
    (``sigma^2 tau inv(S_u^T S_u)``, ``S_u`` the response's sensitivities to the
    sampler's coordinates: a logged parameter's column times its value), or None where
    that is not finite or not positive definite."""
    model = match.model
    base = np.asarray(model.vector(match.values()), float)
    idx = [list(model.param_names).index(n) for n in names]
    n, k = match.y.size, len(names)
    tau = max(float(match.metrics.get("residual_tau", 1.0)), 1.0)
    var = float(np.sum(match.residual**2)) / max(n - k, 1) * tau
    runner = match.data.packed.sens_runner(model, idx)

    def shape(u: np.ndarray) -> np.ndarray | None:
        theta = _from_log(np.atleast_2d(u), logged)[0]
        p = base.copy()
        p[idx] = theta
        with np.errstate(all="ignore"):
            _, sens = runner(p)
            sens_u = sens * np.where(logged, theta, 1.0)
            info = sens_u.T @ sens_u
        if not np.all(np.isfinite(info)):
            return None
        try:
            cov = var * np.linalg.inv(info)
            np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            return None
        return cov if np.all(np.isfinite(cov)) else None

    return shape


def _shaped_start(
    cov: np.ndarray | None, u_centre: np.ndarray, n_walkers: int, rng: np.random.Generator,
    log_pus,
) -> np.ndarray | None:
    """``n_walkers`` points drawn around ``u_centre`` with :data:`START_SHARE` of the
    covariance ``cov``, each inside the posterior's support (a draw outside it, of zero
    density, drawn again, at most ten times); None without a covariance or when the
    draws keep leaving the support."""
    if cov is None:
        return None
    chol = np.linalg.cholesky(cov)
    out = np.empty((0, u_centre.size))
    for _ in range(10):
        draws = u_centre + START_SHARE * rng.normal(size=(n_walkers, u_centre.size)) @ chol.T
        ok = np.isfinite(log_pus(draws))
        out = np.concatenate([out, draws[ok]])
        if len(out) >= n_walkers:
            return out[:n_walkers]
    return None


def sample_posterior(
    match: MatchResult,
    *,
    priors: Sequence[Prior] = (),
    n_walkers: int | None = None,
    max_steps: int = 5000,
    min_steps: int = 300,
    max_seconds: float | None = SAFETY_SECONDS,
    seed: int = 0,
) -> Posterior:
    """Sample the posterior of ``match``'s free parameters with emcee.

    Parameters
    ----------
    match : MatchResult
        The fit (its model, trials, optimum, noise variance and correlation time).
    priors : sequence of Prior
        Normal priors; the parameters without one have the reference prior inside their bounds.
    n_walkers : int, optional
        Ensemble size (default ``max(16, 4 k)``, even).
    max_steps : int
        Steps at most per valley (each ``n_walkers`` simulations): the chain stops at
        :data:`CHAIN_TAUS` autocorrelation times or there, so a seed gives the same
        samples on any machine and under any load.
    min_steps : int
        Steps at least, before the chain's length is judged.
    max_seconds : float or None
        A safety net only: no chain is extended (past ``min_steps``) once this much time
        is spent over all valleys (a shift-long session simulates for long). When it
        stops a chain, the posterior is not converged and says so ("stopped by time");
        None: no limit.
    seed : int
        The sampler's seed.

    Returns
    -------
    Posterior

    Raises
    ------
    UsageError
        A prior on a parameter the fit did not vary.
    """

    names = [n for n, p in match.parameters.items() if p.vary]
    for pr in priors:
        if pr.name not in names:
            raise UsageError(
                f"--prior {pr.name}: not a fitted parameter of '{match.model.spec}' "
                f"(fitted: {', '.join(names) or 'none'})"
            )
    if not names:
        raise UsageError("--posterior: the fit has no free parameter to sample")
    k = len(names)
    modes = posterior_modes(match, names)
    walkers = n_walkers or max(16, 4 * k)
    walkers += walkers % 2
    rng = np.random.default_rng(seed)
    lo, hi = support(match, names, modes)
    center = np.array([match.parameters[n].value for n in names], float)
    cov = covariance_of(match)
    margin = 1e-6 * np.where(np.isfinite(hi - lo), hi - lo, np.maximum(np.abs(center), 1.0))
    centres = np.clip(np.array([center, *modes], float), lo + margin, hi - margin)
    # a positive parameter is sampled as its logarithm (the reference prior is a density
    # in these coordinates; a user's normal prior one in the parameter, its Jacobian
    # added): the curved valley of D0 exp(-A h) is nearly straight in (log D0, A), and a
    # scale spanning decades is one line
    logged = _logged(match, names, lo, centres)
    log_p, lo, hi = _log_posterior_fn(match, names, priors, modes, logged)
    given = logged & np.array([n in {p.name for p in priors} for n in names], bool)

    def log_pus(us: np.ndarray) -> np.ndarray:
        """The log posterior in the sampler's coordinates, each row of ``us``."""
        us = np.atleast_2d(us)
        return log_p(_from_log(us, logged)) + np.sum(us[:, given], axis=1)

    def log_pu(u: np.ndarray) -> float:
        return float(log_pus(u)[0])


    u_centres = np.where(logged, np.log(np.maximum(centres, 1e-300)), centres)
    # an optimum whose posterior density is far below the best's holds no share (the
    # ridge's corners, where the prior vanishes): not sampled (its chain accepted nothing)
    at = log_pus(u_centres)
    keep = np.isfinite(at) & (at >= np.max(at, initial=-np.inf) - MODE_DROP)
    keep[0] = True  # the fit's own optimum is always shown
    centres, u_centres = centres[keep], u_centres[keep]
    # optima with no barrier between them are one valley, sampled by one ensemble (its
    # walkers started around each); a point belongs to the valley of its nearest optimum
    group = valleys(u_centres, log_pus) if len(centres) > 1 else np.zeros(1, int)
    n_valleys = int(group.max()) + 1
    nearest_optimum = region_of(u_centres)

    def nearest(us: np.ndarray) -> np.ndarray:
        return group[nearest_optimum(us)]

    shape_at = _laplace_shape(match, names, logged)
    deadline = None if max_seconds is None else time.monotonic() + max_seconds
    runs = []
    for j in range(n_valleys):
        # each valley on its own: the posterior restricted to the points nearest it
        def log_pk(us: np.ndarray, j: int = j) -> np.ndarray:
            if n_valleys == 1:
                return log_pus(us)
            out = np.full(len(us), -np.inf)
            mine = nearest(us) == j
            if np.any(mine):
                out[mine] = log_pus(us[mine])
            return out

        members = np.flatnonzero(group == j)
        counts = np.full(members.size, walkers // members.size)
        counts[: walkers % members.size] += 1
        start = np.concatenate(
            [
                _start_ensemble(centres[c], cov[1] if cov else None, lo, hi, int(n_c), rng)
                for c, n_c in zip(members, counts, strict=True)
            ]
        )
        start = np.where(logged, np.log(np.maximum(start, 1e-300)), start)
        # the walkers shaped as the valley is (its Laplace covariance in the sampler's
        # coordinates), where it can be had: a round ball spends the chain's first
        # autocorrelation times stretching into the valley
        shaped = [
            _shaped_start(shape_at(u_centres[c]), u_centres[c], int(n_c), rng, log_pus)
            for c, n_c in zip(members, counts, strict=True)
        ]
        if all(x is not None for x in shaped):
            start = np.concatenate(shaped)  # type: ignore[arg-type]
        runs.append(_run_chain(log_pk, start, rng, min_steps, max_steps, deadline))
    centres = centres[[int(np.flatnonzero(group == j)[0]) for j in range(n_valleys)]]
    weights = bridge_weights([r.chain for r in runs], log_pu, nearest, rng)
    # the valleys' samples in proportion to their weights, none drawn twice
    total = min(len(r.chain) / w for r, w in zip(runs, weights, strict=True) if w > 0)
    pooled = [
        r.chain[rng.choice(len(r.chain), size=int(w * total), replace=False)]
        for r, w in zip(runs, weights, strict=True)
        if int(w * total) > 0
    ]
    samples = _from_log(np.concatenate(pooled), logged)
    added = unmodelled_spread(match, names, lo, hi)
    samples = _spread(samples, np.array([added[n] for n in names]), lo, hi, rng)
    # the diagnostics of the valley whose chain is shortest against its autocorrelation,
    # of those that hold a share of the samples (a valley of no weight adds none)
    weighty = [r for r, w in zip(runs, weights, strict=True) if w >= WEIGHTY] or runs
    worst = min(
        weighty, key=lambda r: r.steps / _longest(r.tau) if np.any(np.isfinite(r.tau)) else 0
    )
    tau, steps, burn, thin = worst.tau, worst.steps, worst.burn, worst.thin
    timed_out = any(r.timed_out for r in weighty)
    post = Posterior(
        names=names,
        samples=np.asarray(samples, float),
        fitted={n: float(match.parameters[n].value) for n in names},
        wald={n: match.parameters[n].wald_ci95 for n in names},
        profile={
            n: match.parameters[n].profile  # type: ignore[misc]
            for n in names
            if match.parameters[n].profile is not None
        },
        tau={n: float(t) for n, t in zip(names, tau, strict=True)},
        # of the valleys that hold samples (a weightless one stuck on the ridge, where
        # the prior vanishes, accepted nothing and would call every chain unconverged)
        acceptance=float(min(r.acceptance for r in weighty)),
        n_walkers=walkers,
        n_steps=steps,
        burn=burn,
        thin=thin,
        priors=list(priors),
        seed=seed,
        bounds={n: (float(a), float(b)) for n, a, b in zip(names, lo, hi, strict=True)},
        modes=[
            {"values": dict(zip(names, map(float, c), strict=True)), "weight": float(w)}
            for c, w in zip(centres, weights, strict=True)
        ],
        stopped_by_time=timed_out,
        rhat={
            n: float(np.nanmax([r.rhat[j] for r in weighty if r.rhat is not None] or [np.nan]))
            for j, n in enumerate(names)
        },
        added_sd={n: v for n, v in added.items() if v > 0},
    )
    post.notes.extend(posterior_notes(post))
    return post


@dataclass(frozen=True)
class _Chain:
    """One ensemble's run: samples after burn-in, thinned (the sampler's coordinates)."""

    chain: np.ndarray
    tau: np.ndarray
    acceptance: float
    steps: int
    burn: int
    thin: int
    timed_out: bool = False
    rhat: np.ndarray | None = None


def _run_chain(
    log_pus, start: np.ndarray, rng, min_steps: int, max_steps: int, deadline: float | None
) -> _Chain:
    """An emcee ensemble from ``start`` until :data:`CHAIN_TAUS` autocorrelation times
    long or ``max_steps``; past ``min_steps`` it is not extended after ``deadline`` (a
    :func:`time.monotonic` time; the chain then says it ``timed_out``). ``log_pus``
    takes all the walkers that move at once (``m x k``)."""
    import emcee

    walkers, k = start.shape
    # differential-evolution moves: about 2.5x shorter autocorrelation than the stretch
    # move on these fits (15 steps against 40, paper balancer, 16 walkers)
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    sampler = emcee.EnsembleSampler(walkers, k, log_pus, moves=moves, vectorize=True)
    sampler.random_state = np.random.RandomState(int(rng.integers(2**31))).get_state()
    timed_out = False
    # a walker started where the prior vanishes has -inf, and inf - inf is no number: such
    # a proposal is rejected (as it should be), without numpy's warning
    with np.errstate(invalid="ignore"):
        state = sampler.run_mcmc(start, min_steps, progress=False, skip_initial_state_check=True)
        steps = min_steps
        tau = _autocorr(sampler)
        while steps < max_steps and steps < CHAIN_TAUS * _longest(tau):
            if deadline is not None and time.monotonic() > deadline:
                timed_out = True
                break
            more = int(min(max_steps - steps, max(200, CHAIN_TAUS * _longest(tau) - steps)))
            state = sampler.run_mcmc(state, more, progress=False)
            steps += more
            tau = _autocorr(sampler)
    longest = float(np.nanmax(tau)) if np.all(np.isfinite(tau)) else steps / 10
    burn = min(int(2 * longest), steps // 2)
    thin = max(1, int(0.5 * float(np.nanmin(tau)))) if np.all(np.isfinite(tau)) else 1
    return _Chain(
        sampler.get_chain(discard=burn, thin=thin, flat=True),
        np.asarray(tau, float),
        float(np.mean(sampler.acceptance_fraction)),
        steps,
        burn,
        thin,
        timed_out,
        split_rhat(sampler.get_chain(discard=burn)),
    )


def split_rhat(chain: np.ndarray) -> np.ndarray:
    """The split R-hat of each parameter (Gelman et al., BDA3 11.4): each walker's chain
    cut in halves, the variance between the halves' means against the variance within.

    Parameters
    ----------
    chain : numpy.ndarray
        ``steps x walkers x k`` after burn-in.

    Returns
    -------
    numpy.ndarray
        ``k`` values; near 1 once the walkers have forgotten where they started (nan for
        a chain too short or with no spread).
    """
    steps, _, k = chain.shape
    half = steps // 2
    if half < 2:
        return np.full(k, np.nan)
    seqs = np.concatenate([chain[:half], chain[half : 2 * half]], axis=1)  # half x 2W x k
    means = seqs.mean(axis=0)
    within = seqs.var(axis=0, ddof=1).mean(axis=0)
    between = half * means.var(axis=0, ddof=1)
    with np.errstate(all="ignore"):
        pooled = (half - 1) / half * within + between / half
        return np.sqrt(pooled / within)


#: A parameter that cannot be negative is sampled as its logarithm when its fitted value
#: is this many standard errors above 0 (or its lower bound is above 0). Nearer 0 the
#: logarithm stretches the flat stretch down to the bound into an endless tail the walkers
#: do not explore: near a bound (D0 = 0.2, 20 seeds) the credible coverage of D0 fell from
#: 95 % to 75 % with every such parameter logged.
LOG_AWAY = 3.0


#: ... or when its reported 95 % interval lies above 0 and spans more than this factor
#: (a short log's D0 and A: their uncertainty is a factor, not a difference).
SPANS_DECADE = 10.0


def _logged(
    match: MatchResult, names: Sequence[str], lo: np.ndarray, centres: np.ndarray | None = None
) -> np.ndarray:
    """Which parameters are sampled as their logarithm (see :data:`LOG_AWAY`; also one
    whose modes, ``centres``' rows, lie above 0 and span more than :data:`SPANS_DECADE`)."""
    out = []
    for j, (n, a) in enumerate(zip(names, lo, strict=True)):
        p = match.parameters[n]
        se = p.stderr if p.stderr is not None and math.isfinite(p.stderr) else math.inf
        ci = p.ci95
        decades = ci is not None and a >= 0 and ci[0] > 0 and ci[1] > SPANS_DECADE * ci[0]
        # or its interval reaches more than a factor 10 above its fitted value (a ridge
        # the profile follows to the support's top: D0 and A both large on a short log)
        decades = decades or bool(
            ci is not None and a >= 0 and p.value > 0 and ci[1] > SPANS_DECADE * p.value
        )
        if centres is not None and len(centres) > 1 and a >= 0:
            c = centres[:, j]
            decades = decades or bool(np.all(c > 0) and c.max() > SPANS_DECADE * c.min())
        out.append(bool(a > 0 or (a >= 0 and p.value > LOG_AWAY * se) or decades))
    return np.array(out, bool)


def _from_log(u: np.ndarray, logged: np.ndarray) -> np.ndarray:
    """Parameters from the sampler's coordinates (the logged columns exponentiated)."""
    with np.errstate(over="ignore"):
        return np.where(logged, np.exp(u), u)


def _longest(tau: np.ndarray) -> float:
    """The longest autocorrelation time estimated (nan when none is)."""
    return float(np.nanmax(tau)) if np.any(np.isfinite(tau)) else float("nan")


def _autocorr(sampler) -> np.ndarray:
    """Integrated autocorrelation time per parameter (steps), never raising."""
    try:
        with np.errstate(all="ignore"):  # a stuck walker's chain has no variance
            return np.asarray(sampler.get_autocorr_time(tol=0), float)
    except Exception:  # emcee raises on a too-short or stuck chain
        return np.full(sampler.ndim, np.nan)


def posterior_notes(post: Posterior) -> list[Note]:
    """What the user should know: convergence, and where the posterior and Wald disagree.

    Parameters
    ----------
    post : Posterior
        The samples.

    Returns
    -------
    list of Note
        ``fit.posterior_not_converged`` (warning) when the chain is short against its
        autocorrelation time or the acceptance is off; ``fit.posterior_disagrees``
        (info) for each parameter whose credible interval's ends differ from the Wald
        interval's by more than :data:`DISAGREE_SHARE` of its width, or whose Wald interval
        leaves the bounds.
    """
    notes = []
    longest = max(post.tau.values(), default=float("nan"))
    if post.stopped_by_time:
        notes.append(
            Note(
                "fit.posterior_not_converged",
                "the posterior is not converged: stopped by time (the wall clock's safety "
                f"limit) after {post.n_steps} steps"
                + (
                    f", {post.n_steps / longest:.0f} autocorrelation times of {longest:.0f} "
                    f"steps where {CHAIN_TAUS} are wanted"
                    if math.isfinite(longest) and longest > 0
                    else ""
                )
                + ": read its intervals as rough",
            )
        )
    elif not post.converged:
        notes.append(
            Note(
                "fit.posterior_not_converged",
                f"the posterior chain may not have converged ({post.n_steps} steps, "
                f"{post.n_steps / longest:.0f} autocorrelation times of {longest:.0f} steps "
                f"where {CHAIN_TAUS} are wanted; acceptance {post.acceptance:.2f}"
                + (
                    f"; split R-hat {max(post.rhat.values()):.3f}, at most {RHAT_MAX} wanted"
                    if post.rhat
                    else ""
                )
                + "): read its intervals as rough",
            )
            if math.isfinite(longest)
            else Note(
                "fit.posterior_not_converged",
                "the posterior chain's autocorrelation time could not be estimated: read its "
                "intervals as rough",
            )
        )
    held = [m for m in post.modes[1:] if float(m["weight"]) >= MODE_NOTE_WEIGHT]  # type: ignore[arg-type]
    if held:
        where = "; ".join(
            ", ".join(f"{n} {v:.4g}" for n, v in m["values"].items())  # type: ignore[attr-defined]
            + f" ({float(m['weight']):.0%})"  # type: ignore[arg-type]
            for m in held
        )
        notes.append(
            Note(
                "fit.posterior_modes",
                f"the posterior holds {len(held)} valley(s) besides the fit's optimum "
                f"({float(post.modes[0]['weight']):.0%}; other optima that fit about alike): "  # type: ignore[arg-type]
                f"{where}; the credible intervals span them: the trials do not decide "
                "between them",
                severity="info",
            )
        )
    cred = post.credible()
    for n in post.names:
        wald = post.wald.get(n)
        lo, hi = cred[n]
        if wald is None:
            notes.append(
                Note(
                    "fit.posterior_disagrees",
                    f"{n}: no Wald interval (standard error undefined); the posterior gives "
                    f"{lo:.4g} .. {hi:.4g}",
                    subject=n,
                    severity="info",
                )
            )
            continue
        width = wald[1] - wald[0]
        b_lo, b_hi = post.bounds.get(n, (-np.inf, np.inf))
        crosses = wald[0] < b_lo or wald[1] > b_hi  # Wald's holds impossible values
        if (
            crosses
            or abs(lo - wald[0]) > DISAGREE_SHARE * width
            or abs(hi - wald[1]) > DISAGREE_SHARE * width
        ):
            why = (
                "the priors given"
                if any(p.name == n for p in post.priors)
                else ("a bound or a curved (banana-shaped) valley of the cost")
            )
            how = (
                f"which reaches past the bound {b_lo if wald[0] < b_lo else b_hi:.4g}"
                if crosses
                else "by more than a quarter of its width at an end"
            )
            notes.append(
                Note(
                    "fit.posterior_disagrees",
                    f"{n}: the 95 % credible interval {lo:.4g} .. {hi:.4g} differs from the "
                    f"Wald interval {wald[0]:.4g} .. {wald[1]:.4g} ({how}): the uncertainty "
                    f"is not Gaussian here ({why}); trust the credible (or profile) interval "
                    "over the standard error",
                    subject=n,
                    severity="info",
                )
            )
    return notes
