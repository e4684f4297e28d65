"""Confidence intervals that respect the parameters' bounds: the profile likelihood.

The Wald interval ``value ± 1.96 stderr`` comes from the curvature of the cost at the
optimum. Where a parameter is poorly determined it can cross a physical bound (a mass
"-9.6 .. 21.6 kg"). The profile interval asks the data instead: hold the parameter at a
trial value, refit all the others, and keep the values whose cost stays within the
chi-square threshold of the optimum,

    S(theta) - S_min <= sigma^2 * chi2_1(level),   sigma^2 = tau * S_min / (n - k)

(the likelihood-ratio interval of least squares with the noise variance estimated from
the fit; ``tau`` the residual's correlation time, ``metrics["residual_tau"]``, 1 for
independent samples; times the square of the widening the trials' scatter gave the
parameter's standard error, ``scatter_ratio``, so that a profile and the standard error it
replaces count the same evidence). An end that reaches a bound before the cost crosses the
threshold *is* the bound: the data cannot exclude it, and the interval says so.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from balancer_id.errors import BalancerIdError
from balancer_id.identify.matching import MatchResult, match_trials

#: Refits per end of an interval, at most (bracketing, then bisection).
MAX_REFITS_PER_END = 14


@dataclass(frozen=True)
class ProfileInterval:
    """A profile-likelihood confidence interval of one parameter.

    Attributes
    ----------
    name : str
        The parameter.
    low, high : float
        The interval's ends (in the parameter's unit).
    level : float
        Confidence level (0.95).
    low_at_bound, high_at_bound : bool
        Whether an end is the parameter's bound (the data do not exclude it).
    method : str
        ``"profile"``.
    """

    name: str
    low: float
    high: float
    level: float
    low_at_bound: bool
    high_at_bound: bool
    method: str = "profile"

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "low": self.low,
            "high": self.high,
            "level": self.level,
            "method": self.method,
            "low_at_bound": self.low_at_bound,
            "high_at_bound": self.high_at_bound,
        }


#: How far (as a factor of its value) the profile of a positive parameter is followed.
PROFILE_FACTOR = 100.0


def chi2_quantile_1dof(level: float) -> float:
    """The ``level`` quantile of the chi-square distribution with one degree of freedom.

    Parameters
    ----------
    level : float
        Probability in (0, 1).

    Returns
    -------
    float
        ``z^2`` where ``z`` is the two-sided normal quantile (3.8415 for 0.95).
    """
    from scipy.special import ndtri

    return float(ndtri(0.5 + level / 2.0) ** 2)


def wald_crosses_bound(match: MatchResult, name: str) -> bool:
    """Whether the Wald 95 % interval of ``name`` leaves the parameter's bounds (or is undefined).

    Parameters
    ----------
    match : MatchResult
        A fit.
    name : str
        A fitted parameter.

    Returns
    -------
    bool
    """
    est = match.parameters[name]
    if not est.vary:
        return False
    spec = match.model.param(name)
    ci = est.wald_ci95
    return ci is None or ci[0] < spec.min or ci[1] > spec.max


def profile_interval(match: MatchResult, name: str, level: float = 0.95) -> ProfileInterval:
    """The profile-likelihood interval of one fitted parameter.

    Parameters
    ----------
    match : MatchResult
        The fit (its model, trials, fixed parameters and optimum are reused).
    name : str
        A parameter the fit varied.
    level : float
        Confidence level.

    Returns
    -------
    ProfileInterval

    Raises
    ------
    ValueError
        When ``name`` was not fitted.
    """
    est = match.parameters.get(name)
    if est is None or not est.vary:
        raise ValueError(f"{name} was not fitted; only a fitted parameter has an interval")
    spec = match.model.param(name)
    n = match.y.size
    k = sum(1 for p in match.parameters.values() if p.vary)
    s_min = float(np.sum(match.residual**2))
    # a residual correlated over tau samples: each sample counts 1/tau (as the Wald
    # standard errors, matching._covariance)
    sigma2 = s_min / max(n - k, 1) * max(float(match.metrics.get("residual_tau", 1.0)), 1.0)
    # a standard error widened to the trials' scatter (a whole trial pulled at once) widens
    # the threshold alike: the profile then says what the standard error says
    sigma2 *= max(float(est.scatter_ratio), 1.0) ** 2
    threshold = s_min + sigma2 * chi2_quantile_1dof(level)
    held = {p.name: p.value for p in match.parameters.values() if not p.vary}
    # continuation: each refit starts from the optimum of the nearest value refitted so
    # far (the profile's path is smooth), not from the overall optimum, which lies ever
    # further away as the profile walks out: the same optima in a fraction of the steps
    optima: list[tuple[float, dict[str, float]]] = [(est.value, match.values())]

    def cost(value: float) -> float:
        start = min(optima, key=lambda seen: abs(seen[0] - value))[1]
        try:
            with np.errstate(all="ignore"):  # far out, the simulation may overflow
                refit = match_trials(
                    match.model,
                    match.data.trials,
                    start={**start, name: value},
                    fixed={**held, name: value},
                    max_nfev=300,
                )
        except BalancerIdError:
            return math.inf
        optima.append((value, refit.values()))
        return float(np.sum(refit.residual**2))

    span = spec.max - spec.min
    step0 = est.stderr if est.stderr and np.isfinite(est.stderr) and est.stderr > 0 else None
    step0 = min(step0 or 0.1 * max(abs(est.value), 1e-3 * span), 0.25 * span)

    # a positive parameter is profiled within a factor of PROFILE_FACTOR of its value (the
    # bounds of any scale, 0.01 kg to 1e5 kg, are no place to simulate a balancer)
    lo_end, hi_end = spec.min, spec.max
    if spec.min >= 0 and est.value > 0:
        if spec.min > 0:  # 0 is a physical null worth reaching (no viscosity, no friction)
            lo_end = max(spec.min, est.value / PROFILE_FACTOR)
        hi_end = min(spec.max, max(est.value, step0) * PROFILE_FACTOR)

    def end(side: int) -> tuple[float, bool]:
        bound = lo_end if side < 0 else hi_end
        inside, step = est.value, step0
        c_in = s_min
        for _ in range(MAX_REFITS_PER_END):
            trial = est.value + side * step
            if (trial - bound) * side >= 0:  # at or past the bound
                c_bound = cost(bound)
                if c_bound <= threshold:
                    return bound, True
                outside, c_out = bound, c_bound
                break
            c_trial = cost(trial)
            if c_trial > threshold:
                outside, c_out = trial, c_trial
                break
            inside, c_in, step = trial, c_trial, 2.0 * step
        else:
            return inside, False
        return _crossing(cost, threshold, (inside, c_in), (outside, c_out), est.value), False

    low, low_b = end(-1)
    high, high_b = end(+1)
    return ProfileInterval(name, float(low), float(high), level, low_b, high_b)


def _crossing(
    cost: Callable[[float], float],
    threshold: float,
    inside: tuple[float, float],
    outside: tuple[float, float],
    value: float,
) -> float:
    """Where the profile's cost crosses ``threshold`` between two bracketing points.

    Brent's method (:func:`scipy.optimize.brentq`: the cost near an end is smooth and
    nearly quadratic, so its interpolation lands close after a step or two, and it falls
    back on bisection where the cost curves), after bisections while the outside end's
    cost is not finite. Stops when the bracket is narrower than 0.5 % of the end's distance
    from the fitted ``value`` (or 0.5 per mille of the value), or after
    ``MAX_REFITS_PER_END // 2`` refits, as the bisection it replaces.
    """
    (x_in, c_in), (x_out, c_out) = inside, outside
    tolerance = max(5e-3 * abs(x_out - value), 5e-4 * abs(value), 1e-12)
    budget = MAX_REFITS_PER_END // 2
    while not np.isfinite(c_out) and budget > 0 and abs(x_out - x_in) > tolerance:
        mid = 0.5 * (x_in + x_out)
        c_mid = cost(mid)
        budget -= 1
        if c_mid <= threshold:
            x_in, c_in = mid, c_mid
        else:
            x_out, c_out = mid, c_mid
    if budget == 0 or not np.isfinite(c_out) or abs(x_out - x_in) <= tolerance:
        return 0.5 * (x_in + x_out)
    known = {x_in: c_in - threshold, x_out: c_out - threshold}

    def excess(x: float) -> float:
        if x not in known:  # brentq asks again for the ends it was given
            known[x] = cost(x) - threshold
        return min(known[x], 1e300)

    found, _ = brentq(excess, x_in, x_out, xtol=tolerance, rtol=1e-12, maxiter=budget,
                      full_output=True, disp=False)  # fmt: skip
    return float(found)


#: A parameter correlated with another beyond this trades with it so closely that the
#: cost is no quadratic bowl along their valley: its Wald interval does not hold (issue 31).
CLOSE_TRADE = 0.98


def trades_closely(match: MatchResult, name: str) -> bool:
    """Whether a fitted parameter's correlation with another fitted one exceeds
    :data:`CLOSE_TRADE` (its interval is then its profile's).

    Parameters
    ----------
    match : MatchResult
        The fit.
    name : str
        The parameter.

    Returns
    -------
    bool
    """
    if not match.parameters[name].vary:
        return False
    row = match.correlations.get(name) or {}
    return any(
        other != name
        and other in match.parameters
        and match.parameters[other].vary
        and np.isfinite(c)
        and abs(c) > CLOSE_TRADE
        for other, c in row.items()
    )


def attach_profile_intervals(match: MatchResult, level: float = 0.95) -> list[str]:
    """Replace each Wald interval that crosses a bound, or of a parameter that trades with
    another beyond :data:`CLOSE_TRADE`, by the profile interval.

    Parameters
    ----------
    match : MatchResult
        A fit; its :class:`~balancer_id.identify.matching.ParameterEstimate` s get their
        ``profile`` interval (``ci95`` then returns it, ``ci95_method`` says
        ``"profile"``).
    level : float
        Confidence level.

    Returns
    -------
    list of str
        The parameters given a profile interval.
    """
    done = []
    for name, est in match.parameters.items():
        if est.not_reached:  # a bound has its own
            continue
        if not (wald_crosses_bound(match, name) or trades_closely(match, name)):
            continue
        iv = profile_interval(match, name, level)
        est.profile = (iv.low, iv.high)
        wald = est.wald_ci95
        if wald is not None and not wald_crosses_bound(match, name):
            # a close trade's valley: the profile's threshold knows the residual's
            # correlation time, not the trials' scatter the standard error was widened
            # to, so the wider of the two ends is kept on each side
            est.profile = (min(iv.low, wald[0]), max(iv.high, wald[1]))
        done.append(name)
    return done
