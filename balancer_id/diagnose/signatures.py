"""How each missing effect shows in the residual (MODEL.md, "Residual signatures").

A check looks at a :class:`~balancer_id.diagnose.context.DiagnosisContext` and returns a
:class:`Signature`: a strength in [0, 1], the evidence in numbers and words, and start
values for the quick refit. Built-in checks are listed in :data:`SIGNATURES`; a user
effect contributes its own by defining ``signature(ctx)`` as a classmethod, and any
effect without one is judged by the refit alone (with the residual's correlation with
the states as evidence).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from balancer_id.diagnose.context import DiagnosisContext
from balancer_id.diagnose.residual_tests import input_correlation, state_correlations


@dataclass
class Signature:
    """The evidence one effect's check found."""

    strength: float
    evidence: str
    start: dict[str, float] = field(default_factory=dict)


def _t_stat(x: np.ndarray, sigma: float) -> float:
    return float(np.mean(x) / (sigma / np.sqrt(max(x.size, 1)))) if x.size else 0.0


def _clip01(x: float) -> float:
    return float(min(max(x, 0.0), 1.0))


def check_bias(ctx: DiagnosisContext) -> Signature:
    """Residual mean at rest differs from zero, with the same sign in every trial.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature
        Strength in [0, 1], the evidence in words and numbers, and the start value of
        ``b``: the mean residual at rest (m/s^2).
    """
    rest = [tv.residual[tv.regimes["rest"]] for tv in ctx.trials]
    rest = [r for r in rest if r.size >= 5]
    if not rest:
        return Signature(0.0, "no resting samples before the onsets to test an offset")
    allr = np.concatenate(rest)
    t = _t_stat(allr, ctx.noise_floor)
    means = np.array([np.mean(r) for r in rest])
    same_sign = float(np.mean(np.sign(means) == np.sign(np.mean(allr))))
    motion = np.concatenate([tv.residual[tv.t >= 0] for tv in ctx.trials])
    return Signature(
        _clip01((abs(t) - 3) / 10) * same_sign,
        f"residual mean at rest {np.mean(allr):+.4f} m/s^2 (t = {t:+.1f}, same sign in "
        f"{same_sign:.0%} of trials), during motion {np.mean(motion):+.4f} m/s^2",
        {"b": float(np.mean(allr))},
    )


def check_karnopp(ctx: DiagnosisContext) -> Signature:
    """A residual opposing the motion in steady motion, and a thrust that moves nothing.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature
        Strength in [0, 1], the evidence in words and numbers, and the start value of
        ``f_s``: the friction force the residual implies (N, at most 20).
    """
    parts, thrust, accel, accel_model = [], [], [], []
    for tv in ctx.trials:
        m = tv.regimes["steady"]
        if m.sum() >= 10:
            parts.append(tv.residual[m] * np.sign(tv.v[m]))
        late = (tv.t > 0.6) & (tv.t < 1.6)
        if late.sum() >= 10:
            thrust.append(abs(tv.data.thrust_N))
            accel.append(abs(np.mean(tv.y[late])))
            accel_model.append(abs(np.mean(tv.y_model[late])))
    if not parts:
        return Signature(0.0, "no steady motion to test friction")
    r = np.concatenate(parts)
    t = _t_stat(r, ctx.noise_floor)
    # The free line |f_in| = m |a| + c of the measurement, against the same line of the
    # model's own response (viscosity bends it too): friction adds c = f_s.
    intercept, z_c = 0.0, 0.0
    if len(thrust) >= 3 and np.ptp(accel) > 0 and np.ptp(accel_model) > 0:
        coef, cov = np.polyfit(accel, thrust, 1, cov=True)
        model_coef = np.polyfit(accel_model, thrust, 1)
        intercept = float(coef[1] - model_coef[1])
        z_c = intercept / np.sqrt(cov[1, 1]) if cov[1, 1] > 0 else 0.0
    m_a = ctx.match.values().get("m_a", 15.0)
    f_s = max(-np.mean(r) * m_a, intercept, 0.05)
    still = [
        tv
        for tv in ctx.trials
        if abs(np.mean(tv.y[tv.t > 0.5])) < 2 * ctx.noise_floor / np.sqrt((tv.t > 0.5).sum())
    ]
    return Signature(
        max(_clip01((-t - 3) / 10), _clip01((z_c - 3) / 10)),
        f"steady-motion residual {np.mean(r):+.4f} m/s^2 along the motion (t = {t:+.1f}); "
        f"a free line |f_in| = m|a| + c has c = {intercept:+.2f} N more than the model's"
        + (f"; {len(still)} trial(s) show no motion after the step" if still else ""),
        {"f_s": float(min(f_s, 20.0))},
    )


def check_speed_limit(ctx: DiagnosisContext) -> Signature:
    """The measured speed plateaus at one value across trials while the model speeds on.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature
        Strength in [0, 1], the evidence in words and numbers, and the start value of
        ``v_max``: the measured plateau speed (m/s), or above the model's top speed
        when there is no plateau.
    """
    plateaus, gaps = [], []
    for tv in ctx.trials:
        m = tv.t >= 0
        if m.sum() < 20:
            continue
        v_meas = np.concatenate(
            [[0.0], np.cumsum(0.5 * (tv.y[m][1:] + tv.y[m][:-1]) * np.diff(tv.t[m]))]
        )
        v_peak = float(np.max(np.abs(v_meas)))
        v_model = float(np.max(np.abs(tv.v[m])))
        late = tv.t > tv.t[-1] - 1.0
        if v_model > 1.05 * v_peak and v_peak > 0.05:
            plateaus.append(v_peak)
            gaps.append(float(np.sqrt(np.mean(tv.residual[late] ** 2))) / ctx.noise_floor)
    v_top = max(float(np.max(np.abs(tv.v))) for tv in ctx.trials)
    if len(plateaus) < 2:
        return Signature(
            0.0,
            "no trial where the model outruns the measured speed",
            {"v_max": float(np.clip(1.2 * v_top, 0.02, 4.9))},
        )
    spread = float(np.std(plateaus) / np.mean(plateaus))
    agree = _clip01((0.25 - spread) / 0.2)
    return Signature(
        agree * _clip01((np.mean(gaps) - 1.2) / 2),
        f"measured speed plateaus at {np.mean(plateaus):.3f} m/s (spread {spread:.0%}) in "
        f"{len(plateaus)} trials while the model speeds on; "
        f"late residual {np.mean(gaps):.1f}x noise",
        {"v_max": float(np.clip(np.median(plateaus), 0.02, 4.9))},
    )


def check_dead_time(ctx: DiagnosisContext) -> Signature:
    """The model leads the measurement just after the onset (input cross-correlation).

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature
        Strength in [0, 1], the evidence in words and numbers, and the start value of
        ``tau_d``: the median lag of the measurement behind the model (s).
    """
    shifts = []
    for tv in ctx.trials:
        m = (tv.t > -0.2) & (tv.t < 1.0)
        if m.sum() < 30:
            continue
        y, ym = tv.y[m], tv.y_model[m]
        best, best_err = 0, np.inf
        for k in range(0, int(0.3 / ctx.dt)):
            err = np.mean((y[k:] - ym[: ym.size - k]) ** 2)
            if err < best_err:
                best, best_err = k, err
        shifts.append(best * ctx.dt)
    xc = input_correlation(ctx, max_lag_s=1.0)
    tau = float(np.median(shifts)) if shifts else 0.0
    lead = xc["significant"] and xc["peak_value"] < 0 and 0 <= xc["peak_lag_s"] < 1.0
    return Signature(
        _clip01(tau / (3 * ctx.dt) - 0.5) * (1.0 if lead else 0.5),
        f"the measured response lags the model by {tau * 1e3:.0f} ms (median over trials); "
        f"mean residual against the thrust peaks at {xc['peak_value']:+.4f} m/s^2, "
        f"{xc['peak_lag_s']:.2f} s after the onset",
        {"tau_d": float(np.clip(tau, 0.0, 0.9))},
    )


def check_asymmetric_lag(ctx: DiagnosisContext) -> Signature:
    """The rise is too fast one way and too slow the other.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature
        Strength in [0, 1], the evidence in words and numbers, and the start values of
        ``T_up`` and ``T_down``: the current ``T_a`` (s).
    """
    by_dir: dict[str, list[float]] = {"up": [], "down": []}
    for tv in ctx.trials:
        m = tv.regimes["rise"]
        if m.sum() >= 5:
            by_dir[tv.data.direction].append(
                float(np.mean(tv.residual[m]) * np.sign(tv.data.thrust_N))
            )
    if not by_dir["up"] or not by_dir["down"]:
        return Signature(0.0, "needs trials in both directions")
    up, down = np.mean(by_dir["up"]), np.mean(by_dir["down"])
    n = len(by_dir["up"]) + len(by_dir["down"])
    sigma = ctx.noise_floor / np.sqrt(max(30 * n / 2, 1))
    contrast = abs(up - down) / sigma
    opposite = np.sign(up) != np.sign(down)
    T = ctx.match.values().get("T_a", 0.3)
    return Signature(
        _clip01((contrast - 3) / 10) * (1.0 if opposite else 0.3),
        f"during the rise the residual (along the thrust) is {up:+.4f} m/s^2 going up and "
        f"{down:+.4f} m/s^2 going down",
        {"T_up": T, "T_down": T},
    )


def check_variable_viscosity(ctx: DiagnosisContext) -> Signature:
    """The decay rate depends on the thrust: a constant viscosity over- or under-damps.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature
        Strength in [0, 1], the evidence in words and numbers, and the start value
        ``A = 0.2``.
    """
    rows = []
    for tv in ctx.trials:
        m = tv.regimes["steady"]
        if m.sum() >= 20:
            rows.append((abs(tv.data.thrust_N), float(np.mean(tv.residual[m] * np.sign(tv.v[m])))))
    if len(rows) < 3 or len({round(r[0], 1) for r in rows}) < 2:
        return Signature(0.0, "needs trials at two or more thrust levels")
    h, r = np.array(rows).T
    corr = float(np.corrcoef(h, r)[0, 1]) if np.std(r) > 0 else 0.0
    return Signature(
        _clip01((corr - 0.5) / 0.4),
        f"steady-motion residual along the motion rises with the thrust (r = {corr:+.2f}): "
        "the viscosity falls with the operating force",
        {"A": 0.2},
    )


def check_servo(ctx: DiagnosisContext) -> Signature:
    """A narrow peak in the residual spectrum: an oscillation a person's log does not show.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature
        Strength in [0, 1], the evidence in words and numbers; no start values.
    """
    from balancer_id.diagnose.residual_tests import spectrum_peaks

    peaks = spectrum_peaks(ctx)["peaks"]
    if not peaks:
        return Signature(0.0, "no narrow peak in the residual spectrum")
    p = peaks[0]
    return Signature(
        _clip01((p["ratio_to_median"] - 8) / 30),
        f"narrow residual peak at {p['frequency_hz']:.2f} Hz, {p['ratio_to_median']:.0f}x the "
        "median spectrum: an oscillation during motion",
    )


def check_generic(ctx: DiagnosisContext) -> Signature:
    """No specific signature: report where the residual lives (states it follows).

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature
        Strength in [0, 1], the evidence in words and numbers (the state the
        residual follows best); no start values.
    """
    corr = state_correlations(ctx)
    if not corr:
        return Signature(0.0, "no motion to correlate with")
    name, r = max(corr.items(), key=lambda kv: abs(kv[1]))
    return Signature(
        _clip01((abs(r) - 0.2) / 0.5),
        f"the residual follows the {name} (r = {r:+.2f})",
    )


#: Built-in signature checks by effect name.
SIGNATURES: dict[str, Callable[[DiagnosisContext], Signature]] = {
    "bias": check_bias,
    "karnopp": check_karnopp,
    "speed_limit": check_speed_limit,
    "dead_time": check_dead_time,
    "asymmetric_lag": check_asymmetric_lag,
    "variable_viscosity": check_variable_viscosity,
    "viscous": check_generic,
    "servo": check_servo,
}


def signature_of(effect: type, ctx: DiagnosisContext) -> Signature:
    """Run the effect's own check (user ``signature`` classmethod, built-in, or generic).

    Parameters
    ----------
    effect : type
        An :class:`~balancer_id.model.effect.Effect` subclass. Its ``signature(ctx)``
        classmethod is used when it has one; otherwise the built-in check of its name in
        :data:`SIGNATURES`, or :func:`check_generic`.
    ctx : DiagnosisContext
        The fit and its residuals, trial by trial.

    Returns
    -------
    Signature

    Raises
    ------
    TypeError
        When an effect's own ``signature`` returns something other than a Signature.
    """
    own = getattr(effect, "signature", None)
    check = own if callable(own) else SIGNATURES.get(effect.name, check_generic)
    # Short trials (<= 0.5 s after the step), a single direction or level leave some
    # statistics without data: numpy's warnings about them are expected, and such a check
    # simply finds nothing.
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        sig = check(ctx)
    if not isinstance(sig, Signature):
        raise TypeError(f"{effect.name}.signature must return a Signature")
    if not np.isfinite(sig.strength):
        return Signature(0.0, f"{sig.evidence} (too little data for this check)", sig.start)
    sig.start = {k: float(v) for k, v in sig.start.items() if np.isfinite(v)}
    return sig
