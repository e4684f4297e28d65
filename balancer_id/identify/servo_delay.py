"""Is the robot's servo late? A servo delay as an explanation of a robot's log (issue 31).

A servo that acts ``tau_r`` late (controller cycle, bus, amplifier) feeds the load's
position back with a phase lag: the coupled mode rings longer, and a fit without the
delay takes it for a stiffer servo (a higher ``k_r``). Three explanations of the same
acceleration are fitted side by side, each with the fit's free parameters:

- ``no_delay``: the fit as it stands (a servo acting at once, perhaps stiffer);
- ``servo_delay``: the servo acts ``tau_r`` late (:mod:`~balancer_id.simulation.delayed_servo`);
- ``sensor_lowpass``: the servo acts at once but the accelerometer low-passes what it
  reports (time constant ``tau_s``): a lag of the sensor, not of the loop.

They are compared on BIC with the samples counted as independent ones (the residual's
lag-1 correlation shrinks the count). The delay is *named* when it beats the undelayed
fit by :data:`NAME_DELTA_BIC` and its 95 % profile interval excludes zero; when the
low-pass explains the data as well (within :data:`TIE_DELTA_BIC`) the verdict is
``ambiguous`` and the advice is checked on the delayed loop anyway (the worse case).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import brentq, least_squares

from balancer_id.model.spec import Model
from balancer_id.simulation.delayed_servo import (
    LANE_PARAMS,
    SUPPORTED_EFFECTS,
    simulate_delayed_servo,
)

#: BIC by which the delay must beat the undelayed fit to be named.
NAME_DELTA_BIC = 10.0
#: Two explanations closer than this in BIC are not told apart by the data.
TIE_DELTA_BIC = 6.0
#: Largest delay searched (s): beyond it the loop of any advised robot is unstable.
MAX_DELAY_S = 0.3
#: The delays (s) of the profile that starts the late servo's fit (the least-squares cost
#: is not convex in it, and its basin is a few ms wide where the force is precise: 15 ms
#: steps missed a 41 ms delay); the move's start moved back by each (the found start
#: soaks the delay up), and a few with the start as found.
LAG_GRID = (*(0.005 * k for k in range(21)), 0.125, 0.15)
LAG_GRID_UNSHIFTED = (0.0, 0.02, 0.05, 0.1)
#: The same for a sensor's lag (the move's start does not trade with it).
SENSOR_LAG_GRID = (0.005, 0.02, 0.05)
#: Most evaluations of one least-squares solve.
MAX_NFEV = 200
#: Relative standard deviation of a held balancer value (one identified from step trials
#: and held for the robot's fit): the examination lets it move within this, as a prior,
#: so the delay does not soak up a held value's error.
HELD_RELATIVE_SD = {"m_a": 0.01, "T_a": 0.02, "D0": 0.05, "A": 0.05}
#: chi-square(1) at 95 %: the profile interval's threshold.
CHI2_95 = 3.841458820694124


@dataclass
class Explanation:
    """One explanation of the robot's log, fitted.

    Attributes
    ----------
    name : str
        ``no_delay``, ``servo_delay`` or ``sensor_lowpass``.
    values : dict
        Its parameters (the fit's, refitted, plus ``tau_r`` or ``tau_s``).
    sse : float
        Sum of squared acceleration residuals.
    bic : float
        BIC with the effective sample count.
    text : str
        What it says, in words.
    """

    name: str
    values: dict[str, float]
    sse: float
    bic: float
    text: str
    rmse: float = 0.0
    force_rmse: float | None = None

    def to_dict(self, best_bic: float) -> dict[str, object]:
        """JSON-ready dict.

        Parameters
        ----------
        best_bic : float
            The best explanation's BIC (``delta_bic`` is against it).

        Returns
        -------
        dict
        """
        return {
            "name": self.name,
            "text": self.text,
            "values": dict(self.values),
            "rmse": self.rmse,
            "force_rmse": self.force_rmse,
            "bic": self.bic,
            "delta_bic": self.bic - best_bic,
        }


def _ms(seconds: float, unit: bool = True) -> str:
    """A delay in ms: to 0.1 ms below 10 ms, else whole."""
    ms = 1e3 * seconds
    text = f"{ms:.1f}" if ms < 9.95 else f"{ms:.0f}"
    return f"{text} ms" if unit else text


@dataclass
class ServoDelay:
    """The servo-delay examination of a robot fit.

    Attributes
    ----------
    examined : bool
        False when the model is outside :data:`SUPPORTED_EFFECTS` (``why`` says so).
    verdict : str
        ``servo_delay`` (named), ``ambiguous`` (a late servo or a sensor's lag),
        ``sensor_lowpass`` (the accelerometer lags), ``force_lowpass`` (the force sensor
        lags), ``none`` or ``not_examined``.
    tau_r : float or None
        The delay's estimate (s).
    interval : tuple of float or None
        Its 95 % profile interval (s).
    explanations : list of Explanation
        The fits, best first.
    """

    examined: bool
    verdict: str
    tau_r: float | None = None
    interval: tuple[float, float] | None = None
    explanations: list[Explanation] = field(default_factory=list)
    samples_per_independent: float = 1.0
    has_force: bool = False
    why: str = ""
    #: With ``ambiguous``: ``stiffer`` (a delay fits, not decisively, and is not ruled
    #: out: a late servo or a stiffer one) or ``sensor`` (a sensor's lag as good).
    twin: str = "sensor"

    @property
    def named(self) -> bool:
        """Whether the log's servo is called late."""
        return self.verdict == "servo_delay"

    @property
    def use_delay(self) -> bool:
        """Whether the advice must hold on the delayed loop (named or not ruled out)."""
        return self.verdict in ("servo_delay", "ambiguous")

    def explanation(self, name: str) -> Explanation | None:
        """The fitted explanation ``name``.

        Parameters
        ----------
        name : str
            ``no_delay``, ``servo_delay``, ``sensor_lowpass`` or ``force_lowpass``.

        Returns
        -------
        Explanation or None
            None if not fitted.
        """
        return next((e for e in self.explanations if e.name == name), None)

    @property
    def rival_values(self) -> dict[str, float] | None:
        """With ``ambiguous``: the loop of the explanation the delay is not told apart from
        (a stiffer servo, or the best sensor's lag: a servo acting at once); else None."""
        if self.verdict != "ambiguous":
            return None
        names = ["no_delay"] if self.twin == "stiffer" else list(_SENSOR)
        found = [e for e in self.explanations if e.name in names]
        if not found:
            return None
        best = min(found, key=lambda e: e.bic)
        return {k: v for k, v in best.values.items() if k not in ("tau_r", "tau_s", "tau_f")}

    @property
    def delayed_values(self) -> dict[str, float] | None:
        """The parameters of the delayed loop (None without a delay fit)."""
        e = self.explanation("servo_delay")
        return None if e is None else dict(e.values)

    def lines(self) -> list[str]:
        """The verdict with its evidence, then each other explanation (terminal, report)."""
        if not self.examined:
            return [f"servo delay: not examined ({self.why})"]
        by = {e.name: e for e in self.explanations}
        none, late = by["no_delay"], by["servo_delay"]
        lo, hi = self.interval or (0.0, 0.0)
        gain = none.bic - late.bic
        where = "acceleration and force" if self.has_force else "acceleration only"
        if self.verdict == "none":
            head = (
                f"servo delay: none found ({where}): at most {_ms(hi)} (95 %); a "
                f"delay improves BIC by {gain:.1f}, {NAME_DELTA_BIC:g} needed to name it"
            )
        elif self.verdict in _SENSOR:
            e = by[self.verdict]
            lag = e.values.get(_LAG[self.verdict], 0.0)
            head = (
                f"servo delay: not the servo: {_SENSOR[self.verdict]} by {_ms(lag)} "
                f"explains the log best (BIC {late.bic - e.bic:+.1f} against a late servo, "
                f"{none.bic - e.bic:+.1f} against neither; {where})"
            )
        else:
            what = (
                "the robot's servo acts late"
                if self.verdict == "servo_delay"
                else (
                    "a late servo, or a stiffer one acting at once (a delay fits but not "
                    f"decisively: BIC {gain:+.1f}, {NAME_DELTA_BIC:g} needed; the advice must "
                    "hold on both)"
                    if self.twin == "stiffer"
                    else "a late servo, or a sensor's lag (these data do not tell them apart; "
                    "the advice must hold on both)"
                )
            )
            head = (
                f"servo delay: {what}: tau_r = {_ms(self.tau_r or 0.0)} "
                f"({_ms(lo, False)} .. {_ms(hi)}, 95 %; {where}), BIC {gain:+.1f} "
                f"better than no delay; with it k_r = {late.values.get('k_r', 0.0):.4g} N/m, "
                f"c_r = {late.values.get('c_r', 0.0):.4g} N s/m"
            )
        out = [head]
        if self.verdict == "none":
            return out
        chosen = "servo_delay" if self.verdict == "ambiguous" else self.verdict
        ref = by[chosen]
        for e in self.explanations:
            if e.name == chosen:
                continue
            lag_name = _LAG[e.name]
            extra = f" {_ms(e.values.get(lag_name, 0.0))}," if lag_name else ""
            out.append(
                f"  or {e.text}:{extra} k_r {e.values.get('k_r', 0.0):.4g} N/m: BIC "
                f"{e.bic - ref.bic:+.1f}"
            )
        return out

    def text(self) -> str:
        """The lines of :meth:`lines`, one per line."""
        return "\n".join(self.lines())

    def to_dict(self) -> dict[str, object]:
        """The ``servo_delay`` record of ``fit --json`` (CONTRACT.md)."""
        best = min((e.bic for e in self.explanations), default=0.0)
        return {
            "examined": self.examined,
            "verdict": self.verdict,
            "named": self.named,
            "tau_r_s": self.tau_r,
            "ci95_s": list(self.interval) if self.interval is not None else None,
            "samples_per_independent": self.samples_per_independent,
            "explanations": [e.to_dict(best) for e in self.explanations],
            "lines": self.lines(),
            "why": self.why,
            "twin": self.twin if self.verdict == "ambiguous" else None,
        }


@dataclass(frozen=True)
class _Move:
    time: np.ndarray
    z_ref: np.ndarray
    v_ref: np.ndarray
    x0: tuple[float, float, float] | None
    accel: np.ndarray
    force: np.ndarray | None = None
    #: The move itself (``evaluate(t) -> (z_ref, v_ref)``) on the log's clock and the
    #: shift the fit gave it (s); None: the sampled reference, interpolated.
    reference: Any = None
    shift0: float = 0.0


def _moves(
    trials: Sequence[Any],
    forces: Sequence[np.ndarray | None] | None,
    references: Sequence[tuple[Any, float] | None] | None = None,
) -> list[_Move]:
    out = []
    for k, td in enumerate(trials):
        inp = td.input
        if inp.z_ref is None or inp.v_ref is None:
            continue
        force = None if forces is None or k >= len(forces) else forces[k]
        if force is not None:
            force = np.asarray(force, dtype=float)
            if force.shape != np.shape(inp.time) or np.isfinite(force).sum() < 10:
                force = None
        ref = None if references is None or k >= len(references) else references[k]
        out.append(
            _Move(
                inp.time, inp.z_ref, inp.v_ref, inp.x0, np.asarray(td.accel, float), force,
                *(ref if ref is not None else (None, 0.0)),
            )
        )  # fmt: skip
    return out


def _lowpass(y: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """First-order low-pass (time constant ``tau``) of ``y``, from its first value."""
    if tau <= 0:
        return y
    from scipy.signal import lfilter

    alpha = 1.0 - np.exp(-dt / tau)
    out, _ = lfilter([alpha], [1.0, alpha - 1.0], y, zi=[(1.0 - alpha) * y[0]])
    return out


#: Largest shift of the reference move (s) fitted beside the lag: the move's start was
#: refined by the fit, which soaks up part of a delay.
MAX_SHIFT_S = 0.25


def _shifted_move(move: Any, at: float) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """The reference move started ``at`` seconds later, as a function of time."""

    def reference(tq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return move.evaluate(tq - at)  # type: ignore[no-any-return]

    return reference


def _shifted(m: _Move, shift: float) -> tuple[np.ndarray, np.ndarray]:
    """The reference move ``shift`` seconds later (held at its ends)."""
    if shift == 0.0:
        return m.z_ref, m.v_ref
    t = m.time - shift
    return np.interp(t, m.time, m.z_ref), np.interp(t, m.time, m.v_ref)


class _Problem:
    """The residuals of the robot's moves for a parameter vector: the free names, the
    reference's shift (s), then the lag (when there is one). The acceleration's and the
    force's residuals are divided by their noise levels ``sigma``."""

    def __init__(
        self,
        moves: list[_Move],
        values: Mapping[str, float],
        free: Sequence[str],
        lag: str,
        sigma: tuple[float, float] = (1.0, 1.0),
        prior: Mapping[str, tuple[float, float]] | None = None,
    ) -> None:
        self.prior = dict(prior or {})  # name -> (value held, standard deviation)
        self.fixed: dict[str, float] = {}  # values held over x (a lag on a grid)
        self.moves = moves
        self.base = {n: float(values.get(n, 0.0)) for n in LANE_PARAMS}
        self.base["tau_r"] = float(values.get("tau_r", 0.0))
        self.free = list(free)
        self.lag = lag  # "tau_r", "tau_s", "tau_f" or ""
        self.sigma = sigma

    def values(self, x: np.ndarray) -> dict[str, float]:
        v = dict(self.base)
        for name, xi in zip(self.free, x, strict=False):
            v[name] = float(xi)
        v["shift"] = float(x[len(self.free)])
        if self.lag:
            v[self.lag] = float(x[-1])
        v.update(self.fixed)
        return v

    def channels(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The acceleration's residual (m/s^2) and the force's (N; empty without one)."""
        v = self.values(x)
        lane = np.array([v[n] for n in LANE_PARAMS])
        acc, frc = [], []
        for m in self.moves:
            if m.reference is not None:
                a, h, _ = simulate_delayed_servo(
                    m.time, m.z_ref, m.v_ref, lane, m.x0,
                    reference=_shifted_move(m.reference, m.shift0 + v["shift"]),
                )  # fmt: skip
            else:
                zr, vr = _shifted(m, v["shift"])
                a, h, _ = simulate_delayed_servo(m.time, zr, vr, lane, m.x0)
            y, f = a[0], h[0]
            dt = (m.time[-1] - m.time[0]) / (m.time.size - 1)
            if v.get("tau_s", 0.0) > 0:
                y = _lowpass(y, dt, v["tau_s"])
            acc.append(y - m.accel)
            if m.force is not None:
                if v.get("tau_f", 0.0) > 0:
                    f = _lowpass(f, dt, v["tau_f"])
                r = f - m.force
                frc.append(r[np.isfinite(r)])
        ra = np.concatenate(acc)
        rf = np.concatenate(frc) if frc else np.zeros(0)
        return np.where(np.isfinite(ra), ra, 1e3), np.where(np.isfinite(rf), rf, 1e4)

    def prior_terms(self, x: np.ndarray) -> np.ndarray:
        """``(value - held) / sd`` of each held value let free (its prior's residual)."""
        v = self.values(x)
        return np.array([(v[n] - x0) / sd for n, (x0, sd) in self.prior.items()])

    def residuals(self, x: np.ndarray) -> np.ndarray:
        ra, rf = self.channels(x)
        return np.concatenate([ra / self.sigma[0], rf / self.sigma[1], self.prior_terms(x)])


def _solve(
    problem: _Problem, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, rounds: int = 2
) -> np.ndarray:
    """Weighted least squares from ``x0``; after each round the noise levels are
    re-estimated from the residuals (``rounds`` rounds)."""
    scale = np.maximum(np.abs(x0), 1e-3)
    x = np.clip(x0, lo, hi)
    for _ in range(rounds):
        x = least_squares(
            problem.residuals, x, bounds=(lo, hi), x_scale=scale, method="trf",
            xtol=1e-6, ftol=1e-8, max_nfev=MAX_NFEV,
        ).x  # fmt: skip
        problem.sigma = _sigmas(*problem.channels(x))
    return x


def _sigmas(ra: np.ndarray, rf: np.ndarray) -> tuple[float, float]:
    def rms(r: np.ndarray) -> float:
        return float(np.sqrt(np.mean(r**2))) if r.size else 1.0

    return max(rms(ra), 1e-9), max(rms(rf), 1e-9)


def _independent_ratio(r: np.ndarray) -> float:
    """Samples per independent one from the residual's lag-1 correlation (at least 1)."""
    r = r - r.mean()
    den = float(np.dot(r, r))
    if r.size < 3 or den <= 0:
        return 1.0
    rho = float(np.clip(np.dot(r[1:], r[:-1]) / den, 0.0, 0.95))
    return float((1 + rho) / (1 - rho))


class _Scorer:
    """The concentrated log-likelihood (each channel its own noise level) and BIC, with
    each channel's samples counted as independent ones."""

    def __init__(self, ratios: tuple[float, float], sizes: tuple[int, int]) -> None:
        self.n = sizes
        self.n_eff = tuple(n / r for n, r in zip(sizes, ratios, strict=True))

    def deviance(self, ra: np.ndarray, rf: np.ndarray) -> float:
        out = 0.0
        for r, n, ne in zip((ra, rf), self.n, self.n_eff, strict=True):
            if n:
                out += ne * np.log(max(float(r @ r), 1e-300) / n)
        return float(out)

    def bic(self, ra: np.ndarray, rf: np.ndarray, k: int) -> float:
        return self.deviance(ra, rf) + k * float(np.log(sum(self.n_eff)))


_TEXT = {
    "no_delay": "the servo acts at once (a stiffer servo where the data ring longer)",
    "servo_delay": "the robot's servo acts tau_r late: its feedback lags the load",
    "sensor_lowpass": "the servo acts at once; the accelerometer low-passes (time "
    "constant tau_s)",
    "force_lowpass": "the servo acts at once; the force sensor low-passes or lags (time "
    "constant tau_f)",
}
_SENSOR = {
    "sensor_lowpass": "the accelerometer's low-pass",
    "force_lowpass": "the force sensor's lag",
}
_LAG = {"no_delay": "", "servo_delay": "tau_r", "sensor_lowpass": "tau_s", "force_lowpass": "tau_f"}


def _why_not_examined(model: Model) -> str | None:
    """Why the model's servo delay cannot be examined (None when it can)."""
    names = {e.name for e in model.effects}
    if "servo" not in names:
        return "no robot servo in the model"
    if not names <= SUPPORTED_EFFECTS:
        extra = ", ".join(sorted(names - SUPPORTED_EFFECTS))
        return f"the delayed loop is simulated for the servo with a viscosity only, not {extra}"
    return None


@dataclass
class _Setup:
    """What every explanation is fitted over.

    ``free`` is the fit's free servo parameters, then the held balancer values let move
    within their ``prior`` (name -> (value held, standard deviation)); ``lo``/``hi`` bound
    them and the move's shift (the last entry)."""

    moves: list[_Move]
    vals: dict[str, float]
    free: list[str]
    prior: dict[str, tuple[float, float]]
    lo: np.ndarray
    hi: np.ndarray

    @property
    def servo(self) -> list[str]:
        """The free parameters that are not held values let move."""
        return [n for n in self.free if n not in self.prior]

    @property
    def k_servo(self) -> list[int]:
        """Their places in ``free``."""
        return [k for k, n in enumerate(self.free) if n not in self.prior]


def _setup(
    model: Model,
    values: Mapping[str, float],
    free: Sequence[str],
    moves: list[_Move],
    bounds: Mapping[str, tuple[float, float]] | None,
    held_sd: Mapping[str, float] | None,
) -> _Setup:
    """The values (``tau_r`` 0), the free parameters with the held ones' prior, and bounds."""
    vals = {k: float(v) for k, v in values.items()}
    vals["tau_r"] = 0.0
    own = [n for n in free if n in LANE_PARAMS and n != "tau_r"]
    sds = HELD_RELATIVE_SD if held_sd is None else held_sd
    prior = {
        n: (vals[n], sds[n] * vals[n])
        for n in sds
        if n in model.param_names and n not in own and vals.get(n, 0.0) > 0 and sds[n] > 0
    }
    names = own + list(prior)
    lims = {p.name: (p.min, p.max) for p in model.params}
    lims.update(bounds or {})
    lo = np.array([lims[n][0] for n in names] + [-MAX_SHIFT_S])
    hi = np.array([lims[n][1] for n in names] + [MAX_SHIFT_S])
    return _Setup(moves, vals, names, prior, lo, hi)


def _lag_starts(name: str, shift_none: float) -> list[tuple[float, float]]:
    """The (lag, move's shift) pairs of the coarse profile that finds the lag's basin."""
    if name == "servo_delay":  # the delay's basin is narrow: a fine grid, the start moved back
        tries = [(t, shift_none - t) for t in LAG_GRID]
        return tries + [(t, shift_none) for t in LAG_GRID_UNSHIFTED]
    return [(t, shift_none) for t in SENSOR_LAG_GRID]


def _fit_lag(
    setup: _Setup, name: str, x_none: np.ndarray, sigma: tuple[float, float]
) -> tuple[np.ndarray, _Problem]:
    """Fit the explanation ``name`` (a lag): a coarse profile over the lag (the servo and
    the move's start fitted, held values at their holding) finds its basin; the full fit
    starts there, from the undelayed fit's servo and the held values where they were held
    (the undelayed fit may have pulled them to mimic the delay)."""
    free, k_servo = setup.free, setup.k_servo
    x_from = np.array(x_none, dtype=float)
    for k, n in enumerate(free):
        if n in setup.prior:
            x_from[k] = setup.prior[n][0]
    lo_g = np.append(setup.lo[k_servo], -MAX_SHIFT_S)
    hi_g = np.append(setup.hi[k_servo], MAX_SHIFT_S)
    best: tuple[np.ndarray, float] | None = None
    for tau0, shift0 in _lag_starts(name, float(x_none[len(free)])):
        grid = _Problem(setup.moves, setup.vals, setup.servo, "", sigma)
        grid.fixed = {_LAG[name]: tau0}
        xg0 = np.append(x_from[k_servo], np.clip(shift0, -MAX_SHIFT_S, MAX_SHIFT_S))
        xg = _solve(grid, xg0, lo_g, hi_g, 1)
        grid.sigma = sigma
        cost = float(np.sum(grid.residuals(xg) ** 2))
        if best is None or cost < best[1]:
            x0 = np.append(x_from, tau0)
            x0[k_servo] = xg[:-1]
            x0[len(free)] = xg[-1]
            best = (x0, cost)
    assert best is not None
    problem = _Problem(setup.moves, setup.vals, free, _LAG[name], sigma, setup.prior)
    x = _solve(problem, best[0], np.append(setup.lo, 0.0), np.append(setup.hi, MAX_DELAY_S), 1)
    return x, problem


def _fit_explanations(setup: _Setup) -> dict[str, tuple[np.ndarray, _Problem]]:
    """Each explanation's fitted vector and problem: no delay first, then each lag."""
    lags = ["servo_delay", "sensor_lowpass"]
    if any(m.force is not None for m in setup.moves):
        lags.append("force_lowpass")
    x_fit = np.array([setup.vals[n] for n in setup.free] + [0.0])
    start = _Problem(setup.moves, setup.vals, setup.free, "", prior=setup.prior)
    start.sigma = _sigmas(*start.channels(x_fit))
    x_none = _solve(start, x_fit, setup.lo, setup.hi)
    fitted = {"no_delay": (x_none, start)}
    for name in lags:
        fitted[name] = _fit_lag(setup, name, x_none, start.sigma)
    return fitted


@dataclass
class _Scored:
    """The explanations scored: each one's channels and prior chi-square, the scorer."""

    chans: dict[str, tuple[np.ndarray, np.ndarray]]
    chi2: dict[str, float]
    ratios: tuple[float, float]
    scorer: _Scorer


def _score(fitted: dict[str, tuple[np.ndarray, _Problem]]) -> _Scored:
    """Channels, prior terms and the scorer, its samples per independent one the least of
    the explanations' (the acceleration's and the force's)."""
    chans = {name: prob.channels(x) for name, (x, prob) in fitted.items()}
    chi2 = {name: float(np.sum(prob.prior_terms(x) ** 2)) for name, (x, prob) in fitted.items()}
    ratios = (
        min(_independent_ratio(c[0]) for c in chans.values()),
        min(_independent_ratio(c[1]) for c in chans.values()) if chans["no_delay"][1].size else 1.0,
    )
    scorer = _Scorer(ratios, (chans["no_delay"][0].size, chans["no_delay"][1].size))
    return _Scored(chans, chi2, ratios, scorer)


def _explanations(
    setup: _Setup, fitted: dict[str, tuple[np.ndarray, _Problem]], scored: _Scored
) -> list[Explanation]:
    """Each fit as an :class:`Explanation`, best (lowest BIC) first."""
    k0 = len(setup.free) - len(setup.prior) + 1  # the free parameters and the move's start
    out = []
    for name, (x, prob) in fitted.items():
        ra, rf = scored.chans[name]
        v = prob.values(x)
        if name != "servo_delay":
            v.pop("tau_r", None)
        out.append(
            Explanation(
                name, v, float(ra @ ra),
                scored.scorer.bic(ra, rf, k0 + (1 if _LAG[name] else 0)) + scored.chi2[name],
                _TEXT[name], float(np.sqrt(np.mean(ra**2))),
                float(np.sqrt(np.mean(rf**2))) if rf.size else None,
            )
        )  # fmt: skip
    out.sort(key=lambda e: e.bic)
    return out


def _delay_interval(
    setup: _Setup, late: tuple[np.ndarray, _Problem], scored: _Scored
) -> tuple[float, float]:
    """The delay's 95 % profile interval: where the deviance rises by chi2(1, 95 %)."""
    x_late, late_problem = late
    tau = float(x_late[-1])
    dev_late = scored.scorer.deviance(*scored.chans["servo_delay"]) + scored.chi2["servo_delay"]

    def excess(t: float) -> float:
        held = _Problem(
            setup.moves, {**setup.vals, "tau_r": t}, setup.free, "", late_problem.sigma,
            setup.prior,
        )  # fmt: skip
        x = _solve(held, x_late[:-1], setup.lo, setup.hi, 1)
        dev = scored.scorer.deviance(*held.channels(x)) + float(np.sum(held.prior_terms(x) ** 2))
        return dev - dev_late - CHI2_95

    step = max(0.002, 0.25 * tau)
    lower = 0.0
    if tau > 0 and excess(0.0) > 0:
        lower = float(brentq(excess, 0.0, tau, xtol=2e-4))
    upper = tau + step
    while upper < MAX_DELAY_S and excess(upper) < 0:
        upper += step
        step *= 1.5
    upper = min(upper, MAX_DELAY_S)
    if upper < MAX_DELAY_S:
        upper = float(brentq(excess, tau, upper, xtol=2e-4))
    return lower, upper


def _verdict(explanations: Sequence[Explanation], lower: float) -> tuple[str, str]:
    """The verdict and what an ambiguous delay is not told apart from (``twin``)."""
    by = {e.name: e for e in explanations}
    gain = by["no_delay"].bic - by["servo_delay"].bic
    rivals = [e for e in explanations if e.name not in ("no_delay", "servo_delay")]
    rival = min(rivals, key=lambda e: e.bic)
    if gain < NAME_DELTA_BIC or lower <= 0.0:
        if by["no_delay"].bic - rival.bic >= NAME_DELTA_BIC and (
            by["servo_delay"].bic - rival.bic >= TIE_DELTA_BIC
        ):
            return rival.name, "sensor"
        if lower > 0.0:  # a delay fits, not decisively: nor is it ruled out
            return "ambiguous", "stiffer"
        return "none", "sensor"
    if by["servo_delay"].bic - rival.bic >= TIE_DELTA_BIC:
        return rival.name, "sensor"
    if rival.bic - by["servo_delay"].bic >= TIE_DELTA_BIC:
        return "servo_delay", "sensor"
    return "ambiguous", "sensor"


def examine_servo_delay(
    model: Model,
    values: Mapping[str, float],
    free: Sequence[str],
    trials: Sequence[Any],
    forces: Sequence[np.ndarray | None] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    references: Sequence[tuple[Any, float] | None] | None = None,
    held_sd: Mapping[str, float] | None = None,
) -> ServoDelay:
    """Fit the robot's log with and without a servo delay, and a sensor's lag instead.

    Parameters
    ----------
    model : Model
        The fitted model (with ``servo``).
    values : mapping of str to float
        Its fitted values.
    free : sequence of str
        The parameters the fit varied (refitted in every explanation).
    trials : sequence of TrialData
        The fitted moves (``input`` with the reference, ``accel`` measured).
    forces : sequence of numpy.ndarray or None, optional
        Per trial, the measured servo force at ``input.time`` (N, rest level removed,
        signed with the motion), or None: the force channel's timing is the strongest
        evidence of a late servo.
    bounds : mapping, optional
        Bounds of the free parameters (default: the model's).
    references : sequence, optional
        Per trial, ``(move, shift)``: the reference move (``evaluate(t)``) and the shift
        the fit gave it (s), so the delayed servo reads the move itself, not samples of
        it; None (or a None entry) interpolates the sampled reference.
    held_sd : mapping, optional
        Relative standard deviation of each held balancer value (default
        :data:`HELD_RELATIVE_SD`): held values move within it in every explanation.

    Returns
    -------
    ServoDelay
    """
    why = _why_not_examined(model)
    if why is not None:
        return ServoDelay(False, "not_examined", why=why)
    moves = _moves(trials, forces, references)
    if not moves:
        return ServoDelay(False, "not_examined", why="no robot move with its reference")
    setup = _setup(model, values, free, moves, bounds, held_sd)
    fitted = _fit_explanations(setup)
    scored = _score(fitted)
    explanations = _explanations(setup, fitted, scored)
    lower, upper = _delay_interval(setup, fitted["servo_delay"], scored)
    verdict, twin = _verdict(explanations, lower)
    return ServoDelay(
        True, verdict, float(fitted["servo_delay"][0][-1]), (lower, upper), explanations,
        scored.ratios[0], has_force=any(m.force is not None for m in moves), twin=twin,
    )  # fmt: skip


def move_forces(trials: Sequence[Any], sources: Sequence[Any]) -> list[np.ndarray | None]:
    """The measured servo force of each fitted move, at the move's fitted sample times.

    Parameters
    ----------
    trials : sequence of TrialData
        The fitted moves.
    sources : sequence
        The segmented trials they came from (``index``, ``time``, ``force``: the move's
        force with its rest level removed, signed with the motion).

    Returns
    -------
    list of numpy.ndarray or None
        One per trial; None where its source holds no force channel.
    """
    by_index = {getattr(s, "index", None): s for s in sources}
    out: list[np.ndarray | None] = []
    for td in trials:
        src = by_index.get(td.index)
        force = getattr(src, "force", None)
        t_src = getattr(src, "time", None)
        if force is None or t_src is None:
            out.append(None)
            continue
        t_src, force = np.asarray(t_src, float), np.asarray(force, float)
        ok = np.isfinite(force) & np.isfinite(t_src)
        if ok.sum() < 10 or force.shape != t_src.shape:
            out.append(None)
            continue
        t = np.asarray(td.input.time, float)
        inside = (t >= t_src[ok][0]) & (t <= t_src[ok][-1])
        f = np.full(t.shape, np.nan)
        f[inside] = np.interp(t[inside], t_src[ok], force[ok])
        out.append(f)
    return out


def move_references(
    trials: Sequence[Any], sources: Sequence[Any]
) -> list[tuple[Any, float] | None]:
    """The reference move of each fitted move and the shift the fit gave its start.

    Parameters
    ----------
    trials : sequence of TrialData
        The fitted moves (``t_step`` moved by the fit's refinement of the start).
    sources : sequence
        The segmented trials they came from (``index``, ``t_step``, ``reference``).

    Returns
    -------
    list
        One ``(move, shift)`` per trial, or None where its source holds no move with an
        ``evaluate`` method.
    """
    by_index = {getattr(s, "index", None): s for s in sources}
    out: list[tuple[Any, float] | None] = []
    for td in trials:
        src = by_index.get(td.index)
        ref = getattr(src, "reference", None)
        if ref is None or not hasattr(ref, "evaluate"):
            out.append(None)
            continue
        out.append((ref, float(td.t_step) - float(getattr(src, "t_step", td.t_step))))
    return out
