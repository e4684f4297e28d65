"""Advice for a robot-balancer pair: settings that damp the coupled mode (paper section IV).

The coupled loop ``T_a m_a s^3 + (T_a D + m_a) s^2 + (D + c_r) s + k_r`` has one complex
pole pair, the mode a robot excites. For an identified system, :func:`advise` finds for
each of the balancer's viscosity ``D0``, the robot's damping ``c_r`` and its stiffness
``k_r`` (each changed alone) the value nearest to today's that brings the mode's damping
ratio to at least the target (0.3 by default), with the predicted frequency, damping and
stability margin; :func:`check_by_simulation` simulates the move with each setting and
measures the mode's frequency and damping in the simulated settling.

Changing one setting cannot always reach the target: the damping of the mode is bounded
by the drive lag (with ``k_r -> 0`` it tends to ``(T_a D + m_a) / (2 sqrt(T_a m_a (D +
c_r)))``, and more ``c_r`` beyond a point *lowers* it, the lag turning damping into
stiffness). Such a setting is reported as not reachable.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from balancer_id.identify.coupling import Coupling, coupling_of, delay_margin_of
from balancer_id.model.spec import Model
from balancer_id.simulation.engine import TrialInput, simulate_many
from balancer_id.simulation.inputs import Thrust

#: The damping ratio the advice aims at.
TARGET_DAMPING = 0.3
#: The settings the advice may change, and the range searched (factor of today's value).
SETTINGS = ("D0", "c_r", "k_r")
SEARCH_DECADES = 2.0
#: Settling simulated after the move's end for the check (s).
CHECK_AFTER_S = 8.0

_WHAT = {
    "D0": "balancer viscosity D0 (kg/s)",
    "c_r": "robot servo damping c_r (N s/m)",
    "k_r": "robot servo stiffness k_r (N/m)",
}


@dataclass(frozen=True)
class ModeFigures:
    """Frequency, damping ratio and stability margin of the coupled mode."""

    oscillation_hz: float
    damping_ratio: float
    stability_margin: float | None = None
    #: The largest servo delay (s) the loop stands before it goes unstable (None when not
    #: computed: a simulated mode).
    delay_margin_s: float | None = None

    def to_dict(self) -> dict[str, float | None]:
        """JSON-ready dict."""
        return {
            "oscillation_hz": self.oscillation_hz,
            "damping_ratio": self.damping_ratio,
            "stability_margin": self.stability_margin,
            "delay_margin_s": self.delay_margin_s,
        }


@dataclass
class Setting:
    """One way to reach the target: a single parameter changed.

    Attributes
    ----------
    parameter : str
        ``D0``, ``c_r`` or ``k_r``.
    current : float
        Today's value.
    advised : float or None
        The value nearest to today's that reaches the target; None when not reachable.
    predicted : ModeFigures or None
        The mode after the change, from the characteristic polynomial.
    simulated : ModeFigures or None
        The mode measured in a simulation of the move after the change.
    note : str
        Why it is not reachable, or a caveat.
    """

    parameter: str
    current: float
    advised: float | None
    predicted: ModeFigures | None
    simulated: ModeFigures | None = None
    note: str = ""
    #: False when the simulated mode contradicts the prediction (see
    #: :func:`check_by_simulation`); None before the check.
    confirmed: bool | None = None
    #: With a servo delay: the least damping ratio over the delay's interval and the
    #: interval (``{"tau_r_s": [lo, hi], "damping_ratio_min": ..}``); None without one.
    over_delay: dict[str, Any] | None = None

    @property
    def change(self) -> float | None:
        """Relative change ``advised / current - 1`` (None when not reachable)."""
        if self.advised is None or self.current == 0:
            return None
        return self.advised / self.current - 1.0

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dict."""
        return {
            "parameter": self.parameter,
            "what": _WHAT[self.parameter],
            "current": self.current,
            "advised": self.advised,
            "change_percent": None if self.change is None else 100.0 * self.change,
            "predicted": None if self.predicted is None else self.predicted.to_dict(),
            "simulated": None if self.simulated is None else self.simulated.to_dict(),
            "confirmed": self.confirmed,
            "over_delay": self.over_delay,
            "note": self.note,
        }


@dataclass
class Advice:
    """Settings that bring the coupled mode's damping ratio to the target.

    Attributes
    ----------
    target : float
        The damping ratio aimed at.
    now : ModeFigures
        The mode today.
    settings : list of Setting
        One per parameter (``D0``, ``c_r``, ``k_r``).
    viscosity_factor : float
        The effective viscosity of the settling as a share of ``D0`` used in the
        predictions (``variable_viscosity``: the servo force lowers it).
    """

    target: float
    now: ModeFigures
    settings: list[Setting] = field(default_factory=list)
    viscosity_factor: float = 1.0
    #: The servo delays (s) every setting must reach the target at (the estimate first,
    #: then its interval's ends); empty: the undelayed loop.
    delays: tuple[float, ...] = ()

    @property
    def needed(self) -> bool:
        """Whether today's damping ratio is below the target."""
        return self.now.damping_ratio < self.target

    @property
    def smallest(self) -> Setting | None:
        """The reachable setting with the smallest relative change whose prediction its
        simulation does not contradict (None if none)."""
        ok = [
            s
            for s in self.settings
            if s.advised is not None and s.current > 0 and s.confirmed is not False
        ]
        if not ok:
            return None
        return min(ok, key=lambda s: abs(np.log(s.advised / s.current)))  # type: ignore[operator]

    def to_dict(self) -> dict[str, object]:
        """The ``advice`` record of ``fit --json``."""
        best = self.smallest
        return {
            "target_damping_ratio": self.target,
            "needed": self.needed,
            "now": self.now.to_dict(),
            "settings": [s.to_dict() for s in self.settings],
            "smallest_change": None if best is None else best.parameter,
            "viscosity_factor": self.viscosity_factor,
            "servo_delay_s": list(self.delays) if self.delays else None,
        }

    def lines(self) -> list[str]:
        """The advice as short lines of text (terminal and report)."""
        return advice_lines(self.to_dict())


def _signed(value: float | None) -> str:
    """A margin with its sign, or why it has none (a servo of no stiffness: the stability
    condition's right side is 0, the margin infinite, ``null`` in the JSON)."""
    return "unbounded (no servo stiffness)" if value is None else f"{value:+.3g}"


def advice_lines(advice: Mapping[str, Any]) -> list[str]:
    """Short lines of text from an ``advice`` record (:meth:`Advice.to_dict`).

    Parameters
    ----------
    advice : mapping
        The ``advice`` object of ``fit --json``.

    Returns
    -------
    list of str
        Today's mode, then one line per setting (the smallest change marked).
    """
    now = advice["now"]
    target = advice["target_damping_ratio"]
    fac = float(advice.get("viscosity_factor", 1.0))
    seen = (
        f" (with the settling's effective viscosity, {100 * fac:.0f} % of D0: the servo "
        "force lowers the variable viscosity)"
        if fac < 0.999
        else ""
    )
    delays = advice.get("servo_delay_s") or []
    late = f" with the servo {1e3 * delays[0]:.0f} ms late," if delays and delays[0] > 0 else ""
    late_now = bool(delays) and delays[0] > 0
    margin = (
        f"unstable beyond a {1e3 * now['delay_margin_s']:.0f} ms servo delay"
        if late_now and now.get("delay_margin_s") is not None
        else f"stability margin {_signed(now.get('stability_margin'))}"
    )
    out = [
        f"coupled mode today:{late} {now['oscillation_hz']:.3g} Hz, damping ratio "
        f"{now['damping_ratio']:.3g}, {margin}{seen}"
    ]
    if not advice["needed"]:
        out.append(f"the damping ratio is already at least {target:g}: no change needed")
        return out
    out.append(f"to bring the damping ratio to {target:g}, change one of:")
    for s in advice["settings"]:
        p = s["predicted"]
        if s["advised"] is None or p is None:
            out.append(f"  {s['what']} alone: not reachable ({s['note']})")
            continue
        margin = "" if late_now else f", margin {_signed(p.get('stability_margin'))}"
        text = (
            f"  {s['what']}: {s['current']:.4g} -> {s['advised']:.4g} "
            f"({s['change_percent'] or 0.0:+.0f} %): {p['oscillation_hz']:.3g} Hz, "
            f"damping {p['damping_ratio']:.3g}{margin}"
        )
        over = s.get("over_delay")
        if over:
            lo, hi = over["tau_r_s"][0], over["tau_r_s"][-1]
            text += (
                f"; at least {over['damping_ratio_min']:.3g} for a servo delay of "
                f"{1e3 * lo:.0f} .. {1e3 * hi:.0f} ms"
            )
            alt = [z for z in over.get("also_damping_ratio") or [] if z is not None]
            if alt:
                text += f", {min(alt):.3g} with a servo acting at once"
        if p.get("delay_margin_s") is not None and np.isfinite(p["delay_margin_s"]):
            text += f"; unstable beyond a {1e3 * p['delay_margin_s']:.0f} ms servo delay"
        sim = s.get("simulated")
        if sim is not None:
            text += (
                f"; simulated: {sim['oscillation_hz']:.3g} Hz, damping {sim['damping_ratio']:.3g}"
            )
        if s.get("confirmed") is False:
            text += f"  (not confirmed: {s['note']})"
        if s["parameter"] == advice.get("smallest_change"):
            text += "  <- smallest change"
        out.append(text)
    if advice.get("smallest_change") is None:
        out.append("  no single setting reaches it: change two together, or the lag T_a")
    return out


#: A viscosity factor as a function of the candidate value of the setting searched.
FactorOf = Callable[[float], float]


def _coupling(values: Mapping[str, float], factor: float) -> Coupling:
    return coupling_of(values, viscosity_factor=factor)


def _figures(values: Mapping[str, float], factor: float = 1.0) -> ModeFigures:
    c = _coupling(values, factor)
    margin = delay_margin_of(values, factor)
    return ModeFigures(c.oscillation_hz, c.damping_ratio, c.stability_margin, margin)


def _ok(values: Mapping[str, float], target: float, factor: float = 1.0) -> bool:
    c = _coupling(values, factor)
    return c.stable and c.damping_ratio >= target


def advise_setting(
    values: Mapping[str, float],
    parameter: str,
    target: float = TARGET_DAMPING,
    bounds: tuple[float, float] | None = None,
    viscosity_factor: float | FactorOf = 1.0,
    delays: Sequence[float] = (),
    also: Sequence[Mapping[str, float]] = (),
) -> Setting:
    """The value of one parameter nearest to today's that reaches the target damping.

    A log-spaced grid over :data:`SEARCH_DECADES` decades either side of today's value
    finds the reachable values; the nearest one is then refined by bisection to the
    boundary (so the predicted damping is the target, on its reachable side).

    Parameters
    ----------
    values : mapping of str to float
        The identified parameters (``m_a``, ``T_a``, ``D0``, ``k_r``, ``c_r``).
    parameter : {"D0", "c_r", "k_r"}
        The setting to change.
    target : float
        Damping ratio to reach.
    bounds : tuple of float, optional
        The values the setting may take; None allows the whole searched range.
    viscosity_factor : float or callable
        The effective viscosity during the settling as a share of ``D0`` (1 for a
        constant viscosity; see :func:`viscosity_factor`), or a function of the
        candidate value giving it (a setting changes the settling, and so the share).
    delays : sequence of float
        The servo's delay (s): its estimate first, then the ends of its interval. The
        target must hold at every one (the loop of the late servo); empty: no delay.
    also : sequence of mapping
        Other parameter sets the data allow as well (an explanation not told apart: a
        stiffer servo acting at once); the setting, changed by the same factor, must
        reach the target on each too (at the same viscosity share).

    Returns
    -------
    Setting
        Without ``simulated`` (see :func:`check_by_simulation`); with ``over_delay``
        when ``delays`` are given.
    """
    base = {k: float(v) for k, v in values.items()}
    base.setdefault("D0", 0.0)
    base.pop("tau_r", None)
    current = float(base[parameter])
    share = viscosity_factor
    factor_of: FactorOf = share if callable(share) else (lambda _x: float(share))
    worst_first = sorted({float(d) for d in delays}, reverse=True) or [0.0]
    at = float(delays[0]) if len(delays) else 0.0

    def _alt(alt: Mapping[str, float], x: float) -> dict[str, float]:
        now = float(alt.get(parameter, current))
        scaled = now * x / current if current > 0 else x
        return {**{k: float(v) for k, v in alt.items()}, parameter: scaled}

    def _ok_at(x: float) -> bool:
        return all(
            _ok({**base, parameter: x, "tau_r": d}, target, factor_of(x)) for d in worst_first
        ) and all(_ok(_alt(alt, x), target, factor_of(x)) for alt in also)

    def _figures_at(x: float) -> ModeFigures:
        return _figures({**base, parameter: x, "tau_r": at}, factor_of(x))

    def _setting(advised: float | None, note: str = "") -> Setting:
        out = Setting(
            parameter, current, advised, None if advised is None else _figures_at(advised),
            note=note,
        )  # fmt: skip
        if len(delays) and advised is not None:
            taus = sorted({float(d) for d in delays})
            zetas = [
                _coupling({**base, parameter: advised, "tau_r": d}, factor_of(advised))
                for d in taus
            ]
            others = [_coupling(_alt(alt, advised), factor_of(advised)) for alt in also]
            out.over_delay = {
                "tau_r_s": taus,
                "damping_ratio": [c.damping_ratio if c.stable else None for c in zetas],
                "damping_ratio_min": min(
                    (c.damping_ratio if c.stable else float("-inf")) for c in zetas
                ),
                "also_damping_ratio": [c.damping_ratio if c.stable else None for c in others],
            }
        return out

    if _ok_at(current):
        return _setting(current, "already reached")
    ref = current if current > 0 else 1.0
    # the delayed loop's poles cost a root search each: a coarser grid (the boundary is
    # refined by bisection below either way)
    grid = ref * np.logspace(-SEARCH_DECADES, SEARCH_DECADES, 201 if len(delays) else 801)
    if bounds is not None:
        grid = grid[(grid >= bounds[0]) & (grid <= bounds[1])]
    ok = np.array([_ok_at(float(x)) for x in grid], dtype=bool)
    if not ok.any():
        return _setting(
            None,
            f"no value in {float(grid[0]):.3g} .. {float(grid[-1]):.3g} reaches damping "
            f"{target:g}"
            if grid.size
            else "no value allowed",
        )
    idx = np.flatnonzero(ok)
    k = int(idx[np.argmin(np.abs(np.log(grid[idx] / ref)))])
    good = float(grid[k])
    # the infeasible neighbour on the side of today's value
    j = k - 1 if good > ref else k + 1
    if 0 <= j < grid.size and not ok[j]:
        bad = float(grid[j])
        for _ in range(60):
            mid = float(np.sqrt(good * bad))
            if _ok_at(mid):
                good = mid
            else:
                bad = mid
    return _setting(good)


def advise(
    values: Mapping[str, float],
    target: float = TARGET_DAMPING,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    viscosity_factor: float = 1.0,
    along: Mapping[str, FactorOf] | None = None,
    delays: Sequence[float] = (),
    also: Sequence[Mapping[str, float]] = (),
) -> Advice:
    """Settings of ``D0``, ``c_r`` and ``k_r`` (each alone) that reach the target damping.

    Parameters
    ----------
    values : mapping of str to float
        The identified parameters (``m_a``, ``T_a``, ``D0``, ``k_r``, ``c_r``).
    target : float
        Damping ratio to reach (0.3 by default).
    bounds : mapping of str to tuple, optional
        Allowed range of each setting.
    viscosity_factor : float
        Today's effective viscosity during the settling as a share of ``D0`` (see
        :func:`viscosity_factor`); 1 predicts at ``D0`` itself.
    along : mapping of str to callable, optional
        Per setting, the share as a function of its candidate value
        (:func:`factor_along`): re-evaluated at each candidate, since a setting changes
        the settling it is measured on. A setting not named keeps today's share.
    delays : sequence of float
        A late servo's delay (s), estimate first, then its interval's ends: every
        setting must reach the target at each (see :func:`advise_setting`).
    also : sequence of mapping
        Other parameter sets the setting must reach the target on (see
        :func:`advise_setting`).

    Returns
    -------
    Advice
        Predicted figures only; :func:`check_by_simulation` adds the simulated ones.
    """
    base = dict(values)
    base.setdefault("D0", 0.0)
    base.pop("tau_r", None)
    today = float(viscosity_factor)
    per = dict(along or {})
    settings = [
        advise_setting(base, p, target, (bounds or {}).get(p), per.get(p, today), delays, also)
        for p in SETTINGS
    ]
    now = {**base, "tau_r": float(delays[0]) if len(delays) else 0.0}
    return Advice(target, _figures(now, today), settings, today, tuple(float(d) for d in delays))


def mode_from_response(
    time: np.ndarray, accel: np.ndarray, expected_hz: float | None = None
) -> ModeFigures | None:
    """Frequency and damping ratio of the oscillation in a free response.

    A third-order linear prediction ``a[n] = sum c_i a[n-i]`` (least squares, on the
    response decimated to about 20 samples per second) gives three discrete poles; the
    complex pair, mapped back with ``s = log(z) / dt``, is the mode.

    Parameters
    ----------
    time : numpy.ndarray
        Equally spaced times (s) of the free response (no input).
    accel : numpy.ndarray
        The acceleration (m/s^2).
    expected_hz : float, optional
        The frequency looked for: the decimation keeps at least 10 samples per period.

    Returns
    -------
    ModeFigures or None
        None when the response holds no oscillation, or only one near the decimated
        Nyquist frequency (an artefact of the decimation, not a mode).
    """
    dt0 = float(np.median(np.diff(time)))
    dt_wanted = 0.05
    if expected_hz is not None and expected_hz > 0:
        dt_wanted = min(dt_wanted, 0.1 / expected_hz)
    step = max(round(dt_wanted / dt0), 1)
    y = np.asarray(accel, dtype=float)[::step]
    dt = dt0 * step
    order = 3
    if y.size < 4 * order:
        return None
    X = np.column_stack([y[order - i - 1 : y.size - i - 1] for i in range(order)])
    c, *_ = np.linalg.lstsq(X, y[order:], rcond=None)
    roots = np.roots(np.concatenate([[1.0], -c]))
    s = np.log(roots.astype(complex)) / dt
    nyquist = 0.5 / dt
    pair = [p for p in s if 1e-6 < p.imag / (2 * np.pi) < 0.8 * nyquist]
    if not pair:
        return None
    p = max(pair, key=lambda q: q.real / abs(q))
    return ModeFigures(float(p.imag / (2 * np.pi)), float(-p.real / abs(p)))


def _simulate_move(model: Model, values: Mapping[str, float], move: TrialInput):
    """The move simulated to :data:`CHECK_AFTER_S` past its end: (grid, sim, t_end)."""
    t = np.asarray(move.time, dtype=float)
    if move.z_ref is None or move.v_ref is None:
        return None
    zr = np.asarray(move.z_ref, dtype=float)
    vr = np.asarray(move.v_ref, dtype=float)
    moving = np.flatnonzero((np.abs(vr) > 1e-9) | (np.abs(zr - zr[-1]) > 1e-9))
    if moving.size == 0:
        return None
    dt = float(np.median(np.diff(t)))
    t_end = float(t[moving[-1]])
    grid = np.arange(t[0], t_end + CHECK_AFTER_S, dt)
    zg = np.interp(grid, t, zr)
    vg = np.interp(grid, t, vr, right=0.0)
    if float(values.get("tau_r", 0.0)) > 0:  # a late servo: the delayed loop
        return grid, _delayed_run(model, values, grid, zg, vg), t_end
    sim = simulate_many(model, values, [TrialInput(grid, Thrust.step(grid[0], 0.0), zg, vg)])[0]
    return grid, sim, t_end


@dataclass(frozen=True)
class _Run:
    """What :func:`viscosity_factor` and :func:`simulate_mode` read of a simulation."""

    accel: np.ndarray
    velocity: np.ndarray
    operating_force: np.ndarray


def _delayed_run(
    model: Model, values: Mapping[str, float], grid: np.ndarray, zg: np.ndarray, vg: np.ndarray
) -> _Run:
    """The move simulated with the servo ``values["tau_r"]`` late."""
    from balancer_id.simulation.delayed_servo import LANE_PARAMS, simulate_delayed_servo

    full = {**model.resolve({k: v for k, v in values.items() if k in model.param_names})}
    full["tau_r"] = float(values["tau_r"])
    lane = np.array([float(full.get(n, 0.0)) for n in LANE_PARAMS])
    a, h, v = simulate_delayed_servo(grid, zg, vg, lane)
    return _Run(a[0], v[0], h[0])


def simulate_mode(
    model: Model,
    values: Mapping[str, float],
    move: TrialInput,
    expected_hz: float | None = None,
) -> ModeFigures | None:
    """Simulate the move and measure the coupled mode in the settling after it.

    Parameters
    ----------
    model : Model
        The identified model (with ``servo``).
    values : mapping of str to float
        Its parameters.
    move : TrialInput
        The move (times, thrust, reference); the simulation is extended by
        :data:`CHECK_AFTER_S` after the reference stops.
    expected_hz : float, optional
        The predicted frequency: the response is sampled fast enough for it.

    Returns
    -------
    ModeFigures or None
        From :func:`mode_from_response` on the acceleration after the move's end.
    """
    run = _simulate_move(model, values, move)
    if run is None:
        return None
    grid, sim, t_end = run
    after = grid > t_end
    settling = np.asarray(sim.accel[after], dtype=float)
    if not np.all(np.isfinite(settling)) or np.max(np.abs(settling), initial=0.0) > 1e6:
        return ModeFigures(0.0, -1.0)  # the simulated loop diverged: unstable
    return mode_from_response(grid[after], settling, expected_hz)


def viscosity_factor(model: Model, values: Mapping[str, float], move: TrialInput) -> float:
    """The settling's effective viscosity as a share of ``D0`` (``variable_viscosity``).

    With ``D(h) = D0 exp(-A |h|)`` the servo force lowers the viscosity the mode sees.
    The effective share is the dissipation-weighted mean ``sum exp(-A|h|) v^2 / sum v^2``
    over the simulated settling after the move (an equivalent linearization); 1 without
    ``A``.

    Parameters
    ----------
    model : Model
        The identified model.
    values : mapping of str to float
        Its parameters.
    move : TrialInput
        The move.

    Returns
    -------
    float
        In (0, 1]; 0 when the simulated settling diverges (an unstable loop).
    """
    A = float(values.get("A", 0.0)) if "A" in model.param_names else 0.0
    if A <= 0:
        return 1.0
    run = _simulate_move(model, values, move)
    if run is None:
        return 1.0
    grid, sim, t_end = run
    after = grid > t_end
    with np.errstate(over="ignore", invalid="ignore"):
        w = sim.velocity[after] ** 2
        share = np.sum(np.exp(-A * np.abs(sim.operating_force[after])) * w) / np.sum(w)
    if not np.isfinite(share):  # the settling diverged: the servo force left no viscosity
        return 0.0 if not np.all(np.isfinite(w)) else 1.0
    if not np.sum(w) > 0:
        return 1.0
    return float(share)


#: Candidate values at which the viscosity share is simulated per setting (interpolated
#: in between, in log of the value).
FACTOR_GRID_POINTS = 13


def factor_along(
    model: Model,
    values: Mapping[str, float],
    move: TrialInput,
    parameter: str,
    span: tuple[float, float],
) -> FactorOf:
    """The settling's viscosity share as a function of one setting's value.

    Simulated at :data:`FACTOR_GRID_POINTS` log-spaced values over ``span`` and
    interpolated in log of the value (constant beyond the ends).

    Parameters
    ----------
    model : Model
        The identified model.
    values : mapping of str to float
        Its parameters.
    move : TrialInput
        The move simulated.
    parameter : str
        The setting varied.
    span : tuple of float
        The range searched (positive).

    Returns
    -------
    callable
        ``value -> share`` in (0, 1].
    """
    lo, hi = (max(float(x), 1e-12) for x in span)
    grid = np.logspace(np.log10(lo), np.log10(max(hi, lo * 1.0001)), FACTOR_GRID_POINTS)
    shares = np.array(
        [viscosity_factor(model, {**values, parameter: float(x)}, move) for x in grid]
    )
    logs = np.log(grid)

    def share(x: float) -> float:
        return float(np.interp(np.log(max(float(x), 1e-300)), logs, shares))

    return share


def check_by_simulation(
    advice: Advice, model: Model, values: Mapping[str, float], moves: Sequence[TrialInput]
) -> Advice:
    """Fill each reachable setting's ``simulated`` figures by simulating the first move.

    Parameters
    ----------
    advice : Advice
        From :func:`advise`.
    model : Model
        The identified model.
    values : mapping of str to float
        Its parameters.
    moves : sequence of TrialInput
        The fitted moves; the first is simulated.

    Returns
    -------
    Advice
        The same object, updated.
    """
    if not moves:
        return advice
    for s in advice.settings:
        if s.advised is None:
            continue
        s.simulated = simulate_mode(
            model,
            {**values, s.parameter: s.advised},
            moves[0],
            expected_hz=s.predicted.oscillation_hz if s.predicted else None,
        )
        s.confirmed, why = _agrees(s.predicted, s.simulated, advice.target)
        if not s.confirmed:
            s.note = why
    return advice


#: A simulated frequency this far from the predicted one (relative) contradicts it.
FREQUENCY_TOLERANCE = 0.35
#: A simulated damping ratio this far below the target contradicts the prediction.
DAMPING_TOLERANCE = 0.1


def _agrees(
    predicted: ModeFigures | None, simulated: ModeFigures | None, target: float
) -> tuple[bool, str]:
    """Whether the simulated mode confirms the predicted one, and why not."""
    if predicted is None or simulated is None:
        # no oscillation left in the simulated settling: damped at least as predicted
        return True, ""
    f_p, f_s = predicted.oscillation_hz, simulated.oscillation_hz
    if f_p > 0 and abs(f_s - f_p) > FREQUENCY_TOLERANCE * f_p:
        return False, (
            f"the simulation shows a {f_s:.3g} Hz mode, the prediction {f_p:.3g} Hz: the "
            "linear prediction does not hold for this setting"
        )
    if simulated.damping_ratio < target - DAMPING_TOLERANCE:
        return False, (
            f"the simulated damping ratio is {simulated.damping_ratio:.3g}, short of "
            f"{target:g}: the linear prediction does not hold for this setting"
        )
    return True, ""


def advise_fit(
    model: Model,
    values: Mapping[str, float],
    moves: Sequence[TrialInput],
    target: float = TARGET_DAMPING,
    today: float | None = None,
    delays: Sequence[float] = (),
    also: Sequence[Mapping[str, float]] = (),
) -> Advice:
    """The whole advice for an identified robot-balancer pair, checked by simulation.

    Parameters
    ----------
    model : Model
        The identified model (with ``servo``).
    values : mapping of str to float
        Its parameters.
    moves : sequence of TrialInput
        The fitted moves (the first is simulated for the checks and the viscosity factor).
    target : float
        Damping ratio to reach.
    today : float, optional
        Today's viscosity share when already known (the fit's coupling has it); None
        simulates it (:func:`viscosity_factor`).
    delays : sequence of float
        A late servo's delay (s): the estimate, then its interval's ends. The settings
        are predicted on the delayed loop, must reach the target at every delay given,
        and are simulated with the estimate (:mod:`~balancer_id.simulation.delayed_servo`).
    also : sequence of mapping
        Other parameter sets the data allow (see :func:`advise_setting`).

    Returns
    -------
    Advice
        Settings within the model's parameter bounds, predicted with the settling's
        effective viscosity (:func:`viscosity_factor`) and checked by simulation.
    """
    values = {k: float(v) for k, v in values.items() if k != "tau_r"}
    if len(delays) and float(delays[0]) > 0:
        values["tau_r"] = float(delays[0])
    bounds = {p.name: (p.min, p.max) for p in model.params if p.name in SETTINGS}
    if today is None:
        today = viscosity_factor(model, values, moves[0]) if moves else 1.0
    shares: dict[str, FactorOf] = {}
    if moves and "A" in model.param_names and float(values.get("A", 0.0)) > 0:
        for name in SETTINGS:
            now = float(values.get(name, 0.0))
            ref = now if now > 0 else 1.0
            lo, hi = ref * 10**-SEARCH_DECADES, ref * 10**SEARCH_DECADES
            if name in bounds:
                lo, hi = max(lo, bounds[name][0]), min(hi, bounds[name][1])
            if hi > lo > 0:
                shares[name] = factor_along(model, values, moves[0], name, (lo, hi))
    advice = advise(
        values, target, bounds, viscosity_factor=today, along=shares, delays=delays, also=also
    )
    return check_by_simulation(advice, model, values, moves)
