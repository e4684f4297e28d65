"""The report's "Discovered term" section: the force found in the states, over its evidence."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from balancer_id.numbers import format_number
from balancer_id.report.blocks import (
    Cell,
    Paragraph,
    Plot,
    Preformatted,
    Section,
    Table,
)

if TYPE_CHECKING:
    from balancer_id.diagnostics.discover import Discovery

#: Axis labels of the states a term depends on.
STATE_LABELS = {"z": "position z (m)", "v": "velocity v (m/s)", "h": "operating force h (N)"}


def plot_discovery(found: Discovery, path: str | Path | None = None) -> Any:
    """The residual force against the state the term depends on, the term drawn over it.

    The residual force is the refit's force discrepancy (``m_a`` times the acceleration
    residual) plus the discovered force: what the terms were fitted to. Points are the
    moving samples (thinned), the red line their binned mean, the black line the
    discovered force at the same samples.

    Parameters
    ----------
    found : Discovery
        The discovery (its ``states``).
    path : str or Path, optional
        Write a PNG here instead of returning the figure.

    Returns
    -------
    Figure or Path
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from balancer_id.files import atomic_write
    from balancer_id.report.plots import figure_png

    st = found.states
    key = found.main_state()
    fig = Figure(figsize=(6.5, 3.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.grid(True, color="0.88", linewidth=0.6)
    ax.set_axisbelow(True)
    moving = st["t"] > 0
    x, r, term = st[key][moving], st["residual_force"][moving], st["term_force"][moving]
    step = max(1, x.size // 4000)
    ax.plot(x[::step], r[::step], ".", color="#9DB9D3", markersize=2, label="residual force")
    if x.size > 20:
        edges = np.quantile(x, np.linspace(0, 1, 31))
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, 29)
        centers = np.array([np.mean(x[idx == k]) for k in range(30) if np.any(idx == k)])
        means = np.array([np.mean(r[idx == k]) for k in range(30) if np.any(idx == k)])
        ax.plot(centers, means, color="#D55E00", linewidth=1.4, label="binned mean")
    order = np.argsort(x)
    ax.plot(x[order], term[order], color="black", linewidth=1.2, label=found.formula)
    ax.set_xlabel(STATE_LABELS.get(key, key), fontsize=9)
    ax.set_ylabel("force (N)", fontsize=9)
    ax.tick_params(labelsize=8)
    ax.legend(fontsize=7, loc="best")
    ax.set_title("discovered term over the residual force", fontsize=10, loc="left")
    if path is None:
        return fig
    png = figure_png(fig)
    return atomic_write(Path(path), lambda fh: fh.write(png))


def discovery_section(found: Discovery | None, written: str | None = None) -> Section | None:
    """The "Discovered term" section, or None when nothing was discovered.

    Parameters
    ----------
    found : Discovery or None
        The discovery of a diagnosis.
    written : str, optional
        The effect file ``improve --discover`` wrote.

    Returns
    -------
    Section or None
    """
    if found is None:
        return None
    rows: list[list[str | Cell]] = [
        [
            t.expression,
            format_number(t.coefficient, 4),
            "-" if t.stderr is None else format_number(t.stderr, 2),
            t.term.unit,
            f"{t.inclusion:.0%}",
        ]
        for t in found.terms
    ]
    beats = (
        f" (the best explanation of the library, {found.rival['label']}, by "
        f"{float(found.rival['delta_bic']):.0f})"  # type: ignore[arg-type]
        if found.rival
        else ""
    )
    blocks: list[Any] = [
        Paragraph(
            f"No explanation of the library brought the residual to the noise floor; a sparse "
            f"regression of the force discrepancy on candidate terms in the states found "
            f"{found.formula} (N). Refitted with the whole model, it lowers BIC by "
            f"{found.delta_bic:.0f}{beats}, to an RMSE of {found.rmse:.4g} m/s²."
        ),
        Table(["term", "coefficient", "stderr", "unit", "inclusion"], rows),
        Plot(
            plot_discovery(found),
            caption="The residual force (the refit's discrepancy plus the discovered force) "
            "against the state the term depends on, with the discovered force drawn over it. "
            "Inclusion: share of bootstrap resamples of the trials in which the term is kept.",
        ),
    ]
    if written:
        blocks.append(
            Paragraph(f"Written as a user effect: {written} (load it with --effects-file).")
        )
    else:
        blocks.append(Paragraph("Write it as a user effect and refit:"))
        blocks.append(Preformatted(found.command))
    return Section("Discovered term", blocks=blocks)
