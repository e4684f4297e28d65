"""The ``inspect --plot`` figure: every channel of every run, with the trials found."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from balancer_id.constants import G_DEFAULT
from balancer_id.files import atomic_write
from balancer_id.read.recording import Log, Recording
from balancer_id.report.plots import figure_png
from balancer_id.segment.gravity import vertical_motion
from balancer_id.segment.trial import Trial

if TYPE_CHECKING:
    from matplotlib.axes import Axes

#: Height (in) of one channel panel, the figure's width, and its tallest height.
PANEL_HEIGHT = 1.7
FIGURE_WIDTH = 11.0
MAX_HEIGHT = 60.0


def plot_inspection(
    log: Log,
    trials: Sequence[Trial],
    path: str | Path,
    *,
    g: float = G_DEFAULT,
    vertical: str = "auto",
) -> Path:
    """Draw what was read and the trials found, and write it as a PNG.

    One panel per channel (force, vertical acceleration, raw acceleration axes) per run,
    stacked; trial windows shaded, onsets marked with their thrust, gaps hatched.

    Parameters
    ----------
    log : Log
        What a reader returned.
    trials : sequence of Trial
        The trials found in it (may be empty).
    path : str or Path
        The PNG to write; written whole or not at all.
    g : float, optional
        Gravity removed from with-g acceleration (as for segmentation).
    vertical : {"auto", "x", "y", "z"}, optional
        Vertical axis of linear-acceleration logs (as for segmentation).

    Returns
    -------
    Path
        ``path``.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    panels = [(rec, name, y) for rec in log.recordings for name, y in _channels(rec, g, vertical)]
    height = min(MAX_HEIGHT, PANEL_HEIGHT * max(1, len(panels)) + 0.6)
    fig = Figure(figsize=(FIGURE_WIDTH, height), layout="constrained")
    FigureCanvasAgg(fig)
    if not panels:
        ax = fig.add_subplot()
        ax.text(0.5, 0.5, "no channel to draw", ha="center", va="center")
        ax.set_axis_off()
    axes: list[Axes] = list(fig.subplots(len(panels), 1, squeeze=False)[:, 0]) if panels else []
    for ax, (rec, name, y) in zip(axes, panels, strict=True):
        ax.plot(rec.time, y, lw=0.6, color="0.15")
        ax.set_ylabel(name, fontsize=8)
        ax.set_title(rec.name, fontsize=8, loc="left")
        ax.tick_params(labelsize=7)
        _mark(ax, rec, [t for t in trials if t.recording == rec.name])
    if panels:
        axes[-1].set_xlabel("time (s)")
    fig.suptitle(f"{Path(str(log.path)).name}: {len(trials)} trial(s)", fontsize=9)
    png = figure_png(fig)
    return atomic_write(path, lambda fh: fh.write(png))


def _channels(rec: Recording, g: float, vertical: str) -> list[tuple[str, np.ndarray]]:
    """The (label, samples) pairs drawn for one run."""
    out: list[tuple[str, np.ndarray]] = []
    if rec.force is not None:
        out.append(("force (N)", np.asarray(rec.force, dtype=float)))
    motion = vertical_motion(rec, vertical=vertical, g=g)
    if motion is not None:
        out.append(("vertical a (m/s²)", motion.accel))
    if rec.accel is not None:
        acc = np.asarray(rec.accel, dtype=float).reshape(rec.n_samples, -1)
        for j, axis in enumerate(rec.accel_axes[: acc.shape[1]]):
            out.append((f"a_{axis} (m/s²)", acc[:, j]))
    return out


def _mark(ax: Axes, rec: Recording, trials: Sequence[Trial]) -> None:
    """Shade trial windows, mark onsets with their thrust, hatch gaps."""
    for t in trials:
        ax.axvspan(t.t_start, t.t_end, color="tab:blue", alpha=0.12, lw=0)
        ax.axvline(t.t_step, color="tab:red", lw=0.8)
        ax.annotate(
            f"#{t.index} {t.thrust_N:+.2f} N",
            (t.t_step, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(2, -2),
            textcoords="offset points",
            fontsize=6,
            va="top",
            color="tab:red",
        )
    for gap in rec.gaps:
        ax.axvspan(gap.t_before, gap.t_after, color="tab:orange", alpha=0.3, hatch="//", lw=0)
