"""How results show themselves in a notebook and a terminal.

Every result of the Python API (:class:`~balancer_id.identify.result.FitResult`,
the diagnosis, improve and compare results) has a short ``repr`` (one or two lines), a
``summary()`` in the style of lmfit's ``fit_report``, an HTML table for Jupyter
(``_repr_html_``), ``plot()`` (a matplotlib Figure: measured and simulated acceleration,
trial by trial, and the residual) and ``to_frame()`` (a pandas DataFrame with one row per
sample: trial, time, measured, simulated, residual). They render what the fit holds; they
compute nothing but the per-sample residual.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from balancer_id.identify.shown import ShownFit
from balancer_id.metric_fields import metric_cells, metric_line
from balancer_id.numbers import format_with_uncertainty
from balancer_id.param_fields import PARAM_FIELDS, parameter_cells

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

    from balancer_id.identify.band import ResponseBand


__all__ = ["Displayable", "format_with_uncertainty", "match_frame", "match_plot"]


#: The band columns of :func:`match_frame` (and ``--series``), with the band's arrays.
BAND_COLUMNS = {
    "model_low": "model_low",
    "model_high": "model_high",
    "noise_low": "noise_low",
    "noise_high": "noise_high",
}


def match_frame(match: ShownFit, band: ResponseBand | None = None) -> pd.DataFrame:
    """Measured, simulated and residual acceleration of every trial, one row per sample.

    Parameters
    ----------
    match : ShownFit
        A simulation-matching fit.
    band : ResponseBand, optional
        The fit's 95 % bands on its own trials; their columns are added.

    Returns
    -------
    pandas.DataFrame
        Columns ``trial``, ``source``, ``thrust_N``, ``direction``, ``time`` (s),
        ``measured``, ``simulated``, ``residual`` (m/s^2); with a band also
        ``model_low``, ``model_high`` (the 95 % band of the simulated response from the
        parameters' uncertainty) and ``noise_low``, ``noise_high`` (that band widened by
        the noise: where 95 % of the measured samples should fall).
    """
    import pandas as pd

    parts = []
    for td, sl in zip(match.data.trials, match.data.slices(), strict=True):
        y, ym = match.y[sl], match.y_model[sl]
        n = len(y)
        cols: dict[str, Any] = {
            "trial": np.full(n, td.index),
            "source": [td.source] * n,
            "thrust_N": np.full(n, td.thrust_N),
            "direction": [td.direction] * n,
            "time": np.asarray(td.time, dtype=float)[:n],
            "measured": y,
            "simulated": ym,
            "residual": y - ym,
        }
        if band is not None:
            for col, attr in BAND_COLUMNS.items():
                cols[col] = np.asarray(getattr(band, attr))[sl]
        parts.append(pd.DataFrame(cols))
    if not parts:
        cols_ = ["trial", "source", "thrust_N", "direction", "time", "measured"]
        extra = list(BAND_COLUMNS) if band is not None else []
        return pd.DataFrame(columns=[*cols_, "simulated", "residual", *extra])
    return pd.concat(parts, ignore_index=True)


#: Trials drawn by :func:`match_plot` (one panel each); a longer session shows the first.
MAX_PLOTTED_TRIALS = 12
#: Panels per row of :func:`match_plot`.
PANELS_PER_ROW = 6


def match_plot(match: ShownFit, title: str = "", band: ResponseBand | None = None) -> Figure:
    """Measured and simulated acceleration of each trial, with its residual below.

    One column of two panels per trial (small multiples), each titled by the trial's
    thrust and direction; at most :data:`MAX_PLOTTED_TRIALS` trials (the first), in rows
    of :data:`PANELS_PER_ROW`.

    Parameters
    ----------
    match : ShownFit
        A simulation-matching fit.
    title : str
        The figure's title.
    band : ResponseBand, optional
        The fit's 95 % bands: the model band shaded around the simulation, the noise
        band as its thin outline.

    Returns
    -------
    matplotlib.figure.Figure
        Shown as an image when returned in a notebook (no ``%matplotlib inline`` needed).
    """
    from balancer_id.identify.figure import NotebookFigure

    pairs = list(zip(match.data.trials, match.data.slices(), strict=True))
    shown = pairs[:MAX_PLOTTED_TRIALS]
    cols = max(1, min(PANELS_PER_ROW, len(shown)))
    rows = max(1, -(-len(shown) // cols))
    fig = NotebookFigure(figsize=(2.3 * cols + 1.0, 3.2 * rows + 0.6), layout="constrained")
    grid = fig.add_gridspec(2 * rows, cols, height_ratios=[2, 1] * rows)
    for k, (td, sl) in enumerate(shown):
        r, c = divmod(k, cols)
        ax = fig.add_subplot(grid[2 * r, c])
        ax_r = fig.add_subplot(grid[2 * r + 1, c], sharex=ax)
        t = np.asarray(td.time, dtype=float)[: sl.stop - sl.start] - td.t_step
        ax.plot(t, match.y[sl], color="C0", lw=0.8, alpha=0.7, label="measured")
        ax.plot(t, match.y_model[sl], color="C1", lw=1.4, ls="--", label="simulated")
        if band is not None:
            ax.fill_between(
                t,
                band.model_low[sl],
                band.model_high[sl],
                color="C1",
                alpha=0.35,
                lw=0,
                label="95 % band",
            )
            for edge in (band.noise_low[sl], band.noise_high[sl]):
                ax.plot(t, edge, color="C1", lw=0.5, alpha=0.6)
        ax.set_title(f"trial {td.index}: {td.thrust_N:+.3g} N {td.direction}", fontsize="small")
        ax_r.axhline(0.0, color="0.5", lw=0.6)
        ax_r.plot(t, match.y[sl] - match.y_model[sl], color="C2", lw=0.8)
        ax.tick_params(labelbottom=False, labelsize="x-small")
        ax_r.tick_params(labelsize="x-small")
        if c == 0:
            ax.set_ylabel("acceleration (m/s²)", fontsize="small")
            ax_r.set_ylabel("residual", fontsize="small")
        if r == rows - 1:
            ax_r.set_xlabel("time from the step (s)", fontsize="small")
        if k == 0:
            ax.legend(loc="best", fontsize="x-small")
    more = len(pairs) - len(shown)
    heading = title or f"{match.model.spec}: fit {match.metrics.get('nrmse_fit_percent', 0):.1f} %"
    if more > 0:
        heading += f" (first {len(shown)} of {len(pairs)} trials)"
    fig.suptitle(heading)
    return fig


def _parameter_lines(match: ShownFit) -> list[str]:
    lines = []
    width = max((len(n) for n in match.parameters), default=4)
    for name, p in match.parameters.items():
        if not p.vary:
            lines.append(f"    {name:<{width}}  {p.value:.6g} {p.unit} (fixed)")
            continue
        text = format_with_uncertainty(p.value, p.stderr)
        rel = ""
        if p.stderr is not None and math.isfinite(p.stderr) and p.value != 0:
            rel = f" ({100 * abs(p.stderr / p.value):.1f}%)"
        ci = getattr(p, "ci95", None)
        ci_text = ""
        if ci is not None:
            method = getattr(p, "ci95_method", "wald")
            ci_text = f"  95% [{ci[0]:.4g}, {ci[1]:.4g}] {method}"
        bound = f"  at {p.at_bound} bound" if p.at_bound else ""
        lines.append(f"    {name:<{width}}  {text} {p.unit}{rel}{ci_text}{bound}")
    return lines


def _correlation_lines(match: ShownFit, threshold: float = 0.1) -> list[str]:
    seen: set[tuple[str, str]] = set()
    pairs = []
    for a, row in match.correlations.items():
        for b, c in row.items():
            if a == b or (b, a) in seen or c is None or not math.isfinite(c):
                continue
            seen.add((a, b))
            if abs(c) >= threshold:
                pairs.append((abs(c), f"    C({a}, {b}) = {c:+.3f}"))
    return [text for _, text in sorted(pairs, reverse=True)]


def match_report(match: ShownFit, *, warnings: list[str] | None = None) -> str:
    """An lmfit ``fit_report``-style text of a simulation-matching fit.

    Parameters
    ----------
    match : ShownFit
        The fit.
    warnings : list of str, optional
        The warnings to list after the statistics; None lists the fit's own.

    Returns
    -------
    str
        ``[[Model]]``, ``[[Fit Statistics]]``, ``[[Variables]]``, ``[[Correlations]]``
        and ``[[Warnings]]`` blocks.
    """
    m = match.metrics
    n_var = sum(p.vary for p in match.parameters.values())
    lines = [
        "[[Model]]",
        f"    {match.model.spec}",
        "[[Fit Statistics]]",
        f"    # trials           = {len(match.data.trials)}",
        f"    # data points      = {len(match.y)}",
        f"    # variables        = {n_var}",
        f"    # function evals   = {match.nfev}",
        f"    converged          = {match.success}",
    ]
    for field, text in metric_cells(m):
        lines.append(f"    {field.heading:<18} = {text}")
    lines += ["[[Variables]]", *_parameter_lines(match)]
    corr = _correlation_lines(match)
    if corr:
        lines += ["[[Correlations]] (unreported correlations are < 0.100)", *corr]
    all_warnings = list(match.warnings) if warnings is None else list(warnings)
    if all_warnings:
        lines += ["[[Warnings]]", *(f"    {w}" for w in all_warnings)]
    return "\n".join(lines)


def match_html(match: ShownFit, heading: str = "") -> str:
    """An HTML table of a fit's parameters and error figures (for Jupyter).

    Parameters
    ----------
    match : ShownFit
        The fit.
    heading : str
        A line above the table (escaped).

    Returns
    -------
    str
        A ``<div>`` with the heading, the error figures and the parameter table.
    """
    m = match.metrics
    rows = []
    for name, p in match.parameters.items():
        cells = (name, *parameter_cells(p).values())
        rows.append("<tr>" + "".join(f"<td>{html.escape(str(x))}</td>" for x in cells) + "</tr>")
    stats = f"{metric_line(m)}, {len(match.data.trials)} trials"
    warn = "".join(f"<li>{html.escape(str(w))}</li>" for w in match.warnings)
    return (
        "<div>"
        + (f"<p><b>{html.escape(heading)}</b></p>" if heading else "")
        + f"<p>{html.escape(stats)}</p>"
        + "<table><thead><tr>"
        + "".join(f"<th>{h}</th>" for h in ("parameter", *(f.heading for f in PARAM_FIELDS)))
        + "</tr></thead><tbody>"
        + "".join(rows)
        + "</tbody></table>"
        + (f"<ul>{warn}</ul>" if warn else "")
        + "</div>"
    )


class Displayable:
    """Mixin: a short ``repr``, ``summary()``, ``_repr_html_``, ``plot()``, ``to_frame()``.

    A subclass provides ``_shown_match()`` (the fit it shows) and ``_headline()`` (one
    line), and may extend ``_summary_extra()`` and ``_html_extra()``.
    """

    def _shown_match(self) -> ShownFit:  # pragma: no cover - every subclass overrides
        raise NotImplementedError

    def _headline(self) -> str:  # pragma: no cover - every subclass overrides
        raise NotImplementedError

    def _summary_warnings(self) -> list[str]:
        return list(self._shown_match().warnings)

    def _summary_extra(self) -> list[str]:
        return []

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self._headline()}>"

    def _summary_text(self) -> str:
        parts = [match_report(self._shown_match(), warnings=self._summary_warnings())]
        extra = self._summary_extra()
        if extra:
            parts.append("\n".join(extra))
        return "\n".join(parts)

    def summary(self) -> str:
        """The fit in the style of lmfit's ``fit_report``.

        Returns
        -------
        str
            Model, fit statistics, variables (value ± standard error, 95 % interval),
            correlations, warnings, and what the result adds (verdict, suggestions,
            ladder).
        """
        return self._summary_text()

    def _repr_html_(self) -> str:
        extra = "".join(
            f"<pre>{html.escape(line)}</pre>" for line in ["\n".join(self._summary_extra())] if line
        )
        return match_html(self._shown_match(), heading=self._headline()) + extra

    def plot(self, title: str = "") -> Figure:
        """Measured and simulated acceleration of each trial, and the residual.

        Parameters
        ----------
        title : str
            The figure's title; empty: the model and its fit %.

        Returns
        -------
        matplotlib.figure.Figure
        """
        return match_plot(self._shown_match(), title, self.band())

    def to_frame(self) -> Any:
        """One row per sample: trial, source, thrust, direction, time, measured, simulated,
        residual, and the 95 % bands (``model_low``/``model_high``,
        ``noise_low``/``noise_high``).

        Returns
        -------
        pandas.DataFrame
        """
        return match_frame(self._shown_match(), self.band())

    def _band_samples(self) -> dict[str, Any]:
        """Posterior samples to draw the band from (none by default)."""
        return {}

    def band(self, trials: Sequence[Any] | None = None) -> ResponseBand:
        """The 95 % bands of the simulated acceleration (issue 34).

        The model band: the parameters' covariance carried through the simulated
        sensitivities (or the posterior samples' responses, when there are some); the
        noise band: it widened by the residual's standard deviation.

        Parameters
        ----------
        trials : sequence of TrialData, optional
            Other trials to predict (held-out ones); None: the fit's own.

        Returns
        -------
        ResponseBand
        """
        from balancer_id.identify.band import response_band

        return response_band(self._shown_match(), trials, **self._band_samples())


class CallableText(str):
    """A string that, called, returns a longer text (``diagnosis.summary`` and
    ``diagnosis.summary()``)."""

    _full: Any

    def __new__(cls, text: str, full: Any) -> CallableText:
        obj = super().__new__(cls, text)
        obj._full = full
        return obj

    def __call__(self) -> str:
        """The full text.

        Returns
        -------
        str
        """
        return self._full()

    def __reduce__(self):  # pickles as the plain string
        return (str, (str(self),))
