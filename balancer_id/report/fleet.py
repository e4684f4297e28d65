"""The fleet view of a batch: each parameter across a plant's logs (``batch --report``).

Built from the rows of a batch and the per-log JSON it wrote (no log is read again):
a table of the logs, for each parameter its distribution with the outliers flagged, its
trend against the time each log was recorded (the export's own clock when it has one,
else the file's time: the report says which), and the logs whose diagnosis says an
effect is missing, each with its top suggestion (``batch --diagnose``).

Only what the view trusts is counted (issue 33): a log whose fit is not trusted (a
parameter at a bound the data did not choose, starts that disagree, ...) or whose own
diagnosis says an effect is missing is listed apart, with its reason, and kept out of
the statistics, the outlier rule and the trends; its values stay in the table of logs,
marked.

Outliers follow a robust rule: a value more than 3.5 scaled median absolute deviations
from the fleet's median (the modified z-score of Iglewicz and Hoaglin), and more than 3
of its own standard errors from it; it needs at least five logs. A trend is a Theil-Sen
slope over the non-outliers, drawn and claimed only when its 95 % interval excludes 0.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from balancer_id.numbers import format_number
from balancer_id.report.blocks import (
    Cell,
    Paragraph,
    Plot,
    Section,
    Table,
)
from balancer_id.verdicts import Verdict

#: A batch's row (:class:`balancer_id.batch.BatchRow`; the batch layer sits above this one).
BatchRow = Any
#: Modified z-score above which a log's value is flagged (Iglewicz and Hoaglin).
OUTLIER_Z = 3.5
#: Fewest logs for which outliers are flagged.
MIN_LOGS_FOR_OUTLIERS = 5
#: A value this many of its own standard errors from the median is never an outlier.
WITHIN_STDERR = 3.0
#: Fewest (non-outlying, dated) logs for which a trend is claimed.
MIN_LOGS_FOR_TREND = 5
_MISSING = Verdict.EFFECT_MISSING


def robust_outliers(
    values: Sequence[float] | np.ndarray, stderrs: Sequence[float | None] | None = None
) -> np.ndarray:
    """Which values lie more than :data:`OUTLIER_Z` scaled MADs from the median.

    A value within :data:`WITHIN_STDERR` of its own standard errors of the median is
    never an outlier: a fleet of near-equal logs has a tiny MAD, and a log whose value is
    as close to the median as its own uncertainty allows is no outlier however small the
    fleet's spread.

    Parameters
    ----------
    values : sequence of float
        One value per log (NaN for a log without one: never flagged).
    stderrs : sequence of float or None, optional
        Each value's standard error (None or NaN: unknown).

    Returns
    -------
    numpy.ndarray of bool
        True for an outlier; all False with fewer than :data:`MIN_LOGS_FOR_OUTLIERS`
        finite values, or when more than half of them are equal (no spread to measure).
    """
    x = np.asarray(values, dtype=float)
    flags = np.zeros(x.shape, dtype=bool)
    ok = np.isfinite(x)
    if ok.sum() < MIN_LOGS_FOR_OUTLIERS:
        return flags
    med = float(np.median(x[ok]))
    mad = float(np.median(np.abs(x[ok] - med)))
    if mad <= 0.0:
        return flags
    z = 0.6745 * (x - med) / mad
    flags[ok] = np.abs(z[ok]) > OUTLIER_Z
    if stderrs is not None:
        se = np.array([np.nan if e is None else float(e) for e in stderrs], dtype=float)
        close = np.isfinite(se) & (np.abs(x - med) <= WITHIN_STDERR * se)
        flags &= ~close
    return flags


def robust_trend(t: np.ndarray, v: np.ndarray) -> tuple[float, float, float, float] | None:
    """Theil-Sen slope of ``v`` against ``t`` with its 95 % interval, when significant.

    Parameters
    ----------
    t, v : numpy.ndarray
        Times (s since the epoch) and values of the non-outlying logs.

    Returns
    -------
    tuple of float or None
        ``(slope, intercept, low, high)`` per second, or None with fewer than
        :data:`MIN_LOGS_FOR_TREND` logs or when the interval holds 0 (no trend to claim).
    """
    from scipy.stats import theilslopes

    if t.size < MIN_LOGS_FOR_TREND or np.ptp(t) <= 0:
        return None
    slope, intercept, low, high = theilslopes(v, t, alpha=0.95)
    if not (np.isfinite(low) and np.isfinite(high)) or low <= 0.0 <= high:
        return None
    return float(slope), float(intercept), float(low), float(high)


def _load(row: BatchRow) -> dict[str, Any]:
    if not row.json:
        return {}
    try:
        doc = json.loads(Path(row.json).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return doc if isinstance(doc, dict) else {}


def _when(doc: dict[str, Any]) -> tuple[datetime | None, str | None]:
    rec = doc.get("recorded") or {}
    text = rec.get("time") if isinstance(rec, dict) else None
    if not text:
        return None, None
    try:
        stamp = datetime.fromisoformat(str(text))
    except ValueError:
        return None, None
    if stamp.tzinfo is not None:  # compare exports (local clock) and file times alike
        stamp = stamp.astimezone().replace(tzinfo=None)
    return stamp, rec.get("source")


def not_counted(row: BatchRow, doc: dict[str, Any]) -> str | None:
    """Why an identified log is kept out of the fleet's statistics, or None to count it.

    Parameters
    ----------
    row : BatchRow
        An identified log's row.
    doc : dict
        Its JSON (``trusted``, ``untrusted_because``, ``diagnosis``).

    Returns
    -------
    str or None
        The reason: the fit is not trusted (and why), or its diagnosis says an effect is
        missing (its values describe a model the log contradicts).
    """
    if not row.trusted or doc.get("trusted") is False:
        why = doc.get("untrusted_because") or []
        first = str(why[0]) if isinstance(why, list) and why else ""
        return "fit not trusted" + (f": {first}" if first else "")
    diagnosis = doc.get("diagnosis")
    verdict = diagnosis.get("verdict") if isinstance(diagnosis, dict) else None
    if (verdict or row.diagnosis_verdict) == _MISSING:
        return (
            "its diagnosis says an effect is missing: the values are those of a model the "
            "log contradicts"
        )
    return None


def fleet_sections(
    rows: Sequence[BatchRow], shared: dict[str, Any] | None = None
) -> list[Section]:
    """The sections of the fleet report of a batch's rows.

    Parameters
    ----------
    rows : sequence of BatchRow
        A batch's rows (:attr:`balancer_id.batch.BatchResult.rows`); their per-log JSON
        supply the recording times and the diagnoses.
    shared : dict, optional
        The fleet's shared fit (``batch --per-log``: ``shared_fit.json``), shown as a
        section of its own.

    Returns
    -------
    list of Section
    """
    docs = [_load(r) for r in rows]
    identified = [k for k, r in enumerate(rows) if r.ok]
    apart = {k: why for k in identified if (why := not_counted(rows[k], docs[k])) is not None}
    ok = [k for k in identified if k not in apart]  # counted: trusted, nothing missing
    names, values, stderrs = _fleet_values(rows, identified, ok)
    flagged = {n: robust_outliers(v, stderrs[n]) for n, v in values.items()}
    units = {n: _unit(docs, ok, n) for n in names}
    times = [_when(docs[k]) for k in ok]
    sources = {s for _, s in times if s}
    diagnosed = [k for k in identified if isinstance(docs[k].get("diagnosis"), dict)]

    lead = _lead(len(rows), len(identified), len(ok), len(apart), docs, diagnosed)
    sections = [Section("Fleet", blocks=[Paragraph(lead), _summary_table(names, values, flagged)])]
    sections.append(
        Section("Logs", blocks=[_log_table(rows, ok, names, values, flagged, apart)])
    )
    if apart:
        sections.append(Section("Not counted", blocks=_apart_blocks(rows, apart)))
    if names and ok:
        sections.append(
            Section(
                "Parameters across logs",
                blocks=_plots(names, values, flagged, times, sources, units),
            )
        )
    if diagnosed:
        sections.append(Section("Effect missing", blocks=_missing_blocks(rows, docs, diagnosed)))
    if shared is not None:
        sections.insert(1, Section("Shared over the fleet", blocks=shared_blocks(shared)))
    return sections


def _fleet_values(
    rows: Sequence[BatchRow], identified: list[int], ok: list[int]
) -> tuple[list[str], dict[str, np.ndarray], dict[str, list[Any]]]:
    """Every parameter named by an identified log; its values and standard errors over the
    counted logs (NaN where a log has none)."""
    names: list[str] = []
    for k in identified:
        names += [n for n in rows[k].parameters if n not in names]
    values = {
        n: np.array(
            [
                float(rows[k].parameters.get(n, {}).get("value") or np.nan)
                if rows[k].parameters.get(n, {}).get("value") is not None
                else np.nan
                for k in ok
            ]
        )
        for n in names
    }
    stderrs = {
        n: [rows[k].parameters.get(n, {}).get("stderr") for k in ok] for n in names
    }
    return names, values, stderrs


def _lead(
    n_rows: int,
    n_identified: int,
    n_ok: int,
    n_apart: int,
    docs: list[dict[str, Any]],
    diagnosed: list[int],
) -> str:
    """The fleet section's first paragraph: what was identified, counted and diagnosed."""
    failed = n_rows - n_identified
    return (
        f"{n_rows} log(s): {n_identified} identified, {failed} failed; "
        f"{n_ok} counted in the statistics below"
        + (f", {n_apart} listed apart (not trusted or an effect missing). " if n_apart else ". ")
        + (
            f"{len(diagnosed)} diagnosed; "
            f"{sum(docs[k]['diagnosis'].get('verdict') == _MISSING for k in diagnosed)} "
            "with an effect missing. "
            if diagnosed
            else "Not diagnosed (run batch with --diagnose to list missing effects). "
        )
        + f"Outliers: more than {OUTLIER_Z} scaled median absolute deviations from the "
        f"fleet's median (modified z-score), flagged from {MIN_LOGS_FOR_OUTLIERS} logs on."
    )


def _ci(p: dict[str, Any]) -> str:
    ci = p.get("ci95")
    if not ci:
        return "held" if p.get("vary") is False else "-"
    return f"{format_number(float(ci[0]))} .. {format_number(float(ci[1]))}"


def shared_blocks(shared: dict[str, Any]) -> list[Any]:
    """The fleet's shared fit: verdict, the shared values (their intervals beside the
    median interval of the logs fitted alone) and each log's own values.

    Parameters
    ----------
    shared : dict
        ``shared_fit.json`` (the ``fit --per-log`` JSON plus ``left_out``).

    Returns
    -------
    list of blocks
    """
    blocks: list[Any] = []
    left = shared.get("left_out") or []
    if "error" in shared:
        blocks.append(Paragraph(str(shared["error"])))
    else:
        own_names = list(shared.get("per_log") or [])
        logs = shared.get("logs") or []
        blocks.append(
            Paragraph(
                f"The {len(logs)} counted logs fitted together: {', '.join(own_names)} each "
                f"log's own, the rest shared. Verdict: {shared.get('verdict', '-')}."
            )
        )
        blocks += _shared_tables(shared, logs, own_names)
    if left:
        blocks.append(
            Paragraph(
                "Left out of the shared fit: "
                + "; ".join(f"{x.get('file')} ({x.get('why')})" for x in left)
                + "."
            )
        )
    return blocks


def _shared_tables(
    shared: dict[str, Any], logs: list[dict[str, Any]], own_names: list[str]
) -> list[Any]:
    """The shared values beside the logs alone, each log's own values, the sharings."""
    blocks: list[Any] = []
    body: list[list[str | Cell]] = []
    for name, p in (shared.get("shared") or {}).items():
        alone = [
            float(row["alone"][name]["ci95"][1] - row["alone"][name]["ci95"][0])
            for row in logs
            if (row.get("alone") or {}).get(name, {}).get("ci95")
        ]
        width = (
            f"{format_number(float(np.median(alone)))}" if alone else "-"
        )
        ci = p.get("ci95")
        body.append(
            [
                name,
                format_number(float(p["value"])),
                _ci(p),
                format_number(float(ci[1] - ci[0])) if ci else "-",
                width,
                str(p.get("unit", "")),
            ]
        )
    blocks.append(
        Table(
            ["parameter", "shared value", "95 % interval", "width", "width alone "
             "(median log)", "unit"],
            body,
            caption="Shared parameters, pinned by every counted log at once; beside them "
            "the median width of the same interval from each log fitted alone.",
        )
    )
    own_body: list[list[str | Cell]] = []
    for row in logs:
        cells: list[str | Cell] = [str(row.get("file", ""))]
        for name in own_names:
            p = (row.get("own") or {}).get(name, {})
            a = (row.get("alone") or {}).get(name, {})
            cells.append(
                f"{format_number(float(p['value']))} ({_ci(p)}); alone {_ci(a)}"
                if p else "-"
            )
        own_body.append(cells)
    blocks.append(
        Table(
            ["log", *[f"{n} own (95 %); alone" for n in own_names]],
            own_body,
            caption="Each log's own values in the shared fit, and the log fitted alone.",
        )
    )
    comparison = shared.get("comparison") or {}
    blocks.append(
        Table(
            ["sharing", "BIC", "parameters", "held-out RMSE (m/s²)"],
            [
                [
                    name,
                    format_number(float(s.get("bic"))) if s.get("bic") is not None else "-",
                    str(s.get("n_free", "-")),
                    format_number(float(s["held_out_rmse"]))
                    if s.get("held_out_rmse") is not None
                    else "-",
                ]
                for name, s in comparison.items()
            ],
            caption="All shared, partly shared and all separate compared: BIC on the "
            "effective samples, and the error predicting held-out halves of logs.",
        )
    )
    return blocks


def _unit(docs: list[dict[str, Any]], ok: list[int], name: str) -> str:
    """A parameter's unit, from the first log's JSON that gives one."""
    for k in ok:
        unit = docs[k].get("parameters", {}).get(name, {}).get("unit")
        if unit:
            return str(unit)
    return ""


def _summary_table(
    names: list[str], values: dict[str, np.ndarray], flagged: dict[str, np.ndarray]
) -> Table:
    body: list[list[str | Cell]] = []
    for n in names:
        v = values[n][np.isfinite(values[n])]
        if v.size == 0:
            body.append([n, "0", "-", "-", "-", "-"])
            continue
        q1, med, q3 = np.percentile(v, [25, 50, 75])
        n_out = int(flagged[n].sum())
        body.append(
            [
                n,
                str(v.size),
                format_number(float(med)),
                f"{format_number(float(q1))} .. {format_number(float(q3))}",
                f"{format_number(float(v.min()))} .. {format_number(float(v.max()))}",
                Cell(str(n_out), "warn" if n_out else ""),
            ]
        )
    return Table(
        ["parameter", "logs", "median", "quartiles", "range", "outliers"],
        body,
        caption="Each parameter across the identified logs.",
    )


def _apart_blocks(rows: Sequence[BatchRow], apart: dict[int, str]) -> list[Any]:
    body: list[list[str | Cell]] = [[rows[k].file, Cell(why, "warn")] for k, why in apart.items()]
    return [
        Paragraph(
            f"{len(apart)} identified log(s) kept out of the statistics, the outlier rule and "
            "the trends: their values are no measurement of the balancer as the model "
            "describes it."
        ),
        Table(["log", "why not counted"], body),
    ]


def _log_table(
    rows: Sequence[BatchRow],
    ok: list[int],
    names: list[str],
    values: dict[str, np.ndarray],
    flagged: dict[str, np.ndarray],
    apart: dict[int, str] | None = None,
) -> Table:
    pos = {k: j for j, k in enumerate(ok)}
    apart = apart or {}
    body: list[list[str | Cell]] = []
    for k, row in enumerate(rows):
        if k in apart:
            cells_apart: list[str | Cell] = [row.file, Cell("not counted", "warn")]
            for n in names:
                x = row.parameters.get(n, {}).get("value")
                cells_apart.append(
                    format_number(float(x)) + " (not counted)" if x is not None else "-"
                )
            body.append(cells_apart)
            continue
        if k not in pos:
            body.append([row.file, Cell("failed", "bad"), *["-"] * len(names)])
            continue
        j = pos[k]
        cells: list[str | Cell] = [row.file, "ok"]
        for n in names:
            x = values[n][j]
            text = format_number(float(x)) if np.isfinite(x) else "-"
            cells.append(Cell(text + " (outlier)", "warn") if flagged[n][j] else text)
        body.append(cells)
    return Table(
        ["log", "status", *names],
        body,
        caption="Values flagged as outliers are marked; logs not counted (see below) are "
        "marked and left out of every statistic.",
    )


def _plots(
    names: list[str],
    values: dict[str, np.ndarray],
    flagged: dict[str, np.ndarray],
    times: list[tuple[datetime | None, str | None]],
    sources: set[str],
    units: dict[str, str],
) -> list[Any]:
    from balancer_id.report.plots import _new_figure

    have_time = [t is not None for t, _ in times]
    if sources == {"export"}:
        axis = "the time each log was recorded (from the export)"
    elif sources == {"file time"}:
        axis = "each log file's modification time (the exports carry no recording time)"
    elif sources:
        axis = "the recording time where the export has one, else the file's time"
    else:
        axis = ""
    blocks: list[Any] = []
    if axis:
        blocks.append(Paragraph(f"Trends are plotted against {axis}."))
    n = len(names)
    fig = _new_figure(9.0, 2.2 * n + 0.6)
    axes = fig.subplots(n, 2, squeeze=False)
    stamps = np.array([t.timestamp() if t is not None else np.nan for t, _ in times])
    claims: list[str] = []
    for i, name in enumerate(names):
        v, out = values[name], flagged[name]
        finite = np.isfinite(v)
        ax = axes[i][0]
        ax.hist(v[finite], bins=max(5, min(30, int(np.sqrt(finite.sum())) + 1)), color="#4477aa")
        if out.any():
            ax.plot(v[out], np.zeros(out.sum()), "v", color="#cc3311", label="outlier")
            ax.legend(fontsize=7)
        label = f"{name} ({units[name]})" if units.get(name) else name
        ax.set_xlabel(label)
        ax.set_ylabel("logs")
        claim = _trend_axis(axes[i][1], name, v, out, finite & np.array(have_time, dtype=bool),
                            times, stamps, units)
        if claim is not None:
            claims.append(claim)
        axes[i][1].set_ylabel(label)
    blocks.append(
        Plot(
            fig,
            "Left: each parameter's distribution (outliers marked below the axis). "
            "Right: against time (outliers circled), with a Theil-Sen line over the "
            "non-outliers only where its 95 % interval excludes no change.",
        )
    )
    blocks.append(
        Paragraph(
            "Trends: " + "; ".join(claims) + "."
            if claims
            else "No parameter has a significant trend over time (Theil-Sen slope over the "
            "non-outlying logs, 95 % interval holding zero)."
        )
    )
    return blocks


def _trend_axis(
    ax: Any,
    name: str,
    v: np.ndarray,
    out: np.ndarray,
    when: np.ndarray,
    times: list[tuple[datetime | None, str | None]],
    stamps: np.ndarray,
    units: dict[str, str],
) -> str | None:
    """One parameter against time (outliers circled, the Theil-Sen line over the others);
    the trend in words when it is significant."""
    claim = None
    if when.any():
        dates = [times[j][0] for j in np.flatnonzero(when)]
        ax.plot(dates, v[when], "o", ms=3, color="#4477aa")
        bad = when & out
        if bad.any():
            ax.plot(
                [times[j][0] for j in np.flatnonzero(bad)],
                v[bad],
                "o",
                ms=5,
                mfc="none",
                color="#cc3311",
            )
        fit_on = when & ~out  # the trend over the non-outliers only
        trend = robust_trend(stamps[fit_on], v[fit_on])
        if trend is not None:
            slope, icept, low, high = trend
            t_line = np.array([np.nanmin(stamps[fit_on]), np.nanmax(stamps[fit_on])])
            ax.plot(
                [datetime.fromtimestamp(t) for t in t_line],
                slope * t_line + icept,
                "-",
                color="#228833",
                lw=1,
            )
            day = 86400.0
            claim = (
                f"{name} changes by {slope * day:.3g} {units.get(name, '')} per day "
                f"(95 % {low * day:.3g} .. {high * day:.3g}; Theil-Sen over "
                f"{int(fit_on.sum())} logs, outliers left out)"
            )
        _date_axis(ax)
        ax.set_xlabel("recorded")
    return claim


def _date_axis(ax: Any) -> None:
    """Dates on ``ax``'s x axis that never overlap: matplotlib's concise date labels (as
    many ticks as fit, the year or day said once), slanted."""
    import matplotlib.dates as mdates

    locator = mdates.AutoDateLocator(minticks=2, maxticks=5)
    ax.xaxis.set_major_locator(locator)
    ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
    ax.tick_params(axis="x", labelrotation=30, labelsize=7)


def _missing_blocks(
    rows: Sequence[BatchRow], docs: list[dict[str, Any]], diagnosed: list[int]
) -> list[Any]:
    body: list[list[str | Cell]] = []
    for k in diagnosed:
        diag = docs[k]["diagnosis"]
        if diag.get("verdict") != _MISSING:
            continue
        top = (diag.get("suggestions") or [None])[0]
        if isinstance(top, dict) and not _helps(top):
            top = None  # its own diagnosis: the refit removed nothing
        if isinstance(top, dict):
            suggestion = str(top.get("change") or top.get("effect") or "-")
            command = str(top.get("command") or "-")
        elif isinstance(found := diag.get("discovery"), dict) and found.get("command"):
            suggestion = f"no built-in effect; a force was found: {found.get('formula')} (N)"
            command = str(found["command"])
        else:
            suggestion, command = "no built-in effect explains the residual", "-"
        body.append([rows[k].file, suggestion, command])
    if not body:
        return [Paragraph("No diagnosed log has an effect missing.")]
    return [
        Paragraph(f"{len(body)} log(s) whose diagnosis says an effect is missing."),
        Table(["log", "top suggestion", "command"], body),
    ]


def _helps(suggestion: dict[str, Any]) -> bool:
    """Whether a suggestion's refit removed some of the error above the noise floor."""
    drop = suggestion.get("excess_error_drop")
    return drop is None or (isinstance(drop, int | float) and drop > 0)


def write_fleet_report(
    rows: Sequence[BatchRow], path: str | Path, shared: dict[str, Any] | None = None
) -> Path:
    """Write the fleet report of a batch as FILE.html (or FILE.pdf).

    Parameters
    ----------
    rows : sequence of BatchRow
        A batch's rows.
    path : str or Path
        The report file; written whole or not at all.
    shared : dict, optional
        The fleet's shared fit (``batch --per-log``).

    Returns
    -------
    Path
        ``path``.
    """
    from balancer_id.report.document import write_report

    return write_report(
        "Fleet report",
        fleet_sections(rows, shared),
        path,
        inputs=[r.file for r in rows],
        subtitle=f"{len(rows)} log(s) identified one by one",
    )
