"""Which trial to record next: experiment design from the fit's Fisher information (issue 34.3).

The information the trials already hold is ``I0 = J^T J / (sigma^2 tau)`` (``J`` the
simulated sensitivities of the fitted samples, ``sigma^2 tau`` the noise variance widened
for the residual's correlation, as the standard errors are: ``inv(I0)`` is the fit's
covariance). A candidate step trial (a thrust level and direction, a rest before the step,
a duration after it, at the fit's sample rate) simulated at the fitted values adds
``I_c = J_c^T J_c / (sigma^2 tau)``, so the interval predicted after recording it is
``1.96 sqrt(diag(inv(I0 + I_c)))``. Trials are chosen one after another (each given what
the earlier ones add) to shrink the target: one parameter's variance (the one the user
names, or by default the widest interval relative to its value) or, for ``"all"``, the
determinant of the covariance (D-optimal).

Candidates move the load at most :data:`TRAVEL_FACTOR` times as far as the recorded trials
did (the hoist's travel is finite). A limit or friction the data do not reach
(``not_reached``) has no sensitivity at the end of its range; it is evaluated at the bound
the data leave open (``v_max >= 0.46``: at 0.46), so a trial that reaches that far gets
the information and is proposed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from balancer_id.errors import BalancerIdError, UsageError
from balancer_id.identify.band import Z95
from balancer_id.identify.data import TrialData
from balancer_id.identify.matching import MatchResult
from balancer_id.identify.timing import _derivative
from balancer_id.simulation.engine import PackedTrials, TrialInput
from balancer_id.simulation.inputs import Thrust

__all__ = ["Candidate", "Design", "Proposal", "candidate_grid", "design_trials"]

#: Thrust levels tried, as multiples of the largest level recorded.
LEVEL_FACTORS = (0.25, 0.5, 1.0, 1.5, 2.0, 3.0)
#: Durations after the step tried, as multiples of the median recorded (and the cap, s).
DURATION_FACTORS = (0.5, 1.0, 2.0, 4.0)
MAX_DURATION_S = 120.0
#: Rests before the step tried (s).
RESTS_S = (1.0, 3.0)
#: A trial may move the load at most this many times the farthest the recorded trials
#: moved it (the hoist's travel is finite, and unknown here).
TRAVEL_FACTOR = 1.5
#: A trial proposed to reach a speed limit goes this much faster than the bound the data
#: leave open and than every recorded trial.
REACH_MARGIN = 1.2
#: A prior information so weak it only keeps an unseen direction finite: a standard
#: deviation this many times the parameter's scale.
VAGUE = 1e3


@dataclass(frozen=True)
class Candidate:
    """One step trial that could be recorded.

    Attributes
    ----------
    thrust_N : float
        Signed thrust (N, up positive).
    rest_s : float
        Rest before the step (s).
    duration_s : float
        Recording after the step (s).
    rate_hz : float
        Sample rate (the fit's).
    """

    thrust_N: float
    rest_s: float
    duration_s: float
    rate_hz: float

    @property
    def direction(self) -> str:
        """``"up"`` or ``"down"``."""
        return "up" if self.thrust_N > 0 else "down"

    def trial_input(self) -> TrialInput:
        """The simulated trial: rest, then the step, from rest."""
        dt = 1.0 / self.rate_hz
        t = np.arange(round((self.rest_s + self.duration_s) / dt) + 1) * dt
        return TrialInput(t, Thrust.step(self.rest_s, self.thrust_N))

    def sentence(self) -> str:
        """How to record it, in words."""
        return (
            f"a step of {self.thrust_N:+.3g} N ({self.direction}) after {self.rest_s:g} s at "
            f"rest, recorded {self.duration_s:.3g} s after the step"
        )

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "thrust_N": self.thrust_N,
            "direction": self.direction,
            "rest_s": self.rest_s,
            "duration_s": self.duration_s,
            "rate_hz": self.rate_hz,
        }


@dataclass(frozen=True)
class Proposal:
    """A trial to record next and what it is predicted to do.

    Attributes
    ----------
    candidate : Candidate
        The trial.
    target : str
        The parameter it was chosen for, or ``"all"`` (D-optimal).
    before, after : dict of str to float
        Each parameter's predicted 95 % half-width before and after recording it (and
        the proposals before it).
    peak_speed : float
        The largest speed the trial reaches in the fitted model (m/s; a limit not
        reached is at the end of its range there, so this is the speed it would reach
        without it).
    reaches : str or None
        The parameter not reached so far that it is chosen to reach.
    floor : dict of str to float
        The part of each ``after`` half-width that is the steps' places between
        samples (added in quadrature): no trial at this sampling rate shrinks it.
    """

    candidate: Candidate
    target: str
    before: dict[str, float]
    after: dict[str, float]
    peak_speed: float
    reaches: str | None = None
    floor: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            **self.candidate.to_dict(),
            "target": self.target,
            "halfwidth_before": self.before,
            "halfwidth_after": self.after,
            "peak_speed": self.peak_speed,
            "reaches": self.reaches,
            "halfwidth_floor": self.floor,
        }


@dataclass(frozen=True)
class Design:
    """The proposals, in the order to record them.

    Attributes
    ----------
    target : str
        The criterion: a parameter, or ``"all"`` (D-optimal).
    names : list of str
        The parameters the information is over.
    values : dict of str to float
        The point the sensitivities are taken at (fitted values; an unreached parameter
        at the bound its data leave open).
    now : dict of str to float
        Each parameter's predicted 95 % half-width from the trials recorded.
    proposals : list of Proposal
    unreached : list of str
        Parameters the data do not reach.
    fastest : float
        The largest speed the recorded trials reach in the fitted model (m/s).
    """

    target: str
    names: list[str]
    values: dict[str, float]
    now: dict[str, float]
    proposals: list[Proposal] = field(default_factory=list)
    unreached: list[str] = field(default_factory=list)
    fastest: float = float("nan")

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "target": self.target,
            "parameters": self.names,
            "at": self.values,
            "halfwidth_now": self.now,
            "unreached": self.unreached,
            "proposals": [p.to_dict() for p in self.proposals],
        }


def candidate_grid(trials: Sequence[TrialData]) -> list[Candidate]:
    """The step trials considered: levels, directions, rests and durations around the data's.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials recorded (their levels, durations and rate set the grid's scale).

    Returns
    -------
    list of Candidate
        Every combination of :data:`LEVEL_FACTORS` x the largest level, both directions,
        :data:`RESTS_S` and :data:`DURATION_FACTORS` x the median duration.
    """
    levels = [abs(t.thrust_N) for t in trials if t.thrust_N]
    if not levels:
        raise UsageError("plan: no step trial to scale the proposals on (a move is not planned)")
    top = max(levels)
    after = [float(t.time[-1] - t.t_step) for t in trials]
    d0 = float(np.median(after)) if after else 5.0
    rate = float(np.median([t.rate_hz for t in trials]))
    out = []
    for k in LEVEL_FACTORS:
        for sign in (1.0, -1.0):
            for rest in RESTS_S:
                for m in DURATION_FACTORS:
                    dur = float(min(max(d0 * m, 0.5), MAX_DURATION_S))
                    out.append(Candidate(sign * top * k, rest, round(dur, 2), rate))
    return out


def _scale(match: MatchResult, name: str) -> float:
    p = match.parameters[name]
    return max(abs(p.value), p.stderr or 0.0, 1e-9)


def _point(match: MatchResult) -> tuple[dict[str, float], list[str]]:
    """Fitted values with each unreached parameter at its open bound; the unreached."""
    values = match.values()
    unreached = []
    for name, p in match.parameters.items():
        if p.vary and p.not_reached is not None and p.profile is not None:
            values[name] = p.profile[0] if p.not_reached == "above" else p.profile[1]
            unreached.append(name)
    return values, unreached


def _sensitivities(match: MatchResult, packed, values: dict[str, float], names: list[str]):
    model = match.model
    pvec = np.asarray(model.vector(values), float)
    cols = [list(model.param_names).index(n) for n in names]
    with np.errstate(all="ignore"):
        out, sens = packed.run_sens(model, pvec, cols)
    sens = np.where(np.isfinite(sens), sens, 0.0)
    return out, sens


#: Where a parameter is held at a guess (``A`` from one thrust level), the trials are
#: planned for its value at these multiples of the guess too, the others refitted there.
GUESS_FACTORS = (0.25, 0.5, 2.0, 4.0)


def _guessed_points(
    match: MatchResult, also: Sequence[str], values: dict[str, float]
) -> list[dict[str, float]]:
    """The other values a held-at-a-guess parameter may have, each with the free
    parameters refitted to the data (one thrust level fits ``D0 exp(-A |F|)`` at that level
    equally well for any ``A``: the refit moves ``D0``); refits that fail are skipped.
    """
    from balancer_id.identify.matching import match_trials

    guessed = [nm for nm in also if nm in values and values[nm] != 0]
    if not guessed:
        return []
    model = match.model
    held = {nm: p.value for nm, p in match.parameters.items() if not p.vary}
    out = []
    for f in GUESS_FACTORS:
        fixed = dict(held)
        for nm in guessed:
            lo, hi = model.param(nm).min, model.param(nm).max
            fixed[nm] = float(np.clip(values[nm] * f, lo, hi))
        try:
            refit = match_trials(model, match.data.trials, start=values, fixed=fixed)
        except BalancerIdError:  # a point that cannot be fitted is not planned for
            continue
        if refit.success:
            out.append({**values, **refit.values(), **fixed})
    return out


#: A trial that fills the travel is recorded this much shorter than the time the fitted
#: model takes to reach the limit (s, and at least this share of it).
FILL_MARGIN_S = 0.5
FILL_SHARE = 0.95


def _filling_travel(
    match: MatchResult, grid: Sequence[Candidate], fitted: dict[str, float], travel: float
) -> list[Candidate]:
    """Per level and rest, the trial as long as the travel allows, where the grid's
    durations jump past it: information grows with every second recorded, so the best trial
    at a level is often the longest one that fits (a duration of the grid alone would
    leave a level's best trial out or cut it to half)."""
    if not math.isfinite(travel):
        return []
    model = match.model
    longest: dict[tuple[float, float], Candidate] = {}
    for c in grid:
        key = (c.thrust_N, c.rest_s)
        if key not in longest or c.duration_s > longest[key].duration_s:
            longest[key] = c
    shortest = min(c.duration_s for c in grid)
    pvec = np.asarray(model.vector(fitted), float)
    out = []
    for c in longest.values():
        inp = c.trial_input()
        with np.errstate(all="ignore"):
            pos = PackedTrials.pack([inp]).run(model, pvec)[:, 2]
        beyond = np.flatnonzero(~(np.abs(pos) <= travel))
        if beyond.size == 0:
            continue
        reach = float(inp.time[beyond[0]]) - c.rest_s
        dur = math.floor(min(reach - FILL_MARGIN_S, FILL_SHARE * reach) * 2) / 2
        if dur > shortest and all(
            abs(g.duration_s - dur) > 0.25 for g in grid if (g.thrust_N, g.rest_s) == (
                c.thrust_N, c.rest_s)
        ):
            out.append(Candidate(c.thrust_N, c.rest_s, float(dur), c.rate_hz))
    return out


def _candidate_information(
    match: MatchResult, grid: Sequence[Candidate], point: dict[str, float],
    names: list[str], s2: float, cross: list[np.ndarray] | None = None,
) -> tuple[list[np.ndarray], list[float], list[float]]:
    """Each candidate's information at ``point``, its peak speed and farthest move (and,
    into ``cross``, its sensitivities against its response's time derivative, ``S^T g /
    s2``)."""
    if cross is None:
        cross = []
    model = match.model
    longest: dict[tuple[float, float], Candidate] = {}
    for c in grid:  # one simulation per level and rest: shorter durations are prefixes
        key = (c.thrust_N, c.rest_s)
        if key not in longest or c.duration_s > longest[key].duration_s:
            longest[key] = c
    runs = {}
    pvec = np.asarray(model.vector(point), float)
    cols = [list(model.param_names).index(n) for n in names]
    for key, c in longest.items():
        packed = PackedTrials.pack([c.trial_input()])
        with np.errstate(all="ignore"):
            out, sens = packed.run_sens(model, pvec, cols)
        runs[key] = (np.asarray(c.trial_input().time), out, np.where(np.isfinite(sens), sens, 0.0))
    adds, peaks, moves = [], [], []
    cross.clear()
    for c in grid:
        t, out, s = runs[(c.thrust_N, c.rest_s)]
        rows = t <= c.rest_s + c.duration_s + 1e-9
        moves.append(float(np.nanmax(np.abs(out[rows, 2]))) if rows.any() else 0.0)
        adds.append(s[rows].T @ s[rows] / s2)
        # how the response moves with the trial's timing, against each parameter's
        # sensitivity: what the step's place between samples moves the values by
        g = _derivative(out[rows, 0], t[rows], np.zeros(1, int))
        cross.append(s[rows].T @ np.where(np.isfinite(g), g, 0.0) / s2)
        v = out[rows, 1]
        peaks.append(float(np.nanmax(np.abs(v))) if v.size else 0.0)
    return adds, peaks, moves


def _mean_score(
    infos: list[np.ndarray],
    adds_at: list[list[np.ndarray]],
    j: int | None,
    extra: np.ndarray | None = None,
):
    """Each candidate's objective over the points: the mean of the log target variance (or
    minus the log-determinant), a pseudo-Bayesian design over a guessed parameter;
    ``extra``, each candidate's variance of the target that its information does not
    hold (the steps' places between samples), is added to the target's."""
    total = np.zeros(len(adds_at[0]))
    for info, adds in zip(infos, adds_at, strict=True):
        sc = np.array([_objective(info + add, j) for add in adds])
        if j is not None and extra is not None:
            sc = sc + extra
        if j is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                sc = np.where(sc > 0, np.log(sc), np.inf)
        total += sc
    return total / len(infos) if j is None else np.exp(total / len(infos))


def _typical_halfwidths(infos: list[np.ndarray], names: list[str]) -> dict[str, float]:
    """The half-widths' geometric mean over the points (the fitted point's alone when one)."""
    each = [_halfwidths(info, names) for info in infos]
    return {
        n: float(np.exp(np.mean([np.log(max(h[n], 1e-300)) for h in each]))) for n in names
    }


def _widening(match: MatchResult, info: np.ndarray, names: list[str]) -> np.ndarray:
    """Per parameter, the fit's standard error over the Fisher information's, the
    parameters the fit held (at a guess) held here too; never below 1 (1 where the fit
    gives none)."""
    fitted = [j for j, n in enumerate(names) if match.parameters[n].vary]
    out = np.ones(len(names))
    if not fitted:
        return out
    try:
        var = np.diag(np.linalg.inv(info[np.ix_(fitted, fitted)]))
    except np.linalg.LinAlgError:
        return out
    for v, j in zip(var, fitted, strict=True):
        est = match.parameters[names[j]]
        # the steps' places between samples are no information a new trial adds
        se = math.sqrt(max(est.stderr**2 - est.phase_se**2, 0.0)) if est.stderr else None
        if se and math.isfinite(se) and v > 0:
            out[j] = max(1.0, se / math.sqrt(v))
    return out


#: A parameter is planned for (as the widest) only where the part of its interval a trial
#: can shrink is at least this share of the interval (the rest: the steps' places between
#: samples, :func:`_phase_floor`).
FLOOR_SHARE = 0.5


def _phase_floor(match: MatchResult, names: list[str]) -> dict[str, float]:
    """Each parameter's 95 % half-width from the steps' places between samples alone (the
    part of its standard error no new trial at this rate adds information to)."""
    return {
        n: Z95 * float(match.parameters[n].phase_se or 0.0) if n in match.parameters else 0.0
        for n in names
    }


def _per_second(info: np.ndarray, cross: np.ndarray) -> np.ndarray:
    """How far each value moves per second the drive's timing moves (as the fit's timing
    check regresses it: ``-(S^T S)^-1 S^T g``); nan where the information is singular."""
    try:
        return -np.linalg.solve(info, cross)
    except np.linalg.LinAlgError:
        return np.full(cross.size, np.nan)


class _Floors:
    """The phase floor (:func:`_phase_floor`) as trials are added: each parameter's moves
    with the timing, from the information and ``S^T g`` held (the fitted point's), scaled
    to the fit's own floor now. A strong, short step moves the values more per second of
    its timing: at 200 Hz a 3 N step on a 0.2 kg cart raised m_a's floor from 0.79 to 0.94
    mg (the trial had been chosen as if the floor stayed, and a random trial did as well).
    """

    def __init__(self, info: _Information, floor_now: Mapping[str, float], names: list[str]):
        self.names = names
        self.info = None if info.timing_info is None else info.timing_info.copy()
        self.cross = None if info.timing_now is None else info.timing_now.copy()
        self.adds = info.adds_at[0]
        self.cand_cross = [
            x if np.any(a) else np.zeros_like(x)  # a move too far adds nothing
            for x, a in zip(info.timing_cross, self.adds, strict=False)
        ]
        self.now = np.array([floor_now.get(n, 0.0) for n in names], float)
        per = (
            _per_second(self.info, self.cross)
            if self.info is not None and self.cross is not None
            else np.full(len(names), np.nan)
        )
        ok = np.isfinite(per) & (np.abs(per) > 0)
        # the fit's floor per unit of the predicted moves (0 where it has none)
        self.scale = np.where(ok, self.now / np.where(ok, np.abs(per), 1.0), 0.0)
        self.active = bool(
            self.info is not None
            and np.any(self.now > 0)
            and len(self.cand_cross) == len(self.adds)
        )

    def after(self, i: int | None = None) -> np.ndarray:
        """Each parameter's floor (95 % half-width) with candidate ``i`` added (None: as held)."""
        info, cross = self.info, self.cross
        if not self.active or info is None or cross is None:
            return self.now
        if i is not None:
            info, cross = info + self.adds[i], cross + self.cand_cross[i]
        per = _per_second(info, cross)
        return np.where(np.isfinite(per), self.scale * np.abs(per), self.now)

    def add(self, i: int) -> None:
        """Hold candidate ``i`` (proposed) from now on."""
        if self.active and self.info is not None and self.cross is not None:
            self.info = self.info + self.adds[i]
            self.cross = self.cross + self.cand_cross[i]

    def as_dict(self, i: int | None = None) -> dict[str, float]:
        """:meth:`after` by parameter name."""
        return dict(zip(self.names, map(float, self.after(i)), strict=True))


def _with_floor(half: Mapping[str, float], floor: Mapping[str, float]) -> dict[str, float]:
    """Half-widths with the floor added in quadrature (as the fit's standard error has it)."""
    return {n: float(math.hypot(h, floor.get(n, 0.0))) for n, h in half.items()}


def _halfwidths(info: np.ndarray, names: list[str]) -> dict[str, float]:
    cov = np.linalg.inv(info)
    return {n: float(Z95 * math.sqrt(max(cov[j, j], 0.0))) for j, n in enumerate(names)}


def _objective(info: np.ndarray, target: int | None) -> float:
    """Lower is better: the target's variance, or minus the log-determinant."""
    if target is None:
        sign, logdet = np.linalg.slogdet(info)
        return -logdet if sign > 0 else math.inf
    try:
        return float(np.linalg.inv(info)[target, target])
    except np.linalg.LinAlgError:
        return math.inf


#: Of trials about as good as the best (variance within 5 %, log-determinant within 0.05),
#: the shortest and gentlest is proposed: the information grows with every second
#: recorded, so the best alone would always be the longest, strongest trial.
MODEST_VARIANCE = 1.05
MODEST_LOGDET = 0.05


def _modest(scores: np.ndarray, grid: Sequence[Candidate], logdet: bool) -> int | None:
    """The shortest, gentlest candidate about as good as the best (None: none finite)."""
    finite = np.isfinite(scores)
    if not finite.any():
        return None
    top = float(np.min(scores[finite]))
    near = scores <= (top + MODEST_LOGDET if logdet else top * MODEST_VARIANCE)
    near &= finite
    picks = [int(i) for i in np.flatnonzero(near)]
    key = [(grid[i].duration_s + grid[i].rest_s, abs(grid[i].thrust_N), scores[i]) for i in picks]
    return picks[min(range(len(picks)), key=lambda m: key[m])]


def _planned_names(match: MatchResult, target: str | None, also: Sequence[str]) -> list[str]:
    """The parameters planned for (the free ones and ``also``); refuses a robot's move,
    nothing fitted, or an unknown ``target``."""
    model = match.model
    if model.needs_reference_move:
        raise UsageError("plan: a robot's move is not planned yet; plan the balancer's steps")
    names = [n for n, p in match.parameters.items() if p.vary or n in also]
    if not names:
        raise UsageError("plan: the fit has no free parameter; nothing to plan for")
    if target not in (None, "all", *names):
        raise UsageError(
            f"--param {target}: not a fitted parameter of '{model.spec}' "
            f"(fitted: {', '.join(names)}; or 'all' for D-optimal)"
        )
    return names


def _noise_variance(match: MatchResult, k: int) -> float:
    """The residual's variance per sample, widened by its correlation time."""
    n = match.y.size
    s2 = float(np.sum(match.residual**2)) / max(n - k, 1)
    return s2 * max(float(match.metrics.get("residual_tau", 1.0)), 1.0)


def _travel_and_speed(match: MatchResult, fitted: Mapping[str, float]) -> tuple[float, float]:
    """How far a trial may move (the hoist's travel the trials show, times
    :data:`TRAVEL_FACTOR`) and the fastest speed the trials reach, in the fitted model."""
    model = match.model
    with np.errstate(all="ignore"):
        out0 = match.data.packed.run(model, np.asarray(model.vector(fitted), float))
    travel = TRAVEL_FACTOR * float(np.nanmax(np.abs(out0[:, 2]))) if out0.size else math.inf
    fastest = float(np.nanmax(np.abs(out0[:, 1]))) if out0.size else 0.0
    return travel, fastest


@dataclass
class _Information:
    """The information now at each point (``infos``; the fitted point first), each
    candidate's added information there (``adds_at``), and each candidate's peak speed and
    travel at the fitted point."""

    infos: list[np.ndarray]
    adds_at: list[list[np.ndarray]]
    peaks: np.ndarray
    moved: np.ndarray
    #: at the fitted point, unwidened: the information now, the sensitivities against
    #: the response's time derivative now (``S^T g / s2``) and each candidate's
    timing_info: np.ndarray | None = None
    timing_now: np.ndarray | None = None
    timing_cross: list[np.ndarray] = field(default_factory=list)


def _information(
    match: MatchResult,
    grid: list[Candidate],
    values: dict[str, float],
    also: Sequence[str],
    names: list[str],
    s2: float,
) -> _Information:
    """The information now and each candidate's, at the fitted point and, where a
    parameter is held at a guess, at the other values the data allow (each refitted): the
    proposals are chosen for all of them (module docstring)."""
    ridge = np.diag([1.0 / (VAGUE * _scale(match, nm)) ** 2 for nm in names])
    points = [values, *_guessed_points(match, also, values)]
    infos, adds_at = [], []
    cross: list[np.ndarray] = []
    for point in points:
        out, sens = _sensitivities(match, match.data.packed, point, names)
        infos.append(sens.T @ sens / s2 + ridge)
        adds_p, peaks, moves = _candidate_information(
            match, grid, point, names, s2, cross if point is values else None
        )
        adds_at.append(adds_p)
        if point is values:
            peak_arr, moved_arr = np.array(peaks), np.array(moves)
            starts = np.array([sl.start for sl in match.data.slices()], int)
            g = _derivative(out[:, 0], np.asarray(match.data.packed.t_all, float), starts)
            now = sens.T @ np.where(np.isfinite(g), g, 0.0) / s2
            timing_info = infos[-1].copy()
    return _Information(infos, adds_at, peak_arr, moved_arr, timing_info, now, cross)


def _limited(
    match: MatchResult,
    grid: list[Candidate],
    values: dict[str, float],
    unreached: list[str],
    names: list[str],
    s2: float,
    info: _Information,
    travel: float,
) -> None:
    """Speeds and travels without a speed limit the data do not reach, and no information
    from a candidate that moves beyond the travel; the information now scaled to the
    fit's standard errors."""
    # a speed limit the data do not reach limits the simulation at its open bound: how
    # fast a trial goes, and how far it moves, are those of the balancer without it (the
    # limit may lie anywhere above; a trial that reaches it must pass the bound)
    model = match.model
    lifted = {
        nm: model.param(nm).max
        for nm in unreached
        if match.parameters[nm].not_reached == "above" and match.parameters[nm].unit == "m/s"
    }
    if lifted:
        _, peaks_free, moves_free = _candidate_information(
            match, grid, {**values, **lifted}, names, s2
        )
        info.peaks, info.moved = np.array(peaks_free), np.array(moves_free)
    # too far a move adds nothing: it cannot be recorded on this hoist
    far = info.moved > travel
    for adds_p in info.adds_at:
        for i in np.flatnonzero(far):
            adds_p[i] = np.zeros_like(info.infos[0])
    # the fit reports standard errors that may exceed the Fisher information's (widened
    # to the trials' scatter): the information held now is scaled to them, parameter by
    # parameter (its correlations kept), so that the plan starts from the fit's intervals
    d = _widening(match, info.infos[0], names)
    info.infos = [inf / np.outer(d, d) for inf in info.infos]


def _goals(
    match: MatchResult,
    target: str | None,
    count: int,
    names: list[str],
    unreached: list[str],
    now: Mapping[str, float],
    floor: Mapping[str, float],
) -> list[tuple[str | None, str]]:
    """The (parameter or None for D-optimal, label) each proposal aims at, in order: the
    unreached parameters first, then the target (or the widest interval a trial can
    shrink: ``now`` without the ``floor`` the steps' places between samples leave, of a
    parameter whose interval is not mostly that floor, :data:`FLOOR_SHARE`)."""
    order: list[tuple[str | None, str]] = [(u, u) for u in unreached if target in (None, u)]
    if target == "all":
        order += [(None, "all")] * count
    else:
        if target is None:
            rel = {nm: now[nm] / _scale(match, nm) for nm in names if nm not in unreached}
            # a cart's T_a at 200 Hz: 1.6 ms of its 1.62 ms standard error is where the steps
            # fell between samples; a trial shrank the rest 3x and the interval 2 %
            free = {
                nm: r
                for nm, r in rel.items()
                if now[nm] >= FLOOR_SHARE * math.hypot(now[nm], floor[nm])
            }
            rel = free or rel
            chosen = max(rel, key=lambda nm: rel[nm]) if rel else names[0]
        else:
            chosen = str(target)  # a parameter's name (not None, not "all")
        order += [(chosen, chosen)] * count
    return order[: max(count, len(unreached) if target is None else 1)]


def _proposals(
    match: MatchResult,
    order: list[tuple[str | None, str]],
    grid: list[Candidate],
    info: _Information,
    names: list[str],
    values: Mapping[str, float],
    unreached: list[str],
    fastest: float,
    floors: _Floors,
) -> list[Proposal]:
    """Each goal's best candidate in turn, its information added before the next; the
    half-widths with the floor the steps' places between samples leave (``floors``),
    predicted after each candidate (a target's candidates are scored with it)."""
    infos = info.infos
    peaks = list(info.peaks)
    proposals = []
    for goal, label in order:
        j = names.index(goal) if goal is not None else None
        extra = None
        if j is not None and floors.active:
            extra = np.array([floors.after(i)[j] for i in range(len(grid))]) ** 2 / Z95**2
        scores = _mean_score(infos, info.adds_at, j, extra)
        if goal in unreached and match.parameters[goal].not_reached == "above":
            # a speed limit is reached by a trial faster than both the bound the data
            # leave open and every trial so far (in the model without the limit)
            if match.parameters[goal].unit == "m/s":
                need = REACH_MARGIN * max(values[goal], fastest)
                scores = np.where(info.peaks >= need, scores, np.inf)
        best = _modest(scores, grid, j is None)
        if best is None:
            break
        before = _with_floor(_typical_halfwidths(infos, names), floors.as_dict())
        infos = [inf + adds_p[best] for inf, adds_p in zip(infos, info.adds_at, strict=True)]
        floors.add(best)
        proposals.append(
            Proposal(
                grid[best],
                label,
                before,
                _with_floor(_typical_halfwidths(infos, names), floors.as_dict()),
                peaks[best],
                goal if goal in unreached else None,
                floors.as_dict(),
            )
        )
    return proposals


def design_trials(
    match: MatchResult, target: str | None = None, count: int = 3, also: Sequence[str] = ()
) -> Design:
    """Propose the next ``count`` step trials that shrink the target interval most.

    Parameters
    ----------
    match : MatchResult
        The fit (its model, trials, values, noise variance and correlation time).
    target : str, optional
        A fitted parameter, ``"all"`` (D-optimal: the covariance's determinant), or None:
        first each parameter the data do not reach (the trial that reaches it), then the
        parameter whose 95 % interval is widest against its value.
    count : int
        Trials to propose (at least 1).
    also : sequence of str
        Parameters the fit held because the data could not determine them (``A`` from
        one thrust level): planned for as if free (their interval now is unbounded).

    Returns
    -------
    Design

    Raises
    ------
    UsageError
        An unknown or held ``target``, nothing fitted, or a model that needs a robot's
        reference move (its moves are not planned).
    """
    names = _planned_names(match, target, also)
    values, unreached = _point(match)
    s2 = _noise_variance(match, len(names))
    fitted = match.values()  # where the load goes (the bound point only for information)
    travel, fastest = _travel_and_speed(match, fitted)
    grid = candidate_grid(match.data.trials)
    grid += _filling_travel(match, grid, fitted, travel)
    info = _information(match, grid, values, also, names, s2)
    _limited(match, grid, values, unreached, names, s2, info, travel)
    reducible = _halfwidths(info.infos[0], names)
    floor = _phase_floor(match, names)
    order = _goals(match, target, count, names, unreached, reducible, floor)
    # the intervals as the fit reports them, now and after: with the spread the steps'
    # places between samples leave (no trial shrinks it; a strong, short step widens it)
    floors = _Floors(info, floor, names)
    proposals = _proposals(
        match, order, grid, info, names, values, unreached, fastest, floors
    )
    return Design(
        target=target or "widest",
        names=names,
        values={nm: float(values[nm]) for nm in names},
        now=_with_floor(reducible, floor),
        proposals=proposals,
        fastest=fastest,
        unreached=unreached,
    )
