"""Report sections of ``compare``, ``diagnose`` and ``improve``, and the full report."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from balancer_id.diagnosis_fields import fact_lines
from balancer_id.numbers import format_number
from balancer_id.report.blocks import (
    Cell,
    Paragraph,
    Plot,
    Preformatted,
    Section,
    Table,
)
from balancer_id.verdicts import Verdict

if TYPE_CHECKING:
    from balancer_id.diagnostics.compare import ModelComparison
    from balancer_id.diagnostics.diagnosis import Diagnosis
    from balancer_id.diagnostics.improve import ImproveResult
    from balancer_id.identify.result import FitResult


def plot_comparison(results: Sequence[ModelComparison], path: str | Path | None = None) -> Any:
    """Measured vs simulated per trial with every compared model overlaid, residuals beneath;
    each model's 95 % band shaded, the band widened by the noise dotted.

    Parameters
    ----------
    results : sequence of ModelComparison
        The compared models, all fitted to the same trials (those of the first are
        plotted).
    path : str or Path, optional
        Write a PNG here instead of returning the figure.

    Returns
    -------
    Figure or Path
        The matplotlib figure, or ``path`` once written.
    """
    from balancer_id.report.plots import model_curves, plot_trials

    trials = results[0].match.data.trials
    curves = [model_curves(r.match) for r in results]
    bands = [r.band() for r in results]
    return plot_trials(trials, curves, path, title="models compared", bands=bands)


def diagnosis_section(diagnosis: Diagnosis) -> Section:
    """The verdict, the residual tests and the ranked suggestions.

    Parameters
    ----------
    diagnosis : Diagnosis
        What :func:`~balancer_id.diagnostics.diagnosis.diagnose` returned.

    Returns
    -------
    Section
        The "Diagnosis" section of a report.
    """
    d: dict[str, Any] = diagnosis.to_dict()
    m = d["metrics"]
    tests = d["residual_tests"]
    style = "good" if d["verdict"] == Verdict.ADEQUATE else "bad"
    blocks: list[Any] = [
        Table(
            ["verdict", "RMSE (m/s²)", "noise floor (m/s²)", "above the floor (m/s²)"],
            [
                [
                    Cell(d["verdict"], style),
                    format_number(m["rmse"]),
                    format_number(m["noise_floor"]),
                    format_number(m["excess_rmse"]),
                ]
            ],
        ),
        Paragraph(d["summary"]),
        *(Paragraph(line) for line in fact_lines(d)),
    ]
    blocks += _residual_test_blocks(tests)
    if not d["suggestions"]:  # a table of headers only says nothing
        blocks.append(
            Paragraph(
                "Candidate effects: none suggested ("
                + (
                    "the model is adequate)."
                    if d.get("verdict") == "adequate"
                    else "no effect tried improved the fit enough)."
                )
            )
        )
    else:
        blocks.append(_candidates_table(d))
    for f in d.get("failed_candidates", []):
        blocks.append(Paragraph(f"⚠ candidate failed: {f}"))
    from balancer_id.report.residual_plots import plot_residual_analysis

    blocks.append(
        Plot(
            plot_residual_analysis(diagnosis),
            "Residual analysis, as MATLAB's resid: the residual's autocorrelation and its "
            "cross-correlation with the thrust, each with its 95 % band (bars or a curve "
            "outside the band: structure the model lacks), and the residual against the "
            "simulated position, velocity and drive force (the red line is its binned mean; "
            "a trend names the state the missing effect depends on).",
        )
    )
    return Section("Diagnosis", blocks=blocks)


def _residual_test_blocks(tests: dict[str, Any]) -> list[Any]:
    """Whiteness, the residual against the thrust and the residual by regime."""
    blocks: list[Any] = []
    w = tests["whiteness"]
    if w.get("ljung_box_p") is not None:
        blocks.append(
            Paragraph(
                f"Whiteness: {w['outside_band']} of {len(w['acf'])} autocorrelation lags "
                f"outside ±{w['band']:.4f}; Ljung-Box Q = {w['ljung_box_q']:.1f}, "
                f"p = {w['ljung_box_p']:.2g}."
            )
        )
    xc = tests["input_cross_correlation"]
    blocks.append(
        Paragraph(
            f"Residual against the thrust: peak {xc['peak_value']:+.4f} m/s² at "
            f"{xc['peak_lag_s']:.2f} s after the onset "
            f"({'significant' if xc['significant'] else 'within noise'})."
        )
    )
    blocks.append(
        Table(
            ["group", "label", "samples", "mean (m/s²)", "RMS (m/s²)", "RMS / noise"],
            [
                [
                    r["group"],
                    r["label"],
                    str(r["n"]),
                    f"{r['mean']:+.4f}",
                    format_number(r["rms"]),
                    Cell(
                        f"{r['rms_over_noise']:.2f}",
                        "warn" if r["rms_over_noise"] > 1.2 else "",
                    ),
                ]
                for r in tests["regimes"]
            ],
            caption="Residual by regime, direction and thrust level",
        )
    )
    return blocks


def _candidates_table(d: dict[str, Any]) -> Table:
    """The diagnosis's suggestions as a table, best first."""
    return Table(
        ["change", "score (ΔBIC)", "error drop", "evidence", "command"],
        [
            [
                Cell(s["change"], "strong" if k == 0 else ""),
                f"{s['score']:.1f}",
                f"{s['excess_error_drop']:.0%}",
                s["evidence"],
                s["command"],
            ]
            for k, s in enumerate(d["suggestions"])
        ],
        caption="Candidate effects, best first (quick refit of each)",
    )


def finding_section(diagnosis: Diagnosis) -> Section:
    """What the report found, first: the verdict, the top suggestion and its evidence.

    Parameters
    ----------
    diagnosis : Diagnosis
        The diagnosis of the report's fit.

    Returns
    -------
    Section
        The "Finding" section: verdict, why, the top suggestion with its evidence and the
        command that tries it, and which poorly determined parameters are symptoms.
    """
    style = "good" if diagnosis.verdict == Verdict.ADEQUATE else "bad"
    m = diagnosis.fit.metrics
    blocks: list[Any] = [
        Table(
            ["verdict", "model", "fit (NRMSE %)", "RMSE (m/s²)"],
            [
                [
                    Cell(diagnosis.verdict, style),
                    diagnosis.fit.model,
                    format_number(m["nrmse_fit_percent"], 3),
                    format_number(m["rmse"], 3),
                ]
            ],
        ),
        Paragraph(str(diagnosis.summary)),
    ]
    from balancer_id.diagnostics.diagnosis import is_missing

    missing = [s for s in diagnosis.suggestions if is_missing(s)]
    if diagnosis.verdict != Verdict.ADEQUATE and missing:
        top = missing[0]
        blocks.append(
            Paragraph(
                f"Top suggestion: {top.label} (BIC better by {top.score:.1f}, "
                f"{top.excess_drop:.0%} of the error above the noise removed). "
                f"Evidence: {top.signature.evidence}."
            )
        )
        blocks.append(Preformatted(top.command))
    elif diagnosis.verdict != Verdict.ADEQUATE and diagnosis.suggestions:
        best = diagnosis.suggestions[0]
        blocks.append(
            Paragraph(
                f"No effect of the library passes the test (the best candidate, {best.label}, "
                f"improves BIC by {best.score:.1f} only). The residual analysis in the "
                "Diagnosis shows what the missing effect depends on."
            )
        )
    if diagnosis.verdict != Verdict.ADEQUATE:
        symptoms = [w for w in diagnosis.fit_warnings() if w.code == "fit.symptom"]
        blocks += [Paragraph(f"⚠ {w.text.split(';')[0]}.") for w in symptoms]
    return Section("Finding", blocks=blocks)


def improve_section(result: ImproveResult) -> Section:
    """The ladder of models and the error falling step by step.

    Parameters
    ----------
    result : ImproveResult
        What :func:`~balancer_id.diagnostics.improve.improve` returned.

    Returns
    -------
    Section
        The "Improving the model" section: the ladder table, the error plot, the final
        model and the changes not taken.
    """
    from balancer_id.report.plots import plot_error_ladder

    d: dict[str, Any] = result.to_dict()
    rows = [
        [
            str(k),
            s["model"],
            s["added"] or "-",
            format_number(s["rmse"]),
            format_number(s["cv_rmse"]),
            f"{s['bic']:.1f}",
        ]
        for k, s in enumerate(d["steps"])
    ]
    blocks: list[Any] = [Table(["step", "model", "added", "RMSE", "held-out RMSE", "BIC"], rows)]
    steps = list(d["steps"])
    found = result.final.discovery
    if found is not None:  # discovered but not written (no --discover): its error, dashed
        steps.append(
            {
                "model": "discovered",
                "added": found.formula,
                "rmse": found.rmse,
                "bic": None,
                "aic": None,
                "discovered": True,
            }
        )
    if len(steps) > 1:  # one bar would show nothing falling
        blocks.append(
            Plot(plot_error_ladder(steps), caption="The error falling as effects are added")
        )
    else:
        blocks.append(
            Paragraph(
                "No effect was added: none of the library's candidates improved both BIC and "
                "the held-out error enough (the Diagnosis section ranks them)."
            )
        )
    blocks.append(Paragraph(f"Final model: {d['final_model']}. {d['final_summary']}"))
    if found is not None and not any(s.get("discovered") for s in d["steps"]):
        blocks.append(
            Paragraph(
                f"A missing force was discovered, {found.formula} (N), bringing the error "
                f"to {format_number(found.rmse)} m/s² (the last, hatched bar); it is not in "
                "the final model because no effect file was written for it. To write it and "
                f"add it: {found.command}"
            )
        )
    blocks += [Paragraph(f"Not taken: {r}") for r in d["rejected"]]
    return Section("Improving the model", blocks=blocks)


def write_improve_report(result: ImproveResult, path: str | Path) -> Path:
    """The fit of the final model, the ladder and the final diagnosis.

    Parameters
    ----------
    result : ImproveResult
        What :func:`~balancer_id.diagnostics.improve.improve` returned; the final rung's
        fit is rendered as it is (with its per-trial fits and coupling).
    path : str or Path
        The report file; ``.html``/``.htm`` or ``.pdf``.

    Returns
    -------
    Path
        ``path``, written whole.

    Raises
    ------
    UsageError
        Another suffix, a missing directory, or ``path`` is one of the input logs.
    """
    from balancer_id.report.discovery_section import discovery_section
    from balancer_id.report.document import write_fit_report

    found = discovery_section(
        result.discovery or result.final.discovery,
        str(result.discovered["file"]) if result.discovered else None,
    )
    return write_fit_report(
        result.steps[-1].fit,
        path,
        lead_sections=[finding_section(result.final)],
        extra_sections=[
            improve_section(result),
            *([found] if found is not None else []),
            diagnosis_section(result.final),
        ],
        warnings=result.final.fit_warnings(),
    )


def write_full_report(
    fit: FitResult,
    diagnosis: Diagnosis,
    out: str | Path,
    improved: ImproveResult | None = None,
) -> Path:
    """The full report (``balancer-id report``): the fit's sections and the diagnosis.

    Nothing is computed here: the fit (with its per-trial fits) and its diagnosis are
    rendered as they are.

    Parameters
    ----------
    fit : FitResult
        The identification.
    diagnosis : Diagnosis
        Its diagnosis.
    out : str or Path
        The report file; ``.html``/``.htm`` or ``.pdf``.
    improved : ImproveResult, optional
        The improve ladder from this fit (error and BIC as effects are added).

    Returns
    -------
    Path
        ``out``, written whole.

    Raises
    ------
    UsageError
        A bad report path (suffix, directory, or one of the logs).
    """
    from balancer_id.report.discovery_section import discovery_section
    from balancer_id.report.document import write_fit_report

    extra = [diagnosis_section(diagnosis)]
    found = discovery_section(diagnosis.discovery)
    if found is not None:
        extra.append(found)
    if improved is not None:
        extra.append(improve_section(improved))
    return write_fit_report(
        fit,
        out,
        lead_sections=[finding_section(diagnosis)],
        extra_sections=extra,
        warnings=diagnosis.fit_warnings(),
    )
