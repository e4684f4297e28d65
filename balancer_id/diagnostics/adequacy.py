"""The tests an "adequate" verdict must pass: level, whiteness beyond the sensor's colour,
consistency.

Each test returns a record ``{name, passed, value, limit, text}`` (CONTRACT.md
``diagnose`` ``tests``) and a failing one a typed note (``diagnose.above_noise``,
``diagnose.not_white``, ``diagnose.inconsistent``) saying by how much it failed.

- *level*: the error above the noise floor, against what the noise floor's own
  uncertainty allows (the floor is measured on the resting samples, whose effective count
  falls with the noise's colour).
- *whiteness beyond the noise colour*: the residual's autocorrelation against the
  autocorrelation of the resting noise (the sensor's own colour, measured at rest), lag by
  lag, with Bartlett's variance for both; coloured noise with nothing missing passes.
- *consistency*: each parameter's per-run estimates against one common value (chi-square,
  Bonferroni over the parameters), and the paper's method's m_a against the fit's within
  their uncertainties.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.special import chdtrc, erfc

from balancer_id.diagnostics.context import DiagnosisContext, difference_colour
from balancer_id.diagnostics.groups import run_estimates
from balancer_id.diagnostics.residual_tests import autocorrelation
from balancer_id.identify.metrics import correlation_time
from balancer_id.notes import Note

#: Lags compared (samples): the resting parts are short, so few lags.
COLOUR_LAGS = 10
#: Short lags over which the excess of autocorrelation is averaged.
COLOUR_SHORT = 5
#: Probability below which the residual's colour differs from the noise's ...
COLOUR_P = 1e-6
#: ... and the smallest difference of autocorrelation that counts (effect size).
COLOUR_MIN_DIFF = 0.05
#: Error above the noise floor always tolerated (x the noise).
LEVEL_MIN = 0.5
#: Family-wise false-alarm probability of the consistency test.
CONSISTENCY_ALPHA = 1e-4
#: Smallest relative spread of the per-run estimates that counts.
CONSISTENCY_MIN_SPREAD = 0.03


def rest_noise(ctx: DiagnosisContext) -> list[np.ndarray]:
    """The resting samples before each onset (mean and slope removed), trial by trial.

    Parameters
    ----------
    ctx : DiagnosisContext
        The diagnosis's trials (time from each onset, measured acceleration).

    Returns
    -------
    list of numpy.ndarray
        One array of rest noise per trial with enough rest (m/s^2).
    """
    out = []
    for tv in ctx.trials:
        rest = tv.t < -0.02
        if rest.sum() >= 3 * COLOUR_LAGS:
            y = tv.y[rest]
            t = tv.t[rest]
            coef = np.polyfit(t - t.mean(), y, 1)
            out.append(y - np.polyval(coef, t - t.mean()))
    return out


def _mean_acf(
    series: Sequence[np.ndarray], lags: int, shortest: int | None = None
) -> tuple[np.ndarray, int, float]:
    """The series' autocorrelation (weighted by length), their samples and their mean
    length; series of ``shortest`` samples or fewer (``3 * lags``) are left out."""
    acfs, w = [], []
    for x in series:
        if x.size > (3 * lags if shortest is None else shortest):
            acfs.append(autocorrelation(x, lags))
            w.append(x.size)
    if not acfs:
        return np.zeros(lags), 0, 0.0
    return np.average(np.array(acfs), axis=0, weights=w), int(sum(w)), float(np.mean(w))


def _unbiased(acf: np.ndarray, tau: float, length: float) -> np.ndarray:
    """``acf`` of series of mean ``length`` whose means were removed, undone of the pull
    down that removal gives (about ``tau / length`` at every short lag)."""
    if length <= 0:
        return acf
    share = min(tau / length, 0.5)
    return acf * (1.0 - share) + share


#: Resting samples (over all trials) below which the noise's colour is read from the
#: residual's sample-to-sample differences instead (a first-order colour).
COLOUR_REST_MIN = 100


def noise_colour(ctx: DiagnosisContext, lags: int = COLOUR_LAGS) -> dict[str, object]:
    """The sensor's own colour: the autocorrelation of its noise, at lags ``1..lags``.

    Measured on the residual at rest before the onsets (each trial's stretch with its
    mean removed, the pull down of that removal undone). Where the trials hold fewer
    than :data:`COLOUR_REST_MIN` resting samples (a session's one rest, a 50 Hz log's
    half second), a first-order colour is read from the residual's differences
    (:func:`difference_colour`) over all samples instead: assuming white noise there
    made every coloured log look like a misfit.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals.
    lags : int
        Lags returned.

    Returns
    -------
    dict
        ``acf`` (numpy.ndarray), ``n`` (samples it was measured on), ``tau`` (its
        correlation time, samples), ``source`` (``rest`` or ``differences``) and
        ``n_rest`` (the resting samples, whichever the source).
    """
    rest = [tv.residual[tv.t < -0.02] for tv in ctx.trials]
    rest = [r for r in rest if r.size > 2 * COLOUR_SHORT]
    n_rest = int(sum(r.size for r in rest))
    if n_rest >= COLOUR_REST_MIN:
        tau = correlation_time(rest, removed=1)
        acf, n, length = _mean_acf(rest, lags, shortest=2 * COLOUR_SHORT)
        acf = _unbiased(acf, tau, length)
        return {"acf": acf, "n": n, "tau": tau, "source": "rest", "n_rest": n_rest}
    r1 = difference_colour([tv.residual for tv in ctx.trials])
    n = int(sum(tv.residual.size for tv in ctx.trials))
    acf = r1 ** np.arange(1, lags + 1, dtype=float)
    tau = (1.0 + r1) / (1.0 - r1)
    return {"acf": acf, "n": n, "tau": tau, "source": "differences", "n_rest": n_rest}


def colour_test(ctx: DiagnosisContext) -> dict[str, object]:
    """Whiteness of the residual beyond the noise's own colour (:func:`noise_colour`).

    Both autocorrelations are undone of the pull down that removing each stretch's mean
    gives (a 0.5 s rest of a strongly coloured noise loses a quarter of its lag-one
    correlation that way, which read as a misfit on clean logs).

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals.

    Returns
    -------
    dict
        ``name`` (``whiteness``), ``passed``, ``p_value``, ``max_acf_difference``,
        ``residual_acf`` and ``rest_acf`` (lags 1..:data:`COLOUR_LAGS`), ``n_rest``,
        ``rest_tau``, ``colour_from`` (``rest`` or ``differences``) and
        ``n_rest_samples`` (the resting samples the noise floor's spread was read on).
    """
    colour = noise_colour(ctx)
    acf_rest = np.asarray(colour["acf"], float)
    n_rest = int(colour["n"])  # type: ignore[call-overload]
    tau = float(colour["tau"])  # type: ignore[arg-type]
    raw_res, n_res, length = _mean_acf([tv.residual for tv in ctx.trials], COLOUR_LAGS)
    acf_res = _unbiased(raw_res, tau, length) if n_res else raw_res
    bartlett = 1.0 + 2.0 * float(np.sum(acf_rest**2))
    var = bartlett / max(n_res, 1) + (bartlett / n_rest if n_rest else 0.0)
    diff = acf_res - acf_rest
    # one-sided: a missing term adds a slowly varying part to the residual, which raises
    # its autocorrelation at every short lag; a residual less coloured than the resting
    # noise is no failure
    short = diff[:COLOUR_SHORT]
    excess = float(np.mean(short)) if short.size else 0.0
    z = excess / float(np.sqrt(var)) if var > 0 else 0.0
    p = float(0.5 * erfc(z / np.sqrt(2.0)))
    max_diff = float(np.max(short)) if short.size else 0.0
    passed = not (p < COLOUR_P and excess > COLOUR_MIN_DIFF)
    where = "resting noise's" if colour["source"] == "rest" else "noise's (from its differences)"
    return {
        "name": "whiteness",
        "passed": passed,
        "p_value": p,
        "mean_acf_excess": excess,
        "max_acf_difference": max_diff,
        "limit": COLOUR_MIN_DIFF,
        "residual_acf": [round(float(a), 4) for a in acf_res],
        "rest_acf": [round(float(a), 4) for a in acf_rest],
        "n_rest": n_rest,
        "rest_tau": tau,
        "colour_from": colour["source"],
        "n_rest_samples": colour["n_rest"],
        "text": (
            f"the residual's autocorrelation exceeds the {where} by {excess:.2f} on "
            f"average over lags 1-{COLOUR_SHORT} (up to {max_diff:.2f}; p = {p:.1e})"
        ),
    }


def level_test(ctx: DiagnosisContext, colour: dict[str, object]) -> dict[str, object]:
    """The error above the noise floor against what the floor's uncertainty allows.

    Parameters
    ----------
    ctx : DiagnosisContext
        The fit and its residuals.
    colour : dict
        :func:`colour_test`'s record (its resting autocorrelation sets the floor's
        effective sample count).

    Returns
    -------
    dict
        ``name`` (``level``), ``passed``, ``value`` (error above the floor, x the noise)
        and ``limit``.
    """
    acf_rest = np.asarray(colour.get("rest_acf") or [], float)
    # the floor's uncertainty is the resting samples', whichever gave the colour
    n_rest = int(colour.get("n_rest_samples", colour.get("n_rest")) or 0)  # type: ignore[call-overload]
    n_eff = n_rest / (1.0 + 2.0 * float(np.sum(acf_rest**2))) if n_rest else 0.0
    limit = LEVEL_MIN
    if n_eff > 0:
        limit = max(LEVEL_MIN, float(np.sqrt(3.0 * np.sqrt(2.0 / n_eff))))
    ratio = ctx.excess_rmse() / ctx.noise_floor if ctx.noise_floor > 0 else float("inf")
    return {
        "name": "level",
        "passed": bool(ratio <= limit),
        "value": float(ratio),
        "limit": float(limit),
        "text": (
            f"the error above the noise floor is {ratio:.2f}x the noise "
            f"({ctx.noise_floor:.4g} m/s^2; limit {limit:.2f}x)"
        ),
    }


def consistency_test(
    names: Sequence[str],
    runs: Sequence[str],
    values: Sequence[dict[str, float]],
    stderrs: Sequence[dict[str, float | None]],
    thrusts: Sequence[float],
    paper_m_a: tuple[float, float] | None = None,
    fit_m_a: tuple[float, float | None] | None = None,
    inflation: float = 1.0,
) -> dict[str, object]:
    """Each parameter's per-run estimates against one value; the paper's m_a against the fit's.

    Parameters
    ----------
    names : sequence of str
        The parameters.
    runs : sequence of str
        Each trial's run label.
    values, stderrs : sequence of dict
        Each trial's fitted values and standard errors.
    thrusts : sequence of float
        Each trial's thrust (N).
    paper_m_a : tuple, optional
        ``(m_a, stderr)`` of the paper's method.
    fit_m_a : tuple, optional
        ``(m_a, stderr)`` of the fit.
    inflation : float
        Variance inflation of the per-trial estimates by the noise's colour
        (``(1 + r1) / (1 - r1)`` of the resting noise; 1 for white noise).

    Returns
    -------
    dict
        ``name`` (``consistency``), ``passed``, ``worst`` (the parameter, its chi-square
        per degree of freedom, p-value and relative spread) and ``paper_z``.
    """
    worst: dict[str, object] | None = None
    failed = []
    tested = 0
    rows = []
    for name in names:
        est = run_estimates(
            runs, [v.get(name, np.nan) for v in values], [s.get(name) for s in stderrs], thrusts
        )
        if len(est) < 3:
            continue
        tested += 1
        x = np.array([e.value for e in est])
        w = 1.0 / np.array([e.stderr for e in est]) ** 2
        mean = float(np.average(x, weights=w))
        chi2 = float(np.sum(w * (x - mean) ** 2)) / max(inflation, 1.0)
        dof = len(est) - 1
        spread = float(np.sqrt(np.average((x - mean) ** 2, weights=w))) / max(abs(mean), 1e-300)
        rows.append((name, chi2, dof, spread))
    for name, chi2, dof, spread in rows:
        p = min(float(chdtrc(dof, chi2)) * max(tested, 1), 1.0)
        row = {
            "parameter": name,
            "chi2_per_dof": chi2 / dof,
            "p_value": p,
            "relative_spread": spread,
        }
        if worst is None or p < float(worst["p_value"]):  # type: ignore[arg-type]
            worst = row
        if p < CONSISTENCY_ALPHA and spread > CONSISTENCY_MIN_SPREAD:
            failed.append(row)
    paper_z, paper_off = _paper_disagreement(paper_m_a, fit_m_a)
    text = "the parameters agree across runs"
    if failed:
        f = failed[0]
        text = (
            f"{f['parameter']} differs between runs: chi-square {f['chi2_per_dof']:.1f} per "
            f"degree of freedom, spread {f['relative_spread']:.0%} (p = {f['p_value']:.1e})"
        )
    if paper_off:
        text += (
            f"; the paper's method's m_a {paper_m_a[0]:.3g} kg is "  # type: ignore[index]
            f"{abs(paper_z or 0.0):.1f} "
            "standard errors from the fit's"
        )
    return {
        "name": "consistency",
        # the paper's method is biased by the very effects a model may miss (and by the
        # force noise of a light balancer): its disagreement is reported, not a failure
        "passed": not failed,
        "paper_disagrees": bool(paper_off),
        "worst": worst,
        "failed": failed,
        "paper_z": paper_z,
        "text": text,
    }


def _paper_disagreement(
    paper_m_a: tuple[float, float] | None, fit_m_a: tuple[float, float | None] | None
) -> tuple[float | None, bool]:
    """The paper's m_a against the fit's, in standard errors; whether it is far off (more
    than 5 standard errors and 20 %)."""
    paper_z = None
    if paper_m_a is not None and fit_m_a is not None and fit_m_a[1]:
        se = float(np.hypot(paper_m_a[1], fit_m_a[1] or 0.0))
        if se > 0 and np.isfinite(se):
            paper_z = (paper_m_a[0] - fit_m_a[0]) / se
    paper_off = (
        paper_z is not None
        and abs(paper_z) > 5
        and fit_m_a is not None
        and paper_m_a is not None
        and abs(paper_m_a[0] - fit_m_a[0]) > 0.2 * abs(fit_m_a[0])
    )
    return paper_z, bool(paper_off)


NOTE_OF = {
    "level": "diagnose.above_noise",
    "whiteness": "diagnose.not_white",
    "consistency": "diagnose.inconsistent",
}


def colour_inflation(colour: dict[str, object]) -> float:
    """The resting noise's correlation time (:func:`colour_test`'s ``rest_tau``: its
    long-run variance factor; ``(1 + r1) / (1 - r1)`` for AR(1) noise, 1 for white noise
    or without resting samples).

    Parameters
    ----------
    colour : dict
        :func:`colour_test`'s record.

    Returns
    -------
    float
    """
    return max(float(colour.get("rest_tau", 1.0)), 1.0)  # type: ignore[arg-type]


def failed_notes(tests: Sequence[dict[str, object]]) -> list[Note]:
    """A typed note per failed test, saying by how much it failed.

    Parameters
    ----------
    tests : sequence of dict
        Test records.

    Returns
    -------
    list of Note
    """
    return [
        Note(NOTE_OF[str(t["name"])], str(t["text"]), None, "warning")
        for t in tests
        if not t["passed"]
    ]
