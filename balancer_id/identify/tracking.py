"""Parameters that move within a session: tracked in time (``fit --track``, issue 33).

Two stages (docs/DECISIONS.md, "Tracking a parameter in time"):

1. Local estimates. The session's trials are cut into short blocks (one trial; two or
   more consecutive trials where a tracked parameter is only identifiable from two thrust
   levels, such as ``A``). Each block is fitted alone with the tracked parameters free and
   every other parameter held at the joint fit's value; each block starts from the state
   the joint model reaches there (:func:`~balancer_id.identify.per_trial.detach_sessions`).
2. A random walk through them. Each tracked parameter is a random walk in time observed
   through its local estimates; the walk's variance and a scale on the local standard
   errors are chosen by likelihood, then the Kalman filter and RTS smoother give the
   parameter at every block with a 95 % band
   (:func:`~balancer_id.identify.random_walk.smooth_walk`). A walk of variance 0 is a
   constant parameter; the likelihood ratio against it says whether the parameter moves.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from balancer_id.errors import IdentificationError, UsageError
from balancer_id.identify.data import TrialData
from balancer_id.identify.random_walk import WalkFit, smooth_walk
from balancer_id.model.spec import Model
from balancer_id.notes import Note

#: A walk is called moving when "constant" is rejected at this level: 0.1 %, not 5 %, as
#: the blocks' errors are correlated from one block to the next through the state each
#: starts from (lag-one correlation 0.2-0.4 in the controls called moving), which the
#: test's independence does not count; measured on controls (docs/DECISIONS.md).
MOVING_P_VALUE = 0.001
#: ... and its largest change is at least this share of its mean value: the chained
#: states alone made controls wander by 0.5-1.5 % (docs/DECISIONS.md), and a change
#: below the fit's own tolerances (m_a 2 %) is no finding.
MIN_RELATIVE_CHANGE = 0.02
#: Fewest local estimates a walk is fitted to.
MIN_BLOCKS = 4
#: Most fits of the blocks, each from the states the previous one's values give (the
#: session's state at a block's start depends on the values before it): they stop when
#: no tracked value moves by more than :data:`PASS_STOP` of its standard error.
PASSES = 6
PASS_STOP = 0.1
Z95 = 1.959963984540054


@dataclass
class LocalEstimate:
    """One block's fit of the tracked parameters (the others held)."""

    time_s: float
    t_start_s: float
    t_end_s: float
    trials: list[int]
    values: dict[str, float]
    stderr: dict[str, float | None]
    #: Per parameter, the time its estimate stands for (information-weighted).
    times: dict[str, float] = field(default_factory=dict)
    #: Per parameter, the standard error given the shared parameters (independent from
    #: block to block; the rest of ``stderr`` is common to all blocks).
    given_shared: dict[str, float | None] = field(default_factory=dict)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "time_s": self.time_s,
            "times_s": self.times,
            "t_start_s": self.t_start_s,
            "t_end_s": self.t_end_s,
            "trials": self.trials,
            "values": self.values,
            "stderr": self.stderr,
        }


@dataclass
class ParameterTrack:
    """One parameter as a function of time within the session.

    Attributes
    ----------
    name, unit : str
        The parameter and its unit.
    time_s : numpy.ndarray
        The blocks' times (s from the session's start; runs laid end to end).
    local, local_stderr : numpy.ndarray
        The local estimates and their standard errors.
    walk : WalkFit
        The smoothed walk (``walk.value`` and ``walk.variance`` at ``time_s``).
    joint : float
        The joint fit's constant value.
    common_variance : numpy.ndarray, optional
        The part of each local estimate's variance common to all blocks (through the
        shared parameters' error): the walk smooths the independent part; this is added
        to the band (it does not shrink with more blocks).
    """

    name: str
    unit: str
    time_s: np.ndarray
    local: np.ndarray
    local_stderr: np.ndarray
    walk: WalkFit
    joint: float
    common_variance: np.ndarray | None = None

    @property
    def value(self) -> np.ndarray:
        """Smoothed value at each time."""
        return self.walk.value

    @property
    def stderr(self) -> np.ndarray:
        """Its standard error (the walk's, and the part common to all blocks)."""
        common = 0.0 if self.common_variance is None else self.common_variance * self.walk.scale
        return np.sqrt(self.walk.variance + common)

    @property
    def lo(self) -> np.ndarray:
        """Lower end of the 95 % band."""
        return self.value - Z95 * self.stderr

    @property
    def hi(self) -> np.ndarray:
        """Upper end of the 95 % band."""
        return self.value + Z95 * self.stderr

    @property
    def relative_change(self) -> float:
        """The largest change over the mean value's magnitude (inf for a mean of 0)."""
        big = abs(float(self.largest_change()["change"]))  # type: ignore[arg-type]
        scale = abs(float(np.mean(self.value)))
        return big / scale if scale > 0 else (float("inf") if big > 0 else 0.0)

    @property
    def moving(self) -> bool:
        """The data reject a constant parameter (p < :data:`MOVING_P_VALUE`) and its
        largest change is at least :data:`MIN_RELATIVE_CHANGE` of its value."""
        return self.walk.p_value < MOVING_P_VALUE and self.relative_change >= MIN_RELATIVE_CHANGE

    def _point(self, k: int) -> dict[str, object]:
        return {
            "time_s": float(self.time_s[k]),
            "value": float(self.value[k]),
            "ci95": [float(self.lo[k]), float(self.hi[k])],
        }

    def change(self, i: int, j: int) -> dict[str, object]:
        """The change between two times with its 95 % interval.

        Parameters
        ----------
        i, j : int
            Positions in :attr:`time_s` (from, to).

        Returns
        -------
        dict
            ``from_s``, ``to_s``, ``change`` and ``ci95``.
        """
        d = float(self.value[j] - self.value[i])
        var = self.walk.variance[i] + self.walk.variance[j] - 2 * self.walk.covariance(i, j)
        sd = float(np.sqrt(max(var, 0.0)))
        return {
            "from_s": float(self.time_s[i]),
            "to_s": float(self.time_s[j]),
            "change": d,
            "ci95": [d - Z95 * sd, d + Z95 * sd],
        }

    def largest_change(self) -> dict[str, object]:
        """The largest change of the smoothed curve between two times (earlier to later)."""
        v = self.value
        best, pair = -1.0, (0, 0)
        low_k = high_k = 0
        for k in range(v.size):
            if v[k] - v[low_k] > best:
                best, pair = v[k] - v[low_k], (low_k, k)
            if v[high_k] - v[k] > best:
                best, pair = v[high_k] - v[k], (high_k, k)
            if v[k] < v[low_k]:
                low_k = k
            if v[k] > v[high_k]:
                high_k = k
        return self.change(*pair)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict (the CONTRACT.md ``tracking`` entry)."""
        last = self.time_s.size - 1
        return {
            "unit": self.unit,
            "moving": self.moving,
            "p_value_constant": self.walk.p_value,
            "relative_change": self.relative_change,
            "likelihood_ratio": self.walk.lr,
            "path_model": self.walk.kind,
            "walk_variance": self.walk.ratio * self.walk.scale,
            "stderr_scale": float(np.sqrt(self.walk.scale)),
            "joint_value": self.joint,
            "start": self._point(0),
            "end": self._point(last),
            "end_minus_start": self.change(0, last),
            "largest_change": self.largest_change(),
            "series": {
                "time_s": self.time_s.tolist(),
                "value": self.value.tolist(),
                "ci95_low": self.lo.tolist(),
                "ci95_high": self.hi.tolist(),
                "local": self.local.tolist(),
                "local_stderr": self.local_stderr.tolist(),
            },
        }


@dataclass
class Tracking:
    """The tracked parameters of one fit (``FitResult.tracking``)."""

    tracks: dict[str, ParameterTrack]
    blocks: list[LocalEstimate]
    notes: list[Note] = field(default_factory=list)
    #: The other parameters, refitted with the tracked ones moving.
    shared: dict[str, float] = field(default_factory=dict)
    method: str = "random-walk Kalman/RTS smoother over per-block fits"

    @property
    def moving(self) -> list[str]:
        """The tracked parameters the data say move."""
        return [n for n, t in self.tracks.items() if t.moving]

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "method": self.method,
            "parameters": {n: t.to_dict() for n, t in self.tracks.items()},
            "moving": self.moving,
            "blocks": len(self.blocks),
            "shared": self.shared,
            "notes": [n.text for n in self.notes],
        }

    def to_frame(self):
        """One row per block and parameter: time, value, band, local estimate (``--series``).

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        rows = []
        for name, t in self.tracks.items():
            for k in range(t.time_s.size):
                rows.append(
                    {
                        "parameter": name,
                        "time_s": t.time_s[k],
                        "value": t.value[k],
                        "ci95_low": t.lo[k],
                        "ci95_high": t.hi[k],
                        "local": t.local[k],
                        "local_stderr": t.local_stderr[k],
                    }
                )
        return pd.DataFrame(rows)

    def plot(self, path=None):
        """Each tracked parameter against time with its band
        (:func:`~balancer_id.identify.tracking_plot.plot_tracking`).

        Parameters
        ----------
        path : str or Path, optional
            Write a PNG here instead of returning the figure.

        Returns
        -------
        matplotlib.figure.Figure or Path
        """
        from balancer_id.identify.tracking_plot import plot_tracking

        return plot_tracking(self, path)

    def _repr_html_(self) -> str:
        import html

        return "<pre>" + html.escape("\n".join(self.lines())) + "</pre>"

    def __repr__(self) -> str:
        return "\n".join(self.lines())

    def lines(self) -> list[str]:
        """The terminal's and notebook's text (:func:`tracking_lines`)."""
        return tracking_lines(self.to_dict())


def tracking_lines(tracking: Mapping[str, object]) -> list[str]:
    """Per tracked parameter: whether it moves, its start and end, its largest change.

    Parameters
    ----------
    tracking : mapping
        The ``tracking`` object of a fit's JSON (:meth:`Tracking.to_dict`).

    Returns
    -------
    list of str
    """
    out = ["tracked in time (per-block fits, Kalman/RTS smoother; 95 % intervals):"]
    params = tracking.get("parameters", {})
    assert isinstance(params, Mapping)
    for name, d in params.items():
        path = "smooth drift" if d.get("path_model") == "trend" else "random walk"
        if d["moving"]:
            verdict = f"moves ({path}; a constant is rejected, p = {d['p_value_constant']:.2g})"
        elif d["p_value_constant"] < MOVING_P_VALUE:
            verdict = (
                f"no movement worth reporting (a change of {d['relative_change']:.1%}, below "
                f"{MIN_RELATIVE_CHANGE:.0%}; p = {d['p_value_constant']:.2g} for a constant)"
            )
        else:
            verdict = f"no movement found (p = {d['p_value_constant']:.2g} for a constant)"
        big = d["largest_change"]
        change = (
            f"largest change {_change(big)}"
            if big["from_s"] != big["to_s"]
            else "the curve is flat (one value fits the session)"
        )
        out.append(
            f"  {name} [{d['unit']}]: {verdict}; start {_at(d['start'])}, end {_at(d['end'])}; "
            + change
        )
    notes = tracking.get("notes", [])
    assert isinstance(notes, list)
    out += [f"  note: {n}" for n in notes]
    return out


def _interval(value: object) -> tuple[float, float]:
    """An interval ``[lo, hi]`` of the JSON as two floats."""
    assert isinstance(value, list | tuple) and len(value) == 2
    return float(value[0]), float(value[1])


def _at(p: Mapping[str, object]) -> str:
    lo, hi = _interval(p["ci95"])
    return f"{p['value']:.4g} ({lo:.4g} .. {hi:.4g}) at {p['time_s']:.0f} s"


def _change(c: Mapping[str, object]) -> str:
    lo, hi = _interval(c["ci95"])
    return (
        f"{c['change']:+.4g} ({lo:+.4g} .. {hi:+.4g}) "
        f"from {c['from_s']:.0f} s to {c['to_s']:.0f} s"
    )


def session_times(trials: Sequence[TrialData]) -> np.ndarray:
    """Each trial's middle time on one clock: the runs laid end to end in order.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials, in order.

    Returns
    -------
    numpy.ndarray
        Seconds from the first run's start.
    """
    return np.array([
        (float(np.mean(td.time)) if td.time.size else td.t_step) + off
        for td, off in zip(trials, session_offsets(trials), strict=True)
    ])


def session_offsets(trials: Sequence[TrialData]) -> np.ndarray:
    """What each trial's own clock adds to reach the session's: 0 in the first run, the
    later runs laid end to end after it.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials, in order.

    Returns
    -------
    numpy.ndarray
        Seconds, one per trial.
    """
    out = []
    offset, last_end, source = 0.0, 0.0, None
    for td in trials:
        t = td.time
        if td.source != source:
            if source is not None:
                offset = last_end - (float(t[0]) if t.size else 0.0)
            source = td.source
        out.append(offset)
        last_end = (float(t[-1]) if t.size else td.t_step) + offset
    return np.asarray(out)


def make_blocks(
    model: Model,
    trials: Sequence[TrialData],
    names: Sequence[str],
    fixed: Mapping[str, float] | None = None,
) -> list[list[int]]:
    """Consecutive trials fitted together: one each, or as few as give two thrust levels
    when a tracked parameter is one only two levels pin (``A``) or belongs to an effect
    with a fitted one (``D0`` beside ``A``): a block at one level sees the viscosity at
    that level only, which a tracked ``D0`` and a shared ``A`` would trade freely.

    Parameters
    ----------
    model : Model
        The model.
    trials : sequence of TrialData
        The trials, in order.
    names : sequence of str
        The tracked parameters.
    fixed : mapping of str to float, optional
        Held parameters.

    Returns
    -------
    list of list of int
        Positions in ``trials``.
    """
    held = dict(fixed or {})
    levelled = {n for n in model.thrust_level_names if n in model.param_names and n not in held}
    needs_levels = False
    for effect in model.all_effects:
        own = {p.name for p in effect.parameters}
        if own & levelled and own & set(names):
            needs_levels = True
    blocks: list[list[int]] = []
    current: list[int] = []
    for k in range(len(trials)):
        current.append(k)
        if not needs_levels:
            blocks.append(current)
            current = []
            continue
        mags = {round(abs(trials[j].thrust_N), 1) for j in current}
        if len(_levels(mags)) >= 2:
            blocks.append(current)
            current = []
    if current:
        if blocks:
            blocks[-1].extend(current)
        else:
            blocks.append(current)
    return blocks


def _levels(mags: set[float], rel_tol: float = 0.1) -> list[float]:
    out: list[float] = []
    for m in sorted(mags):
        if not out or m > out[-1] * (1 + rel_tol):
            out.append(m)
    return out


def check_tracked(model: Model, names: Sequence[str], fixed: Mapping[str, float]) -> list[str]:
    """The tracked names, checked: parameters of the model, not held.

    Parameters
    ----------
    model : Model
        The model.
    names : sequence of str
        The names given (``--track``).
    fixed : mapping of str to float
        The held parameters.

    Returns
    -------
    list of str
        The names, each once.

    Raises
    ------
    UsageError
        A name that is not a parameter of the model, or one held with ``--fix``.
    """
    out = []
    for name in names:
        if name not in model.param_names:
            raise UsageError(
                f"--track {name}: not a parameter of '{model.spec}' "
                f"(its parameters: {', '.join(model.param_names)})"
            )
        if name in fixed:
            raise UsageError(f"--track {name}: it is held with --fix; track a fitted parameter")
        if name not in out:
            out.append(name)
    return out


def chain_states(
    model: Model, trials: Sequence[TrialData], values: Sequence[Mapping[str, float]]
) -> list[TrialData]:
    """The trials, each that continues a session made to start on its own, from the state
    the model reaches with each trial's own ``values`` (the session simulated trial by
    trial, the state carried across).

    Parameters
    ----------
    model : Model
        The model.
    trials : sequence of TrialData
        The trials, in order.
    values : sequence of mapping
        Every parameter's value during each trial.

    Returns
    -------
    list of TrialData
    """
    from dataclasses import replace

    from balancer_id.simulation.engine import simulate

    out: list[TrialData] = []
    state: tuple[float, float, float] | None = None
    for k, td in enumerate(trials):
        if td.continues and state is not None:
            td = replace(td, continues=False, previous=None, input=replace(td.input, x0=state))
        out.append(td)
        nxt = trials[k + 1] if k + 1 < len(trials) else None
        if nxt is None or not nxt.continues or not td.time.size:
            state = None
            continue
        t = np.append(td.input.time, nxt.input.time[0])
        inp = td.input
        sim = simulate(model, dict(values[k]), t, inp.thrust, x0=inp.x0,
                       z_ref=None if inp.z_ref is None else np.append(inp.z_ref, inp.z_ref[-1]),
                       v_ref=None if inp.v_ref is None else np.append(inp.v_ref, inp.v_ref[-1]))
        end = (float(sim.drive_force[-1]), float(sim.velocity[-1]), float(sim.position[-1]))
        state = end if np.isfinite(end).all() else None
    return out


def track_parameters(
    model: Model,
    trials: Sequence[TrialData],
    names: Sequence[str],
    values: Mapping[str, float],
    fixed: Mapping[str, float] | None = None,
) -> Tracking:
    """Track parameters in time within the session (see the module's docstring).

    Parameters
    ----------
    model : Model
        The fitted model.
    trials : sequence of TrialData
        The fitted trials, in order.
    names : sequence of str
        The parameters to track (free in the joint fit).
    values : mapping of str to float
        The joint fit's values (the starts).
    fixed : mapping of str to float, optional
        Values the user held (never tracked).

    Returns
    -------
    Tracking

    Raises
    ------
    UsageError
        A name that is not a free parameter of the model.
    IdentificationError
        Fewer than 4 blocks pin a tracked parameter.
    """
    from balancer_id.identify.grouped import fit_grouped

    fixed = dict(fixed or {})
    names = check_tracked(model, names, fixed)
    trials = list(trials)
    times = session_times(trials)
    blocks = make_blocks(model, trials, names, fixed)
    per_trial = [dict(values)] * len(trials)
    own_start = None
    fit = None
    for _ in range(PASSES):  # states from the joint values, then from the tracked ones
        previous: Any = fit
        chained = chain_states(model, trials, per_trial)
        fit = fit_grouped(
            model,
            [[chained[k] for k in b] for b in blocks],
            names,
            start=values,
            own_start=own_start,
            fixed=fixed,
            robust_shared=True,
        )
        own_start = [{n: p.value for n, p in own.items()} for own in fit.own]
        per_trial = [{}] * len(trials)
        for b, g in zip(blocks, range(len(blocks)), strict=True):
            for k in b:
                per_trial[k] = fit.values(g)
        if previous is not None and _settled(previous, fit, names):
            break
    assert fit is not None
    offsets_s = session_offsets(trials)
    estimates: list[LocalEstimate] = []
    for g, b in enumerate(blocks):
        group = [trials[k] for k in b]
        off = float(offsets_s[b[0]])
        t0 = float(group[0].time[0]) if group[0].time.size else 0.0
        t1 = float(group[-1].time[-1]) if group[-1].time.size else 0.0
        estimates.append(
            LocalEstimate(
                time_s=float(np.mean(times[b])),
                t_start_s=t0 + off,
                t_end_s=t1 + off,
                trials=[trials[k].index for k in b],
                values={n: fit.own[g][n].value for n in names},
                stderr={n: _usable(fit.own[g][n]) for n in names},
                given_shared={n: fit.own_given_shared[g][n] for n in names},
                times={n: fit.own_time[g][n] + off for n in names},
            )
        )
    tracks, notes = _tracks(model, names, estimates, values)
    shared = {n: p.value for n, p in fit.shared.items() if n not in names}
    if fit.within and any(len(b) > 1 for b in blocks):
        # a parameter moving within a block of several trials: the block's one value and
        # the shared ones took up the change between its trials; with each trial's offset
        # from the smoothed path in the model, the estimates are corrected and smoothed
        # again (docs/DECISIONS.md, "Within a block")
        own_names = list(fit.own[0])
        moved_shared: dict[str, float] = {}
        for _ in range(WITHIN_PASSES):
            offsets = []
            for g, b in enumerate(blocks):
                off = float(offsets_s[b[0]])
                w = fit.within[g]
                d = np.zeros_like(w.times)
                for j, name in enumerate(own_names):
                    tr = tracks[name]
                    at = _path(w.times[:, j] + off, tr.time_s, tr.value)
                    d[:, j] = at - _path(np.array([fit.own_time[g][name] + off]),
                                         tr.time_s, tr.value)[0]
                offsets.append(d)
            moved_shared, moved_own = fit.moved_within(offsets)
            estimates = [
                replace(e, values={n: moved_own[g][n] for n in names})
                for g, e in enumerate(estimates)
            ]
            tracks, notes = _tracks(model, names, estimates, values)
        shared.update({n: v for n, v in moved_shared.items() if n not in names})
    return Tracking(tracks=tracks, blocks=estimates, notes=notes, shared=shared)


#: Corrections for a parameter moving within a block (each from the path the last gave).
WITHIN_PASSES = 2


def _path(t: np.ndarray, time_s: np.ndarray, value: np.ndarray) -> np.ndarray:
    """The smoothed path at times ``t``: linear between its points, and beyond its ends
    along its first and last segments."""
    out = np.interp(t, time_s, value)
    if time_s.size >= 2:
        lo, hi = t < time_s[0], t > time_s[-1]
        s0 = (value[1] - value[0]) / max(time_s[1] - time_s[0], 1e-12)
        s1 = (value[-1] - value[-2]) / max(time_s[-1] - time_s[-2], 1e-12)
        out = np.where(lo, value[0] + s0 * (t - time_s[0]), out)
        out = np.where(hi, value[-1] + s1 * (t - time_s[-1]), out)
    return out


def _tracks(
    model: Model,
    names: Sequence[str],
    estimates: Sequence[LocalEstimate],
    values: Mapping[str, float],
) -> tuple[dict[str, ParameterTrack], list[Note]]:
    """Each tracked parameter smoothed through the blocks' estimates, and the notes."""
    notes: list[Note] = []
    tracks: dict[str, ParameterTrack] = {}
    for name in names:
        ok = [b for b in estimates if b.stderr[name] is not None]
        if len(ok) < MIN_BLOCKS:
            raise IdentificationError(
                f"--track {name}: only {len(ok)} block(s) of trials pin {name} alone; "
                f"tracking needs at least {MIN_BLOCKS} (a longer session, or more steps)"
            )
        if len(ok) < len(estimates):
            notes.append(
                Note(
                    "fit.other",
                    f"{name}: {len(estimates) - len(ok)} block(s) gave no standard error "
                    "(at a bound); left out of its track",
                    subject=name,
                    severity="info",
                )
            )
        t = np.array([b.times.get(name, b.time_s) for b in ok])
        order = np.argsort(t, kind="stable")
        ok = [ok[k] for k in order]
        t = t[order]
        y = np.array([b.values[name] for b in ok])
        se = np.array([b.stderr[name] for b in ok], dtype=float)
        own = np.array([b.given_shared.get(name) or b.stderr[name] for b in ok], dtype=float)
        own = np.minimum(own, se)
        tracks[name] = ParameterTrack(
            name=name,
            unit=model.param(name).unit,
            time_s=t,
            local=y,
            local_stderr=se,
            walk=smooth_walk(t, y, own),
            common_variance=se**2 - own**2,
            joint=float(values[name]),
        )
    return tracks, notes


def _settled(before, after, names: Sequence[str]) -> bool:
    """No tracked value moved by more than PASS_STOP of its standard error."""
    for old, new in zip(before.own, after.own, strict=True):
        for n in names:
            se = new[n].stderr
            if se is None or not np.isfinite(se) or se <= 0:
                continue
            if abs(new[n].value - old[n].value) > PASS_STOP * se:
                return False
    return True


def _usable(p) -> float | None:
    """A local standard error that can weigh an estimate (finite, positive, not at a bound)."""
    se = p.stderr
    if se is None or not np.isfinite(se) or se <= 0 or p.at_bound:
        return None
    return float(se)
