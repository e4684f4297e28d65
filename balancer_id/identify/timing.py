"""Is the acceleration on time with its drive? A score test at the fit's optimum (issue 31).

A force channel time-stamped late (a wireless sensor, a second device), a balancer's own
dead time or a sensor's low-pass all shift the measured acceleration in time against the
simulated one. The fitted values then bend to absorb the shift (``T_a`` shorter or longer
by about the delay, ``m_a`` and ``A`` with it) and their intervals, which assume the model
is right, no longer hold the truth.

A shift of the drive by ``d`` seconds moves the simulated output by ``-d`` times its own
time derivative to first order (every response of a time-invariant model to a shifted
input is the shifted response). So the residual is regressed on the fit's sensitivities
``J`` and on that one extra column ``g = dy_model/dt``:

    r ~ J dtheta + g d

``d`` estimates the acceleration's lead over the recorded drive (positive: the
acceleration moves before the force says it should, i.e. the force channel is late;
negative: a dead time or a low-pass), with its standard error (the residual's variance
widened by its correlation time, as the fit's own errors are). ``dtheta`` is how far
each parameter would move were the shift modelled: the first-order bias the omitted shift
puts in it. Where ``d`` is clearly non-zero (:data:`TIMING_Z` standard errors), each
parameter that it moves by more than :data:`SHIFT_SE` of its own standard error is no
longer trusted: its interval does not account for the shift. The others keep their trust.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from balancer_id.identify.data import centred_samples
from balancer_id.identify.matching import MatchResult
from balancer_id.identify.starts import lag_floor
from balancer_id.notes import Note

#: The shift must be this many standard errors from zero to be called (a sensor low-pass of
#: 13-17 Hz shows at 3: its few ms of lag move T_a by 4 standard errors).
TIMING_Z = 3.0

#: A parameter the shift moves by more than this many of its standard errors loses trust.
SHIFT_SE = 1.0

#: Where the shift moves any parameter by more than this many of its standard errors,
#: the first order holds for none: every fitted value loses trust.
LINEAR_SE = 3.0

#: Rows simulated per block (a long session is never held whole with its sensitivities).
BLOCK_ROWS = 1 << 16


@dataclass(frozen=True)
class TimingCheck:
    """The acceleration's lead over its drive, at a fit's optimum.

    Attributes
    ----------
    lead_s : float
        Estimated lead (s): positive, the acceleration moves before the recorded drive.
    stderr_s : float
        Its standard error (s).
    shift : dict of str to float
        How far each fitted parameter would move were the shift modelled.
    moved : tuple of str
        Parameters moved by more than :data:`SHIFT_SE` of their standard error, when the
        lead is clear (:attr:`clear`); empty otherwise.
    phase_se : dict of str to float
        Each value's error from where each step lies between its samples
        (:func:`sampling_variance`), added to its standard error.
    noise_se_s : float
        The lead's standard error from the residual alone (s; :attr:`stderr_s` less the
        steps' places between samples). 0: not known (``stderr_s`` is all).
    half_sample_s : float
        Half the force's sample interval (s): the most that the steps' places between
        samples can move the lead. 0 for a smooth force.
    """

    lead_s: float
    stderr_s: float
    shift: dict[str, float]
    moved: tuple[str, ...]
    phase_se: dict[str, float] = field(default_factory=dict)
    noise_se_s: float = 0.0
    half_sample_s: float = 0.0
    #: Drive lags on their floor (:func:`lags_at_floor`) when the drive is clearly late:
    #: each fitted value bends with the lateness read as "no lag".
    floored: tuple[str, ...] = ()
    #: The lead a drive lag on its floor accounts for (s): the model cannot lag less
    #: than its floor, so a balancer with less lag leads the model by up to the lag's
    #: value. A lead is clear only beyond it (0: no lag on its floor).
    floor_lead_s: float = 0.0

    @property
    def z(self) -> float:
        """The lead in standard errors."""
        return self.lead_s / self.stderr_s if self.stderr_s > 0 else 0.0

    @property
    def clear(self) -> bool:
        """Whether the lead is clearly not zero: :data:`TIMING_Z` standard errors of the
        residual's beyond the half sample the steps' places can explain, or
        :data:`TIMING_Z` of its whole standard error.

        Where a step lies between its two samples is unknown, but bounded: the model
        places it halfway, so the steps' places move the lead by half a sample at most,
        however the steps share their places (a programmed schedule). Counted as a
        variance (``dt^2 / 12``, undivided by the steps) it cost the test its power at low
        rates: at 100 Hz it took 8.7 ms to call a lead, where the bound takes 5 ms plus
        the residual's own 3 standard errors.
        """
        if not np.isfinite(self.z):
            return False
        if self.floor_lead_s > 0 and self.lead_s > 0:
            se = self.noise_se_s if self.noise_se_s > 0 else self.stderr_s
            beyond = self.half_sample_s + self.floor_lead_s + TIMING_Z * se
            return bool(self.lead_s >= beyond)
        if abs(self.z) >= TIMING_Z:
            return True
        if self.half_sample_s > 0 and self.noise_se_s > 0:
            return abs(self.lead_s) >= self.half_sample_s + TIMING_Z * self.noise_se_s
        return False

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict (``metrics``-style figures)."""
        return {
            "lead_s": self.lead_s,
            "stderr_s": self.stderr_s,
            "z": self.z,
            "shift": self.shift,
            "moved": list(self.moved),
        }


def _row_times(match: MatchResult) -> np.ndarray:
    """The time of every fitted row, trials in order (rows of ``match.y``)."""
    parts = []
    for td, sl in zip(match.data.trials, match.data.slices(), strict=True):
        t = np.asarray(td.time, dtype=float)
        n = sl.stop - sl.start
        parts.append(t[:n] if t.size >= n else np.linspace(0.0, 1.0, n))
    return np.concatenate(parts) if parts else np.zeros(0)


def _run_slices(match: MatchResult) -> list[slice]:
    """The rows of each stretch the model runs through without a break: a session's
    trials that continue one another (the simulation carries its state over) are one.

    A step inside a session begins the next trial, so the response's jump at the step
    (the viscosity changing with the thrust while the balancer moves) lies on the
    trials' border. Shifted or differentiated trial by trial, the output never moves
    that jump across the border, and a force channel time-stamped late, whose steps
    the acceleration answers before the recorded force changes, went unseen (a 23 ms
    lateness read as 1 +- 3 ms while A sat 3.4 standard errors off).
    """
    trials = match.data.trials
    out: list[slice] = []
    for i, sl in enumerate(match.data.slices()):
        td = trials[i]
        joined = (
            bool(out)
            and td.continues
            and td.previous is not None
            and td.previous.time[-1] == trials[i - 1].time[-1]
            and trials[i - 1].source == td.source
            and out[-1].stop == sl.start
        )
        if joined:
            out[-1] = slice(out[-1].start, sl.stop)
        else:
            out.append(sl)
    return out


def _derivative(y: np.ndarray, t: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """``dy/dt`` row by row, one-sided at each trial's first and last row."""
    g = np.zeros_like(y)
    if y.size < 2:
        return g
    dt = np.diff(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(dt > 0, np.diff(y) / np.where(dt > 0, dt, 1.0), 0.0)
    forward = np.append(slope, 0.0)
    backward = np.insert(slope, 0, 0.0)
    first = np.zeros(y.size, dtype=bool)
    first[starts] = True
    last = np.roll(first, -1)
    last[-1] = True
    g = 0.5 * (forward + backward)
    g[first] = forward[first]
    g[last] = backward[last]
    return g


def sampling_variance(match: MatchResult, smooth: bool = False) -> float:
    """The variance of the drive's timing that the force's sampling leaves (s^2).

    A step is seen first at one sample; it happened somewhere since the sample before,
    and the model places it halfway (:func:`~balancer_id.identify.data.centred_changes`).
    The true instant lies anywhere in that interval: a spread of ``dt^2 / 12``. The
    steps may share their place between samples (a programmed schedule whose period is
    a whole number of samples), so the spread is not divided by their number: a mean
    over them is no better known than one of them.

    A window's force keeps each sample's value until the next
    (:func:`~balancer_id.identify.data.measured_thrust`): against the force between the
    samples it is late by anything from nothing to a whole sample (half a sample, for
    a force read at its instant; less, where the sensors' own filters lag the
    acceleration alike), ``dt^2 / 3`` about the hold's instant. A guided move's force is
    held about each sample (:func:`~balancer_id.identify.data.centred_samples`):
    ``dt^2 / 12``. Both are counted only with ``smooth`` (the values' standard errors):
    the timing test's own statistics keep to the steps' places.

    Parameters
    ----------
    match : MatchResult
        The fit.
    smooth : bool
        Count a smooth force's hold too (``dt^2 / 3``).

    Returns
    -------
    float
        0 when every trial's force is a smooth measured series (held at each sample:
        no step to place) and ``smooth`` is False.
    """
    spreads = []
    for td in match.data.trials:
        times = np.asarray(td.input.thrust.times, dtype=float)
        t = np.asarray(td.time, dtype=float)
        if t.size < 2:
            continue
        dt = float(np.median(np.diff(t)))
        if times.size == t.size and np.array_equal(times, t):  # a smooth series, held
            if smooth:
                spreads.append(dt * dt / 3.0)
            continue
        if times.size == t.size and np.array_equal(times, centred_samples(t)):
            if smooth:  # a guided move's force, held about each sample
                spreads.append(dt * dt / 12.0)
            continue
        spreads.append(dt * dt / 12.0)
    return float(np.median(spreads)) if spreads else 0.0


def lags_at_floor(match: MatchResult) -> tuple[str, ...]:
    """The fitted drive lags held on their lower bound (the samples' floor, or 0).

    A lag on its floor cannot shorten further, so it cannot absorb a drive that is late
    against the acceleration: the fit reads such a drive as "no lag seen" (a first-order
    lag and a delay move a slow response alike, so a free lag column would take the
    lead's place in :func:`timing_check` and hide it). These lags are held in the
    regression; a clear lead then also takes their trust, since the lag the log shows
    is the lead's remainder, not the floor.

    Parameters
    ----------
    match : MatchResult
        A converged fit.

    Returns
    -------
    tuple of str
        Names of the drive lags at their minimum bound or below two floors.
    """
    floor = lag_floor(match.data.trials)
    out = []
    for name in match.model.drive_lag_names:
        est = match.parameters.get(name)
        if est is None or not est.vary:
            continue
        if est.at_bound == "min" or (floor > 0 and est.value < 2 * floor):
            out.append(name)
    return tuple(out)


#: The longest lead or lag of the acceleration on its drive the whole-shift profile tries (s).
SHIFT_MAX_S = 0.25

#: At most this many leads on the whole-shift profile's grid (its step is half a sample,
#: or coarser so that the grid holds no more).
SHIFT_GRID = 100

#: The whole-shift profile holds the shifted outputs at once up to this many values.
SHIFT_CELLS = 4_000_000


def _shifted(
    match: MatchResult, t: np.ndarray, lead: float, slices: list[slice] | None = None
) -> np.ndarray:
    """The model's output were the drive ``lead`` seconds earlier (negative: later):
    each stretch's output (``slices``, default :func:`_run_slices`: a session's trials as
    one) moved in time by ``lead`` (a time-invariant model from rest; its first and last
    values held)."""
    y_model = np.asarray(match.y_model, dtype=float)
    out = np.empty_like(y_model)
    for sl in _run_slices(match) if slices is None else slices:
        tt = t[sl]
        out[sl] = np.interp(tt + lead, tt, y_model[sl]) if tt.size > 1 else y_model[sl]
    return out


def _shift_grid(match: MatchResult, t: np.ndarray, both: bool = False) -> np.ndarray | None:
    """The leads the whole-shift profile tries (s, zero left out): positive only (the
    acceleration before its drive) where a lag sits on its floor, which cannot take a
    lag's place; both signs (``both``) otherwise. None: no usable sample interval, or
    the shifted outputs would not fit :data:`SHIFT_CELLS`."""
    if t.size < 4 or t.size != match.y.size:
        return None
    dt = float(np.median(np.diff(t)))
    if not (np.isfinite(dt) and dt > 0):
        return None
    step = max(dt / 2, 2 * SHIFT_MAX_S / SHIFT_GRID)
    half = np.arange(step, SHIFT_MAX_S + step / 2, step)
    grid = np.concatenate([-half[::-1], half]) if both else half
    while grid.size * t.size > SHIFT_CELLS and grid.size > 8:
        grid = grid[::2]
    return grid if grid.size * t.size <= SHIFT_CELLS else None


@dataclass
class _ShiftProfile:
    """The residual's sums against each whole shift of the output (:func:`timing_check`
    accumulates them block by block): ``sum(D^2)``, ``r . D`` and ``J^T D`` per lead."""

    grid: np.ndarray
    deltas: np.ndarray  # (leads, rows): the output moved by each lead, less the output
    dd: np.ndarray
    rd: np.ndarray
    jd: np.ndarray

    @classmethod
    def start(
        cls,
        match: MatchResult,
        t: np.ndarray,
        grid: np.ndarray,
        k: int,
        slices: list[slice] | None = None,
    ) -> _ShiftProfile:
        y_model = np.asarray(match.y_model, dtype=float)
        deltas = np.stack([_shifted(match, t, float(d), slices) - y_model for d in grid])
        g = grid.size
        return cls(grid, deltas, np.zeros(g), np.zeros(g), np.zeros((k, g)))

    def add(self, first: int, stop: int, r: np.ndarray, sens: np.ndarray) -> None:
        block = self.deltas[:, first:stop]
        self.dd += np.einsum("gi,gi->g", block, block)
        self.rd += block @ r
        self.jd += sens.T @ block.T

    def lead(
        self, jtj: np.ndarray, jr: np.ndarray, rtr: float, dof: int, tau: float, dt: float
    ) -> tuple[float, float, float, np.ndarray] | None:
        """The profile's best lead, its standard error (its 1-sigma interval's half
        width), the fall of the residual's sum of squares there in noise variances, and
        each value's move were that shift modelled; None when no lead lowers it."""
        k = jtj.shape[0]
        try:
            inv = np.linalg.inv(jtj) if k else np.zeros((0, 0))
        except np.linalg.LinAlgError:
            return None
        # r - D regressed on J: what is left of the residual with each shift modelled
        jrd = jr[:, None] - self.jd
        rss = rtr - 2 * self.rd + self.dd - np.einsum("kg,kl,lg->g", jrd, inv, jrd)
        rss0 = float(rtr - jr @ inv @ jr)
        leads = np.concatenate([[0.0], self.grid])
        costs = np.concatenate([[rss0], rss])
        order = np.argsort(leads)
        leads, costs = leads[order], costs[order]
        i = int(np.argmin(costs))
        if leads[i] == 0.0 or not np.isfinite(costs[i]):
            return None
        s2 = max(float(costs[i]), 0.0) / max(dof, 1) * tau
        if not s2 > 0:
            return None
        inside = leads[costs <= costs[i] + s2]  # the 1-sigma profile interval
        step = float(np.median(np.diff(leads))) if leads.size > 1 else dt
        se = max(float(inside.max() - inside.min()) / 2.0, max(step, dt) / (2 * np.sqrt(3.0)))
        g = int(np.flatnonzero(self.grid == leads[i])[0])
        move = -(inv @ self.jd[:, g]) if k else np.zeros(0)
        return float(leads[i]), se, (rss0 - float(costs[i])) / s2, move


def _whole_shift(
    profile: _ShiftProfile,
    gram: np.ndarray,
    k: int,
    n: int,
    match: MatchResult,
    t: np.ndarray,
    first_order: TimingCheck,
) -> TimingCheck | None:
    """The check from the whole-shift profile where the first-order one is not clear.

    A response that jumps (a drive lag on its floor; the paper's viscosity changing with
    the thrust while the balancer moves) moves by whole samples: the first-order column
    ``dy/dt`` is then one spike per step and reads a 30 ms lateness as 3 ms, or a 25 ms
    one as 12 +- 7 ms while A is 4.5 standard errors off. The profile moves
    the whole output by each lead and refits the values to first order; its lead is
    clear by the same rule (:attr:`TimingCheck.clear`) and by its fall in the residual
    (:data:`TIMING_Z` squared noise variances). None: not clear that way either.
    """
    tau = max(float(match.metrics.get("residual_tau", 1.0)), 1.0)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    best = profile.lead(gram[:k, :k], gram[:k, k + 1], float(gram[k + 1, k + 1]), n - k, tau, dt)
    if best is None:
        return None
    lead, se, fall, move = best
    whole = replace(
        first_order,
        lead_s=lead,
        stderr_s=float(np.hypot(se, first_order.half_sample_s / np.sqrt(3.0))),
        noise_se_s=se,
    )
    if not (whole.clear and fall >= TIMING_Z**2):
        return None
    names = [n_ for n_ in first_order.shift]
    return replace(whole, shift={name: float(move[j]) for j, name in enumerate(names)})


def timing_check(match: MatchResult) -> TimingCheck | None:
    """Regress the fit's residual on its sensitivities and on ``dy_model/dt``.

    Parameters
    ----------
    match : MatchResult
        A converged fit.

    Returns
    -------
    TimingCheck or None
        None when nothing was fitted, too few samples, or the design is singular.
    """
    model = match.model
    floored = lags_at_floor(match)
    names = [
        p.name for p in model.params if match.parameters[p.name].vary and p.name not in floored
    ]
    free = [model.param_names.index(n) for n in names]
    n, k = int(match.y.size), len(free)
    if (k == 0 and not floored) or n <= k + 2:
        return None
    pvec = np.array([match.parameters[p.name].value for p in model.params], dtype=float)
    t = _row_times(match)
    starts = np.array([sl.start for sl in _run_slices(match)], dtype=int)
    y = match.data.y
    grid = _shift_grid(match, t, both=not floored)
    profile = _ShiftProfile.start(match, t, grid, k) if grid is not None else None
    # a session's trials also shifted each on its own: the response after each step late
    # while the step's jump stays (a sensor's low-pass smoothing the jumps, a misfit the
    # whole session's shift does not take)
    by_trial = match.data.slices()
    each = (
        _ShiftProfile.start(match, t, grid, k, by_trial)
        if grid is not None and len(by_trial) != len(_run_slices(match))
        else None
    )
    gram = np.zeros((k + 2, k + 2))
    with np.errstate(all="ignore"):
        blocks = match.data.packed.stream_sens(model, pvec, free, BLOCK_ROWS)
        for first, out, sens in blocks:
            stop = first + out.shape[0]
            local = starts[(starts >= first) & (starts < stop)] - first
            g = _derivative(out[:, 0], t[first:stop], np.append(local, 0).astype(int))
            r = y[first:stop] - out[:, 0]
            x = np.column_stack([sens, g, r])
            if not np.isfinite(x).all():
                return None
            gram += x.T @ x
            for prof in (profile, each):
                if prof is not None:
                    prof.add(first, stop, r, sens)
    xtx, xtr, rtr = gram[: k + 1, : k + 1], gram[: k + 1, k + 1], gram[k + 1, k + 1]
    try:
        inv = np.linalg.inv(xtx)
    except np.linalg.LinAlgError:
        return None
    coef = inv @ xtr
    rss = max(float(rtr - coef @ xtr), 0.0)
    tau = max(float(match.metrics.get("residual_tau", 1.0)), 1.0)
    s2 = rss / max(n - k - 1, 1) * tau
    phase = sampling_variance(match)
    var_d = float(inv[k, k]) * s2 + phase
    if not (np.isfinite(var_d) and var_d > 0):
        return None
    shift = {name: float(coef[j]) for j, name in enumerate(names)}
    # how far each value moves per second of the drive's timing, times the timing's
    # spread the sampling leaves: an error of every value the fit's own does not hold
    try:
        per_s = -np.linalg.solve(gram[:k, :k], gram[:k, k])
    except np.linalg.LinAlgError:
        per_s = np.zeros(k)
    held = sampling_variance(match, smooth=True)  # a smooth force's hold counts too
    phase_se = {
        name: float(abs(per_s[j]) * np.sqrt(held))
        for j, name in enumerate(names)
        if np.isfinite(per_s[j])
    }
    noise_se = float(np.sqrt(max(var_d - phase, 0.0)))
    half = float(np.sqrt(3.0 * phase))  # dt / 2 from dt^2 / 12
    check = TimingCheck(
        float(coef[k]), float(np.sqrt(var_d)), shift, (), phase_se, noise_se, half
    )
    if floored:
        check = replace(check, floor_lead_s=max(match.parameters[n].value for n in floored))
    for prof in (profile, each):
        if prof is not None and not check.clear:
            whole = _whole_shift(prof, gram, k, n, match, t, check)
            if whole is not None:
                check = whole
    if not check.clear:
        return check
    shift = check.shift
    moved = tuple(
        name
        for name in names
        if (se := match.parameters[name].stderr) is not None
        and np.isfinite(se)
        and abs(shift[name]) > SHIFT_SE * float(np.hypot(se, phase_se.get(name, 0.0)))
    )
    if check.lead_s > 0 and floored:
        # a lag on its floor reads the drive's lateness as "no lag": the lag and the
        # lateness are then read together, and no value's interval holds either
        moved = (*floored, *names)
    else:
        floored = ()
        if any(
            (se := match.parameters[name].stderr) is not None
            and np.isfinite(se)
            and se > 0
            and abs(shift[name]) > LINEAR_SE * se
            for name in names
        ):
            # one value moved that far is beyond the first order: the others' small
            # moves are no bound on theirs (a 48 ms late force at 50 Hz moved m_a 5.3
            # standard errors to first order, T_a 1.0 and A 0.4, which ended 3.6 and 2.9
            # off)
            moved = tuple(names)
    return replace(check, shift=shift, moved=moved, floored=floored)


def timing_note(check: TimingCheck) -> Note:
    """The ``fit.timing`` note of a clear lead: what it is, what it moves, what to do.

    Parameters
    ----------
    check : TimingCheck
        A clear check (:attr:`TimingCheck.clear`).

    Returns
    -------
    Note
        Severity ``error`` when it moves a parameter (those lose their trust), else
        ``warning``.
    """
    ms = check.lead_s * 1e3
    se = check.stderr_s * 1e3
    if check.lead_s > 0:
        what = (
            f"the acceleration moves {ms:.0f} ± {se:.0f} ms before the recorded force says "
            f"it should (a force channel time-stamped late: try --force-delay "
            f"{check.lead_s:.3f})"
        )
    else:
        what = (
            f"the acceleration follows the recorded force {-ms:.0f} ± {se:.0f} ms later "
            "than the model does (a dead time, a sensor's low-pass, or an "
            "accelerometer time-stamped late)"
        )
    if check.floored:
        tail = (
            f"; {', '.join(check.floored)} sits on its floor, so the fit read this lateness "
            "as no lag and every fitted value bends with it: none is trusted; refit with "
            "--force-delay, or run 'balancer-id diagnose' on the same logs"
        )
        return Note("fit.timing", what + tail, severity="error")
    if check.moved:
        tail = (
            f"; modelling it would move {', '.join(check.moved)} by more than their "
            "standard error, so those values are not trusted: run 'balancer-id diagnose' "
            "on the same logs"
        )
        return Note("fit.timing", what + tail, severity="error")
    return Note(
        "fit.timing", what + "; no fitted value moves by its standard error", severity="warning"
    )


def check_timing(match: MatchResult) -> list[Note]:
    """Run :func:`timing_check` on a fit and mark what it finds on the fit itself.

    The lead and its standard error go into ``match.metrics`` (``timing_lead_s``,
    ``timing_lead_stderr_s``); each parameter's standard error takes in the error the
    steps' places between samples leave in it (:attr:`TimingCheck.phase_se`); each
    parameter a clear lead moves gets a reason in its
    :attr:`~balancer_id.identify.matching.ParameterEstimate.distrust`.

    Parameters
    ----------
    match : MatchResult
        The fit (changed in place).

    Returns
    -------
    list of Note
        The ``fit.timing`` note of a clear lead, else nothing.
    """
    check = timing_check(match)
    if check is None:
        return []
    for name, extra in check.phase_se.items():
        est = match.parameters[name]
        if extra > 0 and est.stderr is not None and np.isfinite(est.stderr):
            est.stderr = float(np.hypot(est.stderr, extra))
            est.phase_se = float(extra)
    match.metrics["timing_lead_s"] = check.lead_s
    match.metrics["timing_lead_stderr_s"] = check.stderr_s
    if not check.clear:
        return []
    floored = check.floored
    if floored:
        match.warnings = [
            w
            for w in match.warnings
            if not (
                isinstance(w, Note) and w.code == "fit.below_resolution" and w.subject in floored
            )
        ]
    for name in check.moved:
        if name in floored:
            why = (
                f"the drive is {check.lead_s * 1e3:.0f} ms late against the acceleration: "
                "this lag's floor is the lateness read as no lag, not a measured bound"
            )
        elif floored and check.lead_s > 0:
            why = (
                f"the drive is {check.lead_s * 1e3:.0f} ms late against the acceleration "
                f"while {', '.join(floored)} sits on its floor: the lateness and the lag "
                "are read together, and this value bends with them"
            )
        else:
            why = (
                f"modelling the drive's timing ({check.lead_s * 1e3:+.0f} ms) moves it by "
                f"{abs(check.shift[name]) / (match.parameters[name].stderr or 1.0):.1f} "
                "standard errors"
            )
        match.parameters[name].distrust.append(why)
    return [timing_note(check)]
