"""Figures of balancer-id: trials, the paper's method, the error ladder, robot coupling.

Every function builds a :class:`matplotlib.figure.Figure` attached to the Agg canvas
(never ``pyplot``): nothing opens a window, no global backend or ``pyplot`` state is
changed, and the figures are freed when they go out of scope. Given a ``path``, a
function writes a PNG whole or not at all (temporary file in the same directory, then
``os.replace``) and returns the path; without one it returns the Figure, which the
report layer embeds in HTML or PDF and Jupyter shows as it is.

matplotlib is imported inside the functions, so importing this module is cheap.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from balancer_id.errors import UsageError
from balancer_id.files import atomic_write
from balancer_id.numbers import format_number
from balancer_id.text import make_figure_text_safe

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from balancer_id.identify.band import ResponseBand, Stretch
    from balancer_id.identify.classic import ClassicResult
    from balancer_id.identify.coupling import Coupling
    from balancer_id.identify.data import TrialData
    from balancer_id.identify.matching import MatchResult
    from balancer_id.identify.posterior import Posterior
    from balancer_id.identify.result import PerTrialFit

#: One model's simulated acceleration, per trial: ``(label, [y_model of trial 0, ...])``.
#: An entry may be ``None`` where that model has no simulation of the trial.
ModelCurves = tuple[str, Sequence[np.ndarray | None]]

#: Colours of the models (colour-blind safe, distinct from the grey of the measurement).
MODEL_COLORS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")
#: Colour and marker of each direction of motion (paper Figs. 7 and 8).
DIRECTION_STYLE = {"up": ("#0072B2", "^"), "down": ("#D55E00", "v")}
MEASURED_COLOR = "0.45"
#: Resolution of the PNG files (dots per inch).
PNG_DPI = 120
#: Width of the moving mean drawn over the residual (s).
RESIDUAL_SMOOTH_S = 0.25
#: Trials per row of :func:`plot_trials`.
TRIAL_COLUMNS = 2


# --------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------
def _new_figure(
    width: float, height: float, layout: Literal["constrained"] | None = "constrained"
) -> Figure:
    """A Figure on the Agg canvas (no pyplot, no GUI), constrained layout by default."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout=layout)
    FigureCanvasAgg(fig)
    return fig


def figure_png(fig: Figure, dpi: int = PNG_DPI) -> bytes:
    """The PNG bytes of a figure.

    Parameters
    ----------
    fig : Figure
        Any matplotlib figure.
    dpi : int
        Resolution.

    Returns
    -------
    bytes
    """
    from io import BytesIO

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if fig.canvas is None or not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    buf = BytesIO()
    make_figure_text_safe(fig).savefig(buf, format="png", dpi=dpi, facecolor="white")
    return buf.getvalue()


def _finish(fig: Figure, path: str | Path | None) -> Figure | Path:
    """Return ``fig``, or write it as a PNG at ``path`` and return the path."""
    if path is None:
        return fig
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise UsageError(f"plot file '{path}' must end in .png")
    png = figure_png(fig)
    return atomic_write(path, lambda fh: fh.write(png))


def _format_axes(ax: Axes) -> None:
    ax.grid(True, color="0.88", linewidth=0.6)
    ax.set_axisbelow(True)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    ax.tick_params(labelsize=8)


def _short_source(source: str) -> str:
    """``dir/log.csv [Run #1]`` -> ``log.csv [Run #1]``."""
    if not source:
        return ""
    head, sep, tail = source.partition(" [")
    return Path(head).name + (sep + tail if sep else "")


# --------------------------------------------------------------------------------------
# trials: measured vs simulated
# --------------------------------------------------------------------------------------
def model_curves(match: MatchResult, label: str | None = None) -> ModelCurves:
    """The simulated acceleration of a fit, split per trial, for :func:`plot_trials`.

    Parameters
    ----------
    match : MatchResult
        A simulation-matching fit.
    label : str, optional
        Legend label (default: the model's spec).

    Returns
    -------
    tuple
        ``(label, [y_model of each trial])``.
    """
    y_model = np.asarray(match.y_model, float)
    return (label or match.model.spec, [y_model[s] for s in match.data.slices()])


def _sig(x: float, digits: int) -> str:
    """``x`` to ``digits`` significant digits, trailing zeros kept (0.0300)."""
    return format_number(x, digits)


def _rmse(y: np.ndarray, y_model: np.ndarray) -> float:
    r = np.asarray(y, float) - np.asarray(y_model, float)
    r = r[np.isfinite(r)]
    return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")


def plot_trials(
    trials: Sequence[TrialData],
    models: Sequence[ModelCurves],
    path: str | Path | None = None,
    *,
    columns: int = TRIAL_COLUMNS,
    title: str | None = None,
    bands: Sequence[ResponseBand | None] | None = None,
    stretches: Sequence[Stretch] = (),
) -> Figure | Path:
    """Measured vs simulated acceleration of each trial, with the residual beneath.

    One panel per trial: the measured vertical acceleration (grey), each model's
    simulation overlaid (legend: its label and its RMSE on that trial), and below it the
    residual ``measured - simulated`` of each model, on the same time axis, which starts
    at the trial's onset (t = 0 at the thrust step). The title gives the trial number,
    its signed thrust, direction and source.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials (``.time``, ``.accel``, ``.t_step``, ``.thrust_N``, ...).
    models : sequence of (str, sequence of array)
        One item per model: its label and its simulated acceleration on each trial, in
        the order of ``trials`` (``None`` where it has none). ``fit`` passes one item
        (:func:`model_curves`), ``compare`` one per model.
    path : str or Path, optional
        Write a PNG here (atomically) instead of returning the figure.
    columns : int
        Trials per row.
    title : str, optional
        Title over all panels.
    bands : sequence of ResponseBand or None, optional
        Each model's 95 % bands over the same ``trials`` (in ``models``' order): the model
        band shaded around its curve, the band widened by the noise as dotted edges.
    stretches : sequence of Stretch
        Where the measurement leaves the noise band (shaded red on its trial's panels).

    Returns
    -------
    Figure or Path
        The figure, or ``path`` once written.

    Raises
    ------
    ValueError
        A model does not give one curve per trial, or a curve does not match its trial.
    """
    trials = list(trials)
    for label, curves in models:
        if len(curves) != len(trials):
            raise ValueError(f"model '{label}' gives {len(curves)} curves for {len(trials)} trials")
        for td, y in zip(trials, curves, strict=True):
            if y is not None and len(y) != len(td.time):
                raise ValueError(
                    f"model '{label}': trial {td.index} has {len(td.time)} samples, "
                    f"the curve {len(y)}"
                )
    n = max(len(trials), 1)
    columns = max(1, min(columns, n))
    rows = -(-n // columns)
    # fixed margins in inches: a layout engine would draw the busy figure twice
    panel_w, panel_h, gap_w, gap_h = 4.75, 2.75, 0.6, 0.85
    left, right, bottom = 0.75, 0.2, 0.5
    top = 0.35 + (0.35 if title else 0.0)
    width = left + columns * panel_w + (columns - 1) * gap_w + right
    height = top + rows * panel_h + (rows - 1) * gap_h + bottom
    fig = _new_figure(width, height, layout=None)
    if title:
        fig.suptitle(title, fontsize=11, fontweight="bold", y=1 - 0.12 / height, va="top")
    if not trials:
        ax = fig.add_subplot()
        ax.axis("off")
        ax.text(0.5, 0.5, "no trial", ha="center", va="center", fontsize=12, color="0.4")
        return _finish(fig, path)
    outer = fig.add_gridspec(
        rows,
        columns,
        left=left / width,
        right=1 - right / width,
        bottom=bottom / height,
        top=1 - top / height,
        wspace=gap_w / panel_w,
        hspace=gap_h / panel_h,
    )
    for k, td in enumerate(trials):
        inner = outer[k // columns, k % columns].subgridspec(
            2, 1, height_ratios=[3.0, 1.25], hspace=0.07
        )
        ax = fig.add_subplot(inner[0])
        axr = fig.add_subplot(inner[1], sharex=ax)
        _draw_trial(ax, axr, td, [(lbl, curves[k]) for lbl, curves in models])
        for j, band in enumerate(bands or ()):
            if band is not None:
                _draw_band(ax, td, band, MODEL_COLORS[j % len(MODEL_COLORS)])
        for s in stretches:
            if s.trial == td.index:
                for a in (ax, axr):
                    a.axvspan(
                        s.t_start - td.t_step,
                        s.t_end - td.t_step,
                        color="#D55E00",
                        alpha=0.15,
                        lw=0,
                        zorder=1,
                    )
        if k % columns == 0:
            ax.set_ylabel("acceleration (m/s²)", fontsize=8)
            axr.set_ylabel("residual (m/s²)", fontsize=8)
    return _finish(fig, path)


def _draw_trial(
    ax: Axes, axr: Axes, td: TrialData, curves: Sequence[tuple[str, np.ndarray | None]]
) -> None:
    t = np.asarray(td.time, float) - float(td.t_step)
    y = np.asarray(td.accel, float)
    ax.plot(t, y, color=MEASURED_COLOR, linewidth=0.6, label="measured", zorder=2)
    for j, (label, ym) in enumerate(curves):
        if ym is None:
            continue
        color = MODEL_COLORS[j % len(MODEL_COLORS)]
        ym = np.asarray(ym, float)
        rmse = _rmse(y, ym)
        ax.plot(
            t,
            ym,
            color=color,
            linewidth=1.7,
            label=f"{label}  (RMSE {_sig(rmse, 3)} m/s²)",
            zorder=3,
        )
        r = y - ym
        axr.plot(t, r, color=color, linewidth=0.5, alpha=0.35)
        axr.plot(t, _moving_mean(t, r, RESIDUAL_SMOOTH_S), color=color, linewidth=1.4)
    for a in (ax, axr):
        _format_axes(a)
        a.axvline(0.0, color="0.3", linewidth=0.8, linestyle=":")
        a.axhline(0.0, color="0.6", linewidth=0.6)
    ax.tick_params(labelbottom=False)
    axr.set_xlabel("time after onset (s)", fontsize=8)
    ax.set_xlim(t[0], t[-1])
    src = _short_source(td.source)
    ax.set_title(
        f"trial {td.index}: {td.thrust_N:+.2f} N {td.direction}" + (f"   ·   {src}" if src else ""),
        fontsize=9,
        loc="left",
    )
    # the emptiest corner, counted here ("best" costs seconds on 200 Hz data)
    loc = _quiet_corner(ax, t, [y, *[c for _, c in curves if c is not None]])
    y0, y1 = ax.get_ylim()
    room = (0.12 + 0.07 * (1 + len(curves))) * (y1 - y0)  # headroom for the legend
    ax.set_ylim((y0, y1 + room) if loc.startswith("upper") else (y0 - room, y1))
    ax.legend(fontsize=7, loc=loc, frameon=True, framealpha=0.85, borderaxespad=0.3)
    lim = np.nanmax(np.abs(axr.get_ylim()))
    if np.isfinite(lim) and lim > 0:
        axr.set_ylim(-lim, lim)


def _draw_band(ax: Axes, td: TrialData, band: ResponseBand, color: str) -> None:
    """The 95 % model band of one trial (shaded) and the noise band's edges (dotted)."""
    for k, other in enumerate(band.trials):
        if other is td or (other.index == td.index and other.source == td.source):
            sl = band.slices()[k]
            break
    else:
        return
    t = np.asarray(td.time, float)[: sl.stop - sl.start] - float(td.t_step)
    ax.fill_between(
        t, band.model_low[sl], band.model_high[sl], color=color, alpha=0.3, lw=0, zorder=2.5
    )
    for edge in (band.noise_low[sl], band.noise_high[sl]):
        ax.plot(t, edge, color=color, lw=0.6, ls=":", zorder=2.6)


_Corner = Literal["upper right", "upper left", "lower left", "lower right"]


def _quiet_corner(ax: Axes, t: np.ndarray, ys: Sequence[np.ndarray]) -> _Corner:
    """The corner of ``ax`` (a box of 45 % x 30 %) that the fewest samples fall in."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    fx = np.concatenate([(t - x0) / (x1 - x0)] * len(ys))
    fy = (np.concatenate([np.asarray(v, float) for v in ys]) - y0) / (y1 - y0)
    right, top = fx > 0.55, fy > 0.7
    left, bottom = fx < 0.45, fy < 0.3
    counts: dict[_Corner, int] = {
        "upper right": int(np.sum(right & top)),
        "upper left": int(np.sum(left & top)),
        "lower right": int(np.sum(right & bottom)),
        "lower left": int(np.sum(left & bottom)),
    }
    return min(counts, key=lambda k: counts[k])


def _moving_mean(t: np.ndarray, y: np.ndarray, width_s: float) -> np.ndarray:
    """Centred moving mean over about ``width_s`` seconds (shows bias through the noise)."""
    if y.size < 3:
        return y
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    n = round(width_s / dt) if dt > 0 else 1
    n = max(1, min(n | 1, y.size if y.size % 2 else y.size - 1))  # odd: same length out
    if n == 1:
        return y
    kernel = np.ones(n) / n
    padded = np.pad(y, n // 2, mode="edge")
    return np.convolve(padded, kernel, mode="valid")


# --------------------------------------------------------------------------------------
# the paper's method: Figs. 7 and 8
# --------------------------------------------------------------------------------------
def plot_paper_method(
    classic: ClassicResult,
    path: str | Path | None = None,
    *,
    reference: Mapping[str, float] | None = None,
) -> Figure | Path:
    """The paper's Fig. 7 (thrust vs steady acceleration) and Fig. 8 (T_a vs thrust).

    Left: each trial's signed thrust ``f_in`` against its steady acceleration ``a_zc``,
    upward and downward trials marked differently, with the line through the origin
    whose slope is ``m_a`` and the free line ``f_in = m a_zc + c`` (an intercept far from
    zero hints at friction). Right: each trial's time constant ``T_a`` against the
    thrust magnitude, per direction, with the mean per thrust level joined and the
    median ``T_a`` as a horizontal line.

    Parameters
    ----------
    classic : ClassicResult
        The paper's method (:func:`balancer_id.identify.classic.paper_method`).
    path : str or Path, optional
        Write a PNG here (atomically) instead of returning the figure.
    reference : mapping, optional
        ``m_a`` and/or ``T_a`` of another identification (simulation matching) to draw
        dotted for comparison.

    Returns
    -------
    Figure or Path
    """
    reference = dict(reference or {})
    fig = _new_figure(10.5, 4.2)
    ax7, ax8 = fig.subplots(1, 2)
    ok = [p for p in classic.trials if np.isfinite(p.a_zc) and np.isfinite(p.T_a)]
    for ax in (ax7, ax8):
        _format_axes(ax)
    if not ok:
        for ax in (ax7, ax8):
            ax.text(
                0.5,
                0.5,
                "no trial could be evaluated",
                ha="center",
                va="center",
                transform=ax.transAxes,
                color="0.4",
            )
        return _finish(fig, path)

    _paper_fig7(ax7, classic, ok, reference)
    _paper_fig8(ax8, classic, ok, reference)
    return _finish(fig, path)


def _paper_fig7(
    ax7: Any, classic: ClassicResult, ok: list[Any], reference: Mapping[str, float]
) -> None:
    """The paper's Fig. 7: each trial's thrust against its steady acceleration, the lines."""
    a_all = np.array([p.a_zc for p in ok])
    span = max(float(np.max(np.abs(a_all))) * 1.15, 1e-3)
    lo = -span if np.any(a_all < 0) else 0.0
    hi = span if np.any(a_all > 0) else 0.0
    grid = np.linspace(lo, hi, 50)
    if np.isfinite(classic.m_a):
        se = classic.m_a_stderr
        se_txt = f" ± {se:.2g}" if np.isfinite(se) else ""
        ax7.plot(
            grid,
            classic.m_a * grid,
            color="black",
            linewidth=1.4,
            label=f"through origin: m_a = {classic.m_a:.4g}{se_txt} kg",
        )
    if np.isfinite(classic.free_slope) and np.isfinite(classic.intercept_N):
        ax7.plot(
            grid,
            classic.free_slope * grid + classic.intercept_N,
            color="0.35",
            linewidth=1.0,
            linestyle="--",
            label=f"free line: {classic.free_slope:.4g} kg, intercept {classic.intercept_N:+.3g} N",
        )
    if "m_a" in reference and np.isfinite(reference["m_a"]):
        ax7.plot(
            grid,
            reference["m_a"] * grid,
            color="#009E73",
            linewidth=1.2,
            linestyle=":",
            label=f"simulation matching: m_a = {reference['m_a']:.4g} kg",
        )
    for direction, (color, marker) in DIRECTION_STYLE.items():
        sel = [p for p in ok if p.direction == direction]
        if sel:
            ax7.scatter(
                [p.a_zc for p in sel],
                [p.thrust_N for p in sel],
                color=color,
                marker=marker,
                s=46,
                zorder=3,
                edgecolor="white",
                linewidth=0.5,
                label=f"{direction} ({len(sel)} trials)",
            )
    ax7.axhline(0, color="0.6", linewidth=0.6)
    ax7.axvline(0, color="0.6", linewidth=0.6)
    ax7.set_xlabel("steady acceleration a_zc (m/s²)", fontsize=9)
    ax7.set_ylabel("thrust f_in (N)", fontsize=9)
    ax7.set_title("equivalent mass (paper Fig. 7)", fontsize=10, loc="left")
    ax7.legend(fontsize=7, loc="upper left")


def _paper_fig8(
    ax8: Any, classic: ClassicResult, ok: list[Any], reference: Mapping[str, float]
) -> None:
    """The paper's Fig. 8: each trial's T_a against the thrust, per direction, the median."""
    table = classic.T_a_table()
    for direction, (color, marker) in DIRECTION_STYLE.items():
        sel = [p for p in ok if p.direction == direction]
        if not sel:
            continue
        ax8.scatter(
            [abs(p.thrust_N) for p in sel],
            [p.T_a for p in sel],
            color=color,
            marker=marker,
            s=34,
            alpha=0.55,
            zorder=3,
            edgecolor="none",
        )
        rows = [r for r in table if r["direction"] == direction and np.isfinite(_num(r["T_a"]))]
        ax8.plot(
            [_num(r["thrust_N"]) for r in rows],
            [_num(r["T_a"]) for r in rows],
            color=color,
            marker=marker,
            markersize=7,
            linewidth=1.3,
            label=f"{direction} (mean)",
        )
    if np.isfinite(classic.T_a):
        ax8.axhline(
            classic.T_a, color="black", linewidth=1.0, label=f"median T_a = {classic.T_a:.3g} s"
        )
    if "T_a" in reference and np.isfinite(reference["T_a"]):
        ax8.axhline(
            reference["T_a"],
            color="#009E73",
            linewidth=1.2,
            linestyle=":",
            label=f"simulation matching: T_a = {reference['T_a']:.3g} s",
        )
    ax8.set_xlim(0, max(abs(p.thrust_N) for p in ok) * 1.2)
    ax8.set_ylim(0, max(p.T_a for p in ok) * 1.3)
    ax8.set_xlabel("thrust |f_in| (N)", fontsize=9)
    ax8.set_ylabel("time constant T_a (s)", fontsize=9)
    ax8.set_title("time constant (paper Fig. 8)", fontsize=10, loc="left")
    ax8.legend(fontsize=7, loc="lower right")


# --------------------------------------------------------------------------------------
# per-trial refits
# --------------------------------------------------------------------------------------
def plot_per_trial(
    per_trial: Sequence[PerTrialFit],
    path: str | Path | None = None,
    *,
    joint: Mapping[str, float] | None = None,
) -> Figure | Path:
    """Each parameter fitted to each trial alone, against the thrust, per direction.

    Drift with thrust or direction shows what a joint fit over all trials averages away
    (the paper's Fig. 8 for every parameter). Parameters held in every refit are left out.

    Parameters
    ----------
    per_trial : sequence of PerTrialFit
        The refits (``fit(..., per_trial=True)``).
    path : str or Path, optional
        Write a PNG here (atomically) instead of returning the figure.
    joint : mapping, optional
        The joint fit's values, drawn as horizontal lines.

    Returns
    -------
    Figure or Path
    """
    joint = dict(joint or {})
    names = [
        n
        for n in (per_trial[0].values if per_trial else {})
        if any(p.stderr.get(n) is not None for p in per_trial)
    ]
    cols = max(1, min(len(names), 4))
    rows = max(1, -(-len(names) // cols))
    fig = _new_figure(2.9 * cols + 0.6, 2.7 * rows)
    if not names:
        ax = fig.add_subplot()
        ax.axis("off")
        ax.text(
            0.5,
            0.5,
            "no parameter varied in the per-trial refits",
            ha="center",
            va="center",
            color="0.4",
        )
        return _finish(fig, path)
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, name in zip(axes, names, strict=False):
        _format_axes(ax)
        for direction, (color, marker) in DIRECTION_STYLE.items():
            sel = [p for p in per_trial if p.direction == direction]
            if not sel:
                continue
            x = np.array([abs(p.thrust_N) for p in sel])
            y = np.array([p.values[name] for p in sel])
            e = np.array([p.stderr.get(name) or np.nan for p in sel], float)
            e = np.where(np.isfinite(e), e, 0.0)
            ax.errorbar(
                x,
                y,
                yerr=e,
                color=color,
                marker=marker,
                linestyle="none",
                markersize=6,
                capsize=2,
                elinewidth=0.8,
                label=direction,
            )
        _limit_to_values(ax, per_trial, name, joint.get(name))
        if name in joint and np.isfinite(joint[name]):
            ax.axhline(
                joint[name], color="black", linewidth=1.0, linestyle="--", label="all trials"
            )
        ax.set_title(name, fontsize=10, loc="left")
        ax.set_xlabel("thrust |f_in| (N)", fontsize=8)
        ax.set_xlim(left=0)
    for ax in axes[len(names) :]:
        ax.axis("off")
    axes[0].legend(fontsize=7)
    return _finish(fig, path)


def _limit_to_values(
    ax: Axes, per_trial: Sequence[PerTrialFit], name: str, joint: float | None
) -> None:
    """Y range from the estimates, so one huge error bar does not flatten the others."""
    vals = np.array([p.values[name] for p in per_trial], float)
    errs = np.array([p.stderr.get(name) or 0.0 for p in per_trial], float)
    if joint is not None:
        vals, errs = np.append(vals, joint), np.append(errs, 0.0)
    ok = np.isfinite(vals)
    if not ok.any():
        return
    vals, errs = vals[ok], np.where(np.isfinite(errs[ok]), errs[ok], 0.0)
    span = max(float(np.ptp(vals)), 0.1 * float(np.max(np.abs(vals))), 1e-12)
    errs = np.minimum(errs, 1.5 * span)  # longer bars run off the axes
    lo, hi = float(np.min(vals - errs)), float(np.max(vals + errs))
    pad = 0.08 * (hi - lo)
    ax.set_ylim(lo - pad, hi + pad)


# --------------------------------------------------------------------------------------
# improve: the error ladder
# --------------------------------------------------------------------------------------
def plot_error_ladder(
    steps: Sequence[Mapping[str, Any]],
    path: str | Path | None = None,
    *,
    chosen: str | None = None,
) -> Figure | Path:
    """RMSE (bars) and information criteria (lines) of each model step of ``improve``.

    Parameters
    ----------
    steps : sequence of mapping
        CONTRACT.md ``improve`` steps: keys ``model``, ``added``, ``rmse``, ``aic``,
        ``bic`` (``added`` empty or ``None`` for the starting model); a step with
        ``discovered`` true (a discovered force) is hatched and labelled so.
    path : str or Path, optional
        Write a PNG here (atomically) instead of returning the figure.
    chosen : str, optional
        The final model, highlighted (default: the step with the lowest BIC).

    Returns
    -------
    Figure or Path
    """
    steps = list(steps)
    fig = _new_figure(max(5.5, 1.25 * len(steps) + 3.0), 4.0)
    ax = fig.add_subplot()
    _format_axes(ax)
    if not steps:
        ax.axis("off")
        ax.text(0.5, 0.5, "no step", ha="center", va="center", color="0.4")
        return _finish(fig, path)
    x = np.arange(len(steps))
    labels = [(f"+ {s['added']}" if s.get("added") else str(s["model"])) for s in steps]
    labels = [
        f"{t}\n(discovered)" if s.get("discovered") else t
        for t, s in zip(labels, steps, strict=True)
    ]
    rmse = np.array([_num(s.get("rmse")) for s in steps])
    bic = np.array([_num(s.get("bic")) for s in steps])
    aic = np.array([_num(s.get("aic")) for s in steps])
    if chosen is None and np.any(np.isfinite(bic)):
        chosen = steps[int(np.nanargmin(bic))]["model"]
    colors = ["#0072B2" if s["model"] == chosen else "#9DB9D3" for s in steps]
    bars = ax.bar(x, np.nan_to_num(rmse), color=colors, width=0.6, zorder=2)
    for b, s in zip(bars, steps, strict=True):
        if s.get("discovered"):  # a discovered force: hatched
            b.set_hatch("//")
            b.set_edgecolor("#D55E00")
    _annotate_bars(ax, bars, rmse)
    ax.set_ylabel("RMSE (m/s²)", fontsize=9)
    ax.set_xticks(
        x,
        labels,
        rotation=20 if len(steps) > 4 else 0,
        ha="right" if len(steps) > 4 else "center",
        fontsize=8,
    )
    ax.set_ylim(0, np.nanmax(np.append(rmse, 1e-12)) * 1.2)
    _criteria_lines(ax, x, bic, aic)
    ax.set_title("error ladder: effects added one by one", fontsize=10, loc="left")
    return _finish(fig, path)


def _annotate_bars(ax: Any, bars: Any, rmse: np.ndarray) -> None:
    """Each bar's RMSE written above it."""
    for b, r in zip(bars, rmse, strict=True):
        if np.isfinite(r):
            ax.annotate(
                _sig(r, 3),
                (b.get_x() + b.get_width() / 2, b.get_height()),
                ha="center",
                va="bottom",
                fontsize=8,
                xytext=(0, 2),
                textcoords="offset points",
            )


def _criteria_lines(ax: Any, x: np.ndarray, bic: np.ndarray, aic: np.ndarray) -> None:
    """BIC and AIC of each step on a second axis, the lowest BIC starred."""
    ax2 = ax.twinx()
    ax2.tick_params(labelsize=8)
    ax2.spines["top"].set_visible(False)
    ax2.plot(x, bic, color="black", marker="o", linewidth=1.4, label="BIC", zorder=3)
    if np.any(np.isfinite(aic)):
        ax2.plot(
            x,
            aic,
            color="0.5",
            marker="s",
            markersize=4,
            linewidth=1.0,
            linestyle="--",
            label="AIC",
        )
    if np.any(np.isfinite(bic)):
        k = int(np.nanargmin(bic))
        ax2.plot(
            [x[k]],
            [bic[k]],
            marker="*",
            markersize=15,
            color="#D55E00",
            linestyle="none",
            label="lowest BIC",
            zorder=4,
        )
    ax2.set_ylabel("information criterion (lower is better)", fontsize=9)
    ax2.legend(fontsize=7, loc="upper right")


def _num(x: Any) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return float("nan")


# --------------------------------------------------------------------------------------
# robot coupling (paper section IV)
# --------------------------------------------------------------------------------------
def plot_coupling(
    coupling: Coupling,
    path: str | Path | None = None,
    *,
    params: Mapping[str, float] | None = None,
) -> Figure | Path:
    """Poles of the robot-balancer loop and, with the parameters, its stability chart.

    Left: the closed-loop poles of ``T_a m_a s^3 + (T_a D + m_a) s^2 + (D + c_r) s + k_r``
    in the complex plane (right half plane shaded: unstable). Right (when ``params``
    holds ``m_a``, ``T_a``, ``k_r``, ``c_r`` and optionally ``D0``): the Routh-Hurwitz
    boundary ``k_r = (T_a D + m_a)(D + c_r) / (T_a m_a)`` in the servo's (c_r, k_r)
    plane with the identified robot marked.

    Parameters
    ----------
    coupling : Coupling
        :func:`balancer_id.identify.coupling.coupling`.
    path : str or Path, optional
        Write a PNG here (atomically) instead of returning the figure.
    params : mapping, optional
        Identified parameter values.

    Returns
    -------
    Figure or Path
    """
    params = dict(params or {})
    chart = all(k in params for k in ("m_a", "T_a", "k_r", "c_r"))
    fig = _new_figure(10.0 if chart else 5.2, 4.0)
    axes = fig.subplots(1, 2 if chart else 1, squeeze=False).ravel()
    ax = axes[0]
    _format_axes(ax)
    poles = np.array(coupling.poles, dtype=complex)
    re_span = max(float(np.max(np.abs(poles.real))) if poles.size else 1.0, 1e-3) * 1.3
    im_span = max(float(np.max(np.abs(poles.imag))) if poles.size else 1.0, re_span * 0.3) * 1.3
    ax.axvspan(0, re_span, color="#D55E00", alpha=0.08, label="unstable")
    ax.scatter(
        poles.real, poles.imag, marker="x", s=70, color="black", zorder=3, label="closed-loop poles"
    )
    ax.axhline(0, color="0.5", linewidth=0.6)
    ax.axvline(0, color="0.5", linewidth=0.6)
    ax.set_xlim(-re_span, re_span)
    ax.set_ylim(-im_span, im_span)
    ax.set_xlabel("real part (1/s)", fontsize=9)
    ax.set_ylabel("imaginary part (rad/s)", fontsize=9)
    ax.set_title(
        f"poles: {coupling.oscillation_hz:.3g} Hz, ζ = {coupling.damping_ratio:.3g}, "
        f"margin {coupling.stability_margin:+.3g}",
        fontsize=9,
        loc="left",
    )
    ax.legend(fontsize=7, loc="lower left")
    if chart:
        ax = axes[1]
        _format_axes(ax)
        m, T, k, c = params["m_a"], params["T_a"], params["k_r"], params["c_r"]
        D = params.get("D0", 0.0)
        c_grid = np.linspace(0.0, max(3.0 * c, 1.0), 200)
        k_bound = (T * D + m) * (D + c_grid) / (T * m)
        top = max(float(k_bound.max()), 2.0 * k) * 1.05
        ax.fill_between(
            c_grid, k_bound, top, color="#D55E00", alpha=0.12, label="unstable (oscillates)"
        )
        ax.plot(c_grid, k_bound, color="#D55E00", linewidth=1.2, label="stability boundary")
        ax.plot(
            [c],
            [k],
            marker="o",
            color="#0072B2",
            markersize=8,
            linestyle="none",
            label="identified robot servo",
        )
        ax.set_xlim(c_grid[0], c_grid[-1])
        ax.set_ylim(0, top)
        ax.set_xlabel("servo damping c_r (N s/m)", fontsize=9)
        ax.set_ylabel("servo stiffness k_r (N/m)", fontsize=9)
        ax.set_title(f"Routh-Hurwitz (D = D0 = {D:.3g} kg/s)", fontsize=9, loc="left")
        ax.legend(fontsize=7, loc="upper left")
    return _finish(fig, path)


# --------------------------------------------------------------------------------------
# the posterior: a corner plot
# --------------------------------------------------------------------------------------
def plot_corner(posterior: Posterior, path: str | Path | None = None) -> Figure | Path:
    """The posterior's corner plot: each parameter's histogram and each pair's samples.

    The least-squares optimum is marked (lines) and the Wald 95 % interval drawn as dashed
    lines on the diagonal, so a curved or one-sided posterior stands out against them.

    Parameters
    ----------
    posterior : Posterior
        Samples (:func:`~balancer_id.identify.posterior.sample_posterior`).
    path : str or Path, optional
        Write a PNG here instead of returning the figure.

    Returns
    -------
    Figure or Path
    """
    import corner

    k = len(posterior.names)
    size = max(2.0, min(2.2 * k, 9.0))
    fig = _new_figure(size, size, layout=None)
    corner.corner(
        posterior.samples,
        labels=list(posterior.names),
        truths=[posterior.fitted[n] for n in posterior.names],
        truth_color=MODEL_COLORS[1],
        quantiles=[0.025, 0.5, 0.975],
        show_titles=True,
        title_fmt=".4g",
        title_kwargs={"fontsize": 8},
        label_kwargs={"fontsize": 9},
        fig=fig,
        color=MODEL_COLORS[0],
    )
    axes = np.array(fig.axes).reshape(k, k)
    for j, name in enumerate(posterior.names):
        wald = posterior.wald.get(name)
        if wald is not None:
            for end in wald:
                axes[j, j].axvline(end, color="0.3", ls="--", lw=0.8)
    return _finish(fig, path)
