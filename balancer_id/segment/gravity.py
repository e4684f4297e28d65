"""Vertical motion from a recording: gravity direction, projection, gravity removal."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import UsageError
from balancer_id.read.orientation import TURN_DEG, Orientation, axis_name, orientations
from balancer_id.read.recording import Recording
from balancer_id.segment.robust import fill_nan, local_std, n_samples, rate_of, smooth

#: Accepted values of the ``vertical`` setting.
VERTICAL_CHOICES = ("auto", "x", "y", "z", "+x", "+y", "+z", "-x", "-y", "-z")

#: Short window (s) of the resting test, and how far |a| may sit from g at rest (fraction).
REST_WINDOW_S = 0.25
REST_G_TOLERANCE = 0.05

#: A resting magnitude this close to ``g`` (m/s^2) is the local gravity (9.78 at the
#: equator to 9.83 at the poles, against the default 9.8) and is removed as measured;
#: farther, the level is left for the diagnosis to name (a gain, a zero offset).
LOCAL_G_SPAN = 0.03

#: The log's first stretch is at rest while its moving mean stays within this many noise
#: sigmas (of the mean) of the first windows' level.
REST_SIGMAS = 5.0

#: Prior spread (m/s^2) of a resting level around ``g`` within :data:`LOCAL_G_SPAN`: a
#: measured level is pulled towards ``g`` by its noise against this (empirical Bayes),
#: never taken or left by a significance test (issue 31: a noisy level was removed just
#: where its noise carried it past 3 standard errors, a selection that offset those runs
#: alone by 1.5 % of their motion and bent a clean fit's A and D0 past their intervals).
LEVEL_PRIOR_SD = LOCAL_G_SPAN / 2

#: Windows of rest the first stretch needs before its level is used.
MIN_REST_WINDOWS = 1


@dataclass(frozen=True)
class VerticalMotion:
    """The vertical acceleration of one recording.

    Attributes
    ----------
    accel : numpy.ndarray
        Vertical acceleration (m/s^2), gravity removed, up positive, shape ``(n,)``.
    up : numpy.ndarray
        Unit vector of "up" in the sensor frame, one entry per accel column.
    rest : numpy.ndarray
        Boolean mask of quiet samples (low short-window variance; with g, |a| near g).
    method : str
        How the vertical was found, for notes and reports.
    sign_known : bool
        False when the sign of ``up`` is a convention (linear acceleration, automatic
        axis); the force step or signed thrusts may flip it later.
    axis_known : bool
        False when the up axis itself is a guess: the principal direction of a linear
        acceleration, or the one axis of a sensor without gravity (assumed vertical).
    part_ups : numpy.ndarray or None
        A sensor turned during the run (issue 19.3): "up" of each orientation, shape
        ``(parts, axes)``; ``up`` is then the one rested in longest.
    part_of : numpy.ndarray or None
        The orientation of every sample (an index into ``part_ups``).
    turns : tuple of (int, int)
        Stretches ``[start, stop)`` where the sensor was turning: their vertical is
        interpolated from either side and no trial may start or run through them.
    """

    accel: np.ndarray
    up: np.ndarray
    rest: np.ndarray
    method: str
    sign_known: bool = True
    axis_known: bool = True
    part_ups: np.ndarray | None = None
    part_of: np.ndarray | None = None
    turns: tuple[tuple[int, int], ...] = ()
    #: The projection's level at rest before the motion and its standard error (a with-g
    #: log projected on one "up"), and the level removed from it (m/s^2).
    rest_level: tuple[float, float] | None = None
    removed: float | None = None

    def up_at(self, i: int) -> np.ndarray:
        """ "Up" at sample ``i`` (the orientation the sensor was in there).

        Parameters
        ----------
        i : int
            A sample index.

        Returns
        -------
        numpy.ndarray
        """
        if self.part_ups is None or self.part_of is None or not 0 <= i < self.part_of.size:
            return self.up
        return self.part_ups[int(self.part_of[i])]

    def flipped(self, why: str) -> VerticalMotion:
        """Return the same motion with the up direction reversed, noting ``why``.

        Parameters
        ----------
        why : str
            The reason for the flip (a force step, signed thrusts), appended to
            :attr:`method`.

        Returns
        -------
        VerticalMotion
            ``accel`` and ``up`` negated, the same rest mask, and ``sign_known`` True.
        """
        return VerticalMotion(
            -self.accel,
            -self.up,
            self.rest,
            f"{self.method}; {why}",
            True,
            self.axis_known,
            None if self.part_ups is None else -self.part_ups,
            self.part_of,
            self.turns,
            self.rest_level,
            self.removed,
        )


def vertical_motion(
    rec: Recording, *, vertical: str = "auto", g: float = G_DEFAULT
) -> VerticalMotion | None:
    """Find the vertical acceleration of a recording.

    With-g logs (specific force, +g up at rest): the up direction is the mean unit
    acceleration vector over the resting samples, the vertical motion is the projection
    on it minus ``g``; no axis is assumed vertical. Linear-acceleration ("without g")
    logs: ``vertical`` names the axis, or ``"auto"`` takes the principal direction of
    the smoothed motion (SVD); its sign is then a convention (``sign_known=False``).
    A single accel column is used as is (its resting mean removed when it holds g).

    Parameters
    ----------
    rec : Recording
        One run of a log.
    vertical : {"auto", "x", "y", "z", "+x", ..., "-z"}, optional
        The vertical axis, or ``"auto"``; a ``-`` makes that axis point down (linear
        acceleration; with g, gravity gives the sign).
    g : float, optional
        Gravity (m/s^2) subtracted from the projection of a with-g log.

    Returns
    -------
    VerticalMotion or None
        None when the recording has no acceleration channel.

    Raises
    ------
    UsageError
        When ``vertical`` is not one of :data:`VERTICAL_CHOICES` or names a missing axis.
    """
    check_vertical(vertical)
    if rec.accel is None:
        return None
    acc = np.asarray(rec.accel, dtype=float)
    if acc.ndim == 1:
        acc = acc[:, None]
    finite = [bool(np.isfinite(acc[:, j]).any()) for j in range(acc.shape[1])]
    if not any(finite) or acc.shape[0] < 2:
        return None
    if not np.isfinite(acc).all():  # a whole finite log is used as it is, not copied
        # an empty column reads nothing: zeros, so that "up" keeps one entry per column
        acc = np.column_stack(
            [fill_nan(acc[:, j]) if ok else np.zeros(acc.shape[0]) for j, ok in enumerate(finite)]
        )
    axes = tuple(rec.accel_axes) if len(rec.accel_axes) == acc.shape[1] else ("x", "y", "z")
    rate = rec.sample_rate_hz if np.isfinite(rec.sample_rate_hz) else rate_of(rec.time)
    w = n_samples(REST_WINDOW_S, rate if np.isfinite(rate) else 200.0, minimum=3)

    if vertical != "auto":
        return _given_axis(rec, acc, axes, vertical, w)
    if acc.shape[1] == 1:
        m = _single_axis(acc, 0, w, rec.accel_includes_gravity, f"single axis {axes[0]}")
        if rec.accel_includes_gravity:
            return m
        # one axis without gravity (a motion sensor): nothing says it is vertical nor
        # which way it counts; both are assumed
        return dataclasses.replace(
            m,
            axis_known=False,
            sign_known=False,
            method=f"{m.method}; axis assumed vertical, positive up",
        )
    if rec.accel_includes_gravity:
        parts = orientations(rec, g) if acc.shape[1] == 3 else []
        if len(parts) > 1:
            return _project_turned(acc, parts, w, g, axes)
        return _project_on_gravity(acc, w, g, _pushed_from(rec.force, w))
    return _principal_axis(acc, axes, w)


def _given_axis(
    rec: Recording, acc: np.ndarray, axes: tuple[str, ...], vertical: str, w: int
) -> VerticalMotion:
    """The motion along the axis the user gave (``-z``: up is minus z)."""
    axis = vertical.lstrip("+-")
    if axis not in axes:
        raise UsageError(
            f"vertical axis {vertical!r} is not in the accel columns {', '.join(axes)}"
        )
    col = axes.index(axis)
    m = _single_axis(acc, col, w, rec.accel_includes_gravity, f"axis {vertical} as given")
    if vertical.startswith("-") and not rec.accel_includes_gravity:
        return VerticalMotion(-m.accel, -m.up, m.rest, f"{m.method}; up is -{axis}", True)
    return m


def check_vertical(vertical: str) -> None:
    """Raise :class:`UsageError` unless ``vertical`` is one of :data:`VERTICAL_CHOICES`.

    Parameters
    ----------
    vertical : str
        The ``--vertical`` choice: ``"auto"`` or an axis with an optional sign (``"-z"``).

    Raises
    ------
    UsageError
        For any other value.
    """
    if vertical not in VERTICAL_CHOICES:
        raise UsageError(f"vertical must be one of {', '.join(VERTICAL_CHOICES)}, not {vertical!r}")


def _quiet(x: np.ndarray, w: int) -> np.ndarray:
    """Samples whose short-window std is low compared with the log's typical value."""
    s = local_std(x, w)
    return s <= max(4.0 * float(np.median(s)), 0.05)


def _single_axis(acc: np.ndarray, col: int, w: int, with_g: bool, what: str) -> VerticalMotion:
    """One column as the vertical; with g, its sign and resting mean come from rest."""
    x = acc[:, col]
    rest = _quiet(x, w)
    up = np.zeros(acc.shape[1])
    if not with_g:
        up[col] = 1.0
        return VerticalMotion(x.copy(), up, rest, f"{what} (linear acceleration)")
    base = float(np.median(x[rest])) if rest.any() else float(np.median(x))
    sign = 1.0 if base >= 0 else -1.0
    up[col] = sign
    method = f"{what}; resting mean {base:+.3f} m/s^2 removed"
    return VerticalMotion(sign * (x - base), up, rest, method)


def _project_on_gravity(
    acc: np.ndarray, w: int, g: float, pushed: int | None = None
) -> VerticalMotion:
    """Up = mean unit vector over resting samples; vertical = projection minus g."""
    mag = np.linalg.norm(acc, axis=1)
    quiet = _quiet(mag, w)
    near_g = np.abs(smooth(mag, w) - g) <= REST_G_TOLERANCE * g
    rest = quiet & near_g
    if rest.sum() >= w:
        how = "resting samples"
    elif quiet.sum() >= w:
        rest = quiet
        how = f"quiet samples (none reads |a| near g={g:g}; median |a| {np.median(mag):.3f})"
    else:
        rest = np.ones(mag.size, dtype=bool)
        how = "all samples (no resting part found)"
    np.copyto(mag, 1.0, where=mag <= 0)  # |a| from here on only divides
    u = _mean_direction(acc, mag, rest)
    up = u / np.linalg.norm(u)
    tilt = float(np.degrees(np.arccos(np.clip(np.max(np.abs(up)), -1.0, 1.0))))
    proj = acc @ up
    offset = float(np.median(proj[rest])) - g
    start = _initial_rest_level(proj, w, pushed)
    head = (
        f"gravity direction from {how} ({int(rest.sum())} samples), {tilt:.1f} deg from "
        "the nearest axis"
    )
    if start is not None and abs(start[0] - g) <= LOCAL_G_SPAN:
        # the data's own gravity: local g (9.78-9.83) and a small zero offset, not a
        # force; removing a fixed g would leave it as an acceleration the model lacks
        level = shrunk_level(start[0], start[1], g)
        proj -= level
        return VerticalMotion(
            proj, up, rest, f"{head}; {_level_text(level, start, g)}", rest_level=start,
            removed=level,
        )  # fmt: skip
    method = f"{head}; resting level {offset:+.3f} m/s^2 after removing g={g:g}"
    proj -= g
    return VerticalMotion(proj, up, rest, method, rest_level=start, removed=g)


def _level_text(level: float, start: tuple[float, float], g: float, runs: int = 1) -> str:
    """How the resting level removed was found, for the vertical's method."""
    where = "at rest before the motion" if runs == 1 else f"at rest, pooled over {runs} runs"
    return (
        f"the magnitude {where}, {start[0]:.4f} ± {start[1]:.4f} m/s^2, read as "
        f"{level:.4f} m/s^2 (its noise weighed against the local gravity's spread within "
        f"{LOCAL_G_SPAN:g} of g={g:g}) and removed"
    )


def shrunk_level(level: float, se: float, g: float) -> float:
    """A measured resting level pulled towards ``g`` by its noise (empirical Bayes).

    The level is ``g`` (local gravity, a small zero offset) plus a spread of
    :data:`LEVEL_PRIOR_SD`; a measurement of standard error ``se`` is weighted
    ``prior^2 / (prior^2 + se^2)``: a quiet sensor's level is taken as read, a noisy
    one's stays near ``g``, and none is taken or left by a test on its own noise (which
    would keep just the noisiest readings).

    Parameters
    ----------
    level : float
        Measured level (m/s^2).
    se : float
        Its standard error (m/s^2).
    g : float
        Gravity assumed (m/s^2).

    Returns
    -------
    float
        The level to remove (m/s^2).
    """
    prior = LEVEL_PRIOR_SD**2
    weight = prior / (prior + max(float(se), 0.0) ** 2)
    return float(g + weight * (level - g))


#: The runs' levels differ by more than their noise (a random effect: a sensor remounted
#: between runs) only where their scatter passes Cochran's Q test at this level; below it
#: they are one level, and no run keeps its own noisy reading. Strict, because a reading's
#: standard error is too small for a quantized or coloured sensor (the sample
#: quantized_sensor.csv scatters at Q = 14 on 4 degrees of freedom; pooled, its fit's D0
#: comes back within 1 %, run by run 17 % low).
HETEROGENEITY_ALPHA = 1e-4


def _between_runs(levels: np.ndarray, se2: np.ndarray) -> float:
    """The variance of the runs' true levels about their mean (DerSimonian-Laird), 0 when
    Cochran's Q does not pass :data:`HETEROGENEITY_ALPHA`."""
    from scipy.special import gammainccinv  # chi-square's quantile (scipy.stats: slow import)

    w = 1.0 / np.maximum(se2, 1e-18)
    mean = float(np.sum(w * levels) / np.sum(w))
    q = float(np.sum(w * (levels - mean) ** 2))
    k = levels.size
    if q <= 2.0 * float(gammainccinv(0.5 * (k - 1), HETEROGENEITY_ALPHA)):
        return 0.0
    return max((q - (k - 1)) / float(np.sum(w) - np.sum(w**2) / np.sum(w)), 0.0)


def pool_rest_levels(motions: list[VerticalMotion | None], g: float) -> list[VerticalMotion | None]:
    """The runs of one log with one resting level: the sensor's and the place's.

    Each run's level before its motion is a noisy reading of the same local gravity and
    zero offset; a run alone removes its own (:func:`shrunk_level`), which offsets each
    run by its own noise. Pooled (random effects: the runs' levels may differ by more
    than their noise, e.g. a sensor remounted between runs, and then each keeps its
    share of its own reading), the level's error shrinks with the number of runs.

    Parameters
    ----------
    motions : list of VerticalMotion or None
        The runs' verticals, in order (None: no acceleration).
    g : float
        Gravity assumed (m/s^2).

    Returns
    -------
    list of VerticalMotion or None
        The same list; when the pooled level is within :data:`LOCAL_G_SPAN` of ``g``,
        the runs with a measured level replaced by copies with it removed (a run's own
        reading past the span is no test of the level: its noise, not the place).
    """
    idx = [
        i
        for i, m in enumerate(motions)
        if m is not None
        and m.rest_level is not None
        and m.removed is not None
        and m.part_ups is None
    ]
    if len(idx) < 2:
        return motions
    levels = np.array([motions[i].rest_level[0] for i in idx])  # type: ignore[index,union-attr]
    se2 = np.array([motions[i].rest_level[1] for i in idx]) ** 2  # type: ignore[index,union-attr]
    between = _between_runs(levels, se2)
    w = 1.0 / np.maximum(se2 + between, 1e-18)
    pooled = float(np.sum(w * levels) / np.sum(w))
    pooled_se = float(np.sqrt(1.0 / np.sum(w)))
    if abs(pooled - g) > LOCAL_G_SPAN:  # not the local gravity: the diagnosis names it
        return motions
    centre = shrunk_level(pooled, pooled_se, g)
    out = list(motions)
    # a run with no rest of its own before its motion shares the others' level
    unread = [
        i
        for i, m in enumerate(motions)
        if m is not None and m.rest_level is None and m.removed is not None
        and m.part_ups is None
    ]  # fmt: skip
    for i, level, s2 in [*zip(idx, levels, se2, strict=True), *((i, centre, 0.0) for i in unread)]:
        m = motions[i]
        assert m is not None and m.removed is not None
        own = between / (between + s2) if between + s2 > 0 else 0.0
        new = centre + own * (float(level) - centre)
        method = m.method.split("; the magnitude")[0].split("; resting level")[0]
        out[i] = dataclasses.replace(
            m,
            accel=m.accel + (m.removed - new),
            removed=new,
            method=f"{method}; {_level_text(new, (pooled, pooled_se), g, len(idx))}",
        )
    return out


def _pushed_from(force: np.ndarray | None, w: int) -> int | None:
    """The first sample where the force leaves its level at the log's start, or None.

    Its moving mean over ``w`` samples leaves the first window's level by
    :data:`REST_SIGMAS` of its noise (of the mean), as the acceleration's rest does; half
    a window back from there (the moving mean sees the change early by that much) the
    load was surely not yet pushed. A lag's slow rise hides the motion's first part under
    the acceleration's noise, and the acceleration's own rest then holds it.
    """
    if force is None:
        return None
    f = np.asarray(force, dtype=float)
    if f.size < 2 * w or w < 3 or not np.isfinite(f[:w]).all():
        return None
    f = fill_nan(f) if not np.isfinite(f).all() else f
    head = f[:w]
    sigma = float(np.median(np.abs(np.diff(head))) / (0.6745 * np.sqrt(2.0)))
    mean = smooth(f, w)
    away = np.abs(mean - float(np.median(head))) > REST_SIGMAS * max(sigma, 1e-9) / np.sqrt(w)
    away[: w // 2] = False
    if not away.any():
        return None
    return max(int(np.argmax(away)) - w // 2, 0)


def _initial_rest_level(
    proj: np.ndarray, w: int, pushed: int | None = None
) -> tuple[float, float] | None:
    """The level of the log's first stretch at rest and its standard error, or None when
    the log does not start at rest.

    Only the stretch before anything moves is surely at rest: the "resting" samples
    (quiet, ``|a|`` near g) also hold the slow parts of a motion. The stretch runs from
    the first sample while the moving mean over ``w`` samples stays within
    :data:`REST_SIGMAS` of the first window's noise (of the mean) from its level; at least
    :data:`MIN_REST_WINDOWS` windows of it are needed. It ends before ``pushed`` (the
    sample the force first moves at, when known).
    """
    if proj.size < MIN_REST_WINDOWS * w or w < 3:
        return None
    head = proj[: MIN_REST_WINDOWS * w]
    # the noise from the whole log's differences too: a dozen differences of one window
    # can read it half as large, and the stretch then ends at the noise's own wander
    # (a 50 Hz log's rest cut to 0.2 s, its level dropped and g=9.8 kept against a log
    # at 9.8067: an offset the diagnosis named "effect missing: bias")
    sigma = float(
        max(np.median(np.abs(np.diff(head))), np.median(np.abs(np.diff(proj))))
        / (0.6745 * np.sqrt(2.0))
    )
    if not np.isfinite(sigma):
        return None
    level0 = float(np.median(head))
    mean = smooth(proj, w)
    away = np.abs(mean - level0) > REST_SIGMAS * max(sigma, 1e-6) / np.sqrt(w) + 1e-9
    away[: w // 2] = False  # the moving mean's edge sees a half window only
    first = int(np.argmax(away)) if away.any() else proj.size
    end = max(first - w, 0)  # the moving mean sees the motion half a window early
    if pushed is not None:
        end = min(end, pushed)  # and nothing after the force first moved
    if end < MIN_REST_WINDOWS * w:
        return None
    # the mean, trimmed of spikes: a median snaps to a quantized sensor's levels, while
    # the noise dithers the mean to the level between them
    rest = np.sort(proj[:end])
    cut = rest.size // 20
    kept = rest[cut : rest.size - cut]
    return float(np.mean(kept)), float(np.std(kept) / np.sqrt(kept.size))


#: Samples per block of :func:`_mean_direction` (its temporaries stay this long).
BLOCK = 1 << 16


def _mean_direction(acc: np.ndarray, mag: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """Mean of ``acc / mag`` over the ``rest`` samples, a block at a time (no copy of a
    long log's resting samples)."""
    total = np.zeros(acc.shape[1])
    for i in range(0, acc.shape[0], BLOCK):
        r = rest[i : i + BLOCK]
        total += (acc[i : i + BLOCK][r] / mag[i : i + BLOCK][r, None]).sum(axis=0)
    return total / max(int(rest.sum()), 1)


def _project_turned(
    acc: np.ndarray, parts: list[Orientation], w: int, g: float, axes: tuple[str, ...]
) -> VerticalMotion:
    """A sensor turned during the run: each sample is projected on the "up" of the
    orientation nearest its own (smoothed) direction; where that is more than
    :data:`~balancer_id.read.orientation.TURN_DEG` off every orientation the sensor is
    turning, and the vertical there is interpolated (no motion is read from a turn)."""
    ups = np.array([p.up for p in parts])
    mag = np.linalg.norm(acc, axis=1)
    unit = acc / np.where(mag > 0, mag, 1.0)[:, None]
    smooth_unit = ndimage.uniform_filter1d(unit, w, axis=0, mode="nearest")
    smooth_unit /= np.maximum(np.linalg.norm(smooth_unit, axis=1), 1e-12)[:, None]
    cos = smooth_unit @ ups.T
    part_of = np.argmax(cos, axis=1)
    angle = np.degrees(np.arccos(np.clip(cos[np.arange(acc.shape[0]), part_of], -1.0, 1.0)))
    turning = ndimage.binary_dilation(angle > TURN_DEG, iterations=w)
    proj = np.einsum("ij,ij->i", acc, ups[part_of])
    vertical = proj - g
    vertical[turning] = np.nan
    vertical = fill_nan(vertical)
    labels, _ = ndimage.label(turning)
    turns = tuple((int(sl[0].start), int(sl[0].stop)) for sl in ndimage.find_objects(labels))
    quiet = _quiet(mag, w) & ~turning
    main = int(np.argmax([p.n_rest for p in parts]))
    names = ", ".join(axis_name(u, axes) for u in ups)
    method = (
        f"gravity direction per orientation ({len(parts)}: {names}; the sensor was turned "
        f"{len(turns)} time(s), the turns left out)"
    )
    return VerticalMotion(vertical, ups[main], quiet, method, True, True, ups, part_of, turns)


def _principal_axis(acc: np.ndarray, axes: tuple[str, ...], w: int) -> VerticalMotion:
    """Linear acceleration: the principal direction of the sustained motion (SVD).

    Transients (catches, knocks: high short-window variance, in any direction) are
    left out, the rest averaged over ``4 w`` samples so that quantization averages out.
    """
    keep = _quiet(np.linalg.norm(acc, axis=1), w)
    idx = np.arange(acc.shape[0])
    sm = np.column_stack(
        [
            ndimage.uniform_filter1d(np.interp(idx, idx[keep], acc[keep, j]), 4 * w)
            if keep.sum() >= 2
            else acc[:, j]
            for j in range(acc.shape[1])
        ]
    )
    sm -= np.median(sm, axis=0)
    mag = np.linalg.norm(sm, axis=1)
    moving = mag > 4.0 * float(np.median(mag)) + 1e-12
    use = sm[moving] if moving.sum() >= w else sm
    _, sv, vt = np.linalg.svd(use, full_matrices=False)
    up = vt[0] / np.linalg.norm(vt[0])
    j = int(np.argmax(np.abs(up)))
    if up[j] < 0:
        up = -up
    share = float(sv[0] ** 2 / max(np.sum(sv**2), 1e-300))
    angle = float(np.degrees(np.arccos(np.clip(abs(up[j]), -1.0, 1.0))))
    x = acc @ up
    method = (
        f"linear acceleration: principal direction of the motion (SVD of {use.shape[0]} "
        f"smoothed samples, {100 * share:.0f}% of the variance), {angle:.1f} deg from "
        f"+{axes[j]}; sign taken along +{axes[j]} until the force step or signed thrusts fix it"
    )
    return VerticalMotion(x, up, _quiet(x, w), method, sign_known=False, axis_known=False)
