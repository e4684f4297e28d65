"""The figure of parameters tracked in time (``fit --track``): curve, band, block fits."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from balancer_id.identify.figure import NotebookFigure

if TYPE_CHECKING:
    from matplotlib.figure import Figure


class Tracked(Protocol):
    """What the plot reads of a :class:`~balancer_id.identify.tracking.Tracking` (named
    structurally: ``tracking`` draws itself with this module, which does not import it
    back)."""

    @property
    def tracks(self) -> Mapping[str, Any]:
        """Parameter name -> its track (``time_s``, ``value``, ``lo``, ``hi``...)."""
        ...


def plot_tracking(tracking: Tracked, path: str | Path | None = None) -> Figure | Path:
    """Each tracked parameter against time: the smoothed curve, its 95 % band, the
    per-block estimates (± 1.96 standard errors, scaled as the walk found them) and the
    joint fit's constant value.

    Parameters
    ----------
    tracking : Tracking
        ``FitResult.tracking``.
    path : str or Path, optional
        Write a PNG here instead of returning the figure.

    Returns
    -------
    Figure or Path
    """
    names = list(tracking.tracks)
    fig = NotebookFigure(figsize=(7.5, 2.4 * max(len(names), 1) + 0.4), layout="constrained")
    axes = np.atleast_1d(fig.subplots(max(len(names), 1), 1, squeeze=False)).ravel()
    for ax, name in zip(axes, names, strict=False):
        t = tracking.tracks[name]
        ax.grid(True, color="0.88", linewidth=0.6)
        color = "#0072B2"
        ax.fill_between(t.time_s, t.lo, t.hi, color=color, alpha=0.2, linewidth=0,
                        label="95 % band")
        ax.plot(t.time_s, t.value, color=color, linewidth=1.6, label="tracked")
        err = 1.96 * t.local_stderr * np.sqrt(t.walk.scale)
        ax.errorbar(t.time_s, t.local, yerr=err, color="0.35", marker="o", markersize=3,
                    linestyle="none", elinewidth=0.7, capsize=1.5, label="each block alone")
        ax.axhline(t.joint, color="black", linestyle="--", linewidth=0.9,
                   label="one value for the session")
        verdict = "moves" if t.moving else "no movement found"
        ax.set_title(f"{name} ({t.unit}): {verdict}, p = {t.walk.p_value:.2g} for a constant",
                     fontsize=10, loc="left")
        ax.set_ylabel(f"{name} ({t.unit})", fontsize=8)
    axes[-1].set_xlabel("time in the session (s)", fontsize=8)
    if names:
        axes[0].legend(fontsize=7, ncol=2)
    if path is None:
        return fig
    from balancer_id.files import atomic_write

    png = fig._repr_png_()
    return atomic_write(Path(path), lambda fh: fh.write(png))
