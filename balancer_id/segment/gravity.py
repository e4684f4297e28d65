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

#: The level at rest replaces g where it differs from it by this many standard errors.
REST_Z = 3.0

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
        return _project_on_gravity(acc, w, g)
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


def _project_on_gravity(acc: np.ndarray, w: int, g: float) -> VerticalMotion:
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
    start = _initial_rest_level(proj, w)
    # measured where it differs from g beyond its own error (else g is as good, and a
    # run's noisy level would offset that run alone: a quantized sensor's)
    if start is not None and REST_Z * start[1] < abs(start[0] - g) <= LOCAL_G_SPAN:
        # the data's own gravity: local g (9.78-9.83) and a small zero offset, not a
        # force; removing a fixed g would leave it as an acceleration the model lacks
        method = (
            f"gravity direction from {how} ({int(rest.sum())} samples), {tilt:.1f} deg "
            f"from the nearest axis; the magnitude at rest before the motion, "
            f"{start[0]:.4f} m/s^2, removed (within {LOCAL_G_SPAN:g} of g={g:g}: the "
            "local gravity)"
        )
        proj -= start[0]
        return VerticalMotion(proj, up, rest, method)
    method = (
        f"gravity direction from {how} ({int(rest.sum())} samples), "
        f"{tilt:.1f} deg from the nearest axis; resting level {offset:+.3f} m/s^2 after "
        f"removing g={g:g}"
    )
    proj -= g
    return VerticalMotion(proj, up, rest, method)


def _initial_rest_level(proj: np.ndarray, w: int) -> tuple[float, float] | None:
    """The level of the log's first stretch at rest and its standard error, or None when
    the log does not start at rest.

    Only the stretch before anything moves is surely at rest: the "resting" samples
    (quiet, ``|a|`` near g) also hold the slow parts of a motion. The stretch runs from
    the first sample while the moving mean over ``w`` samples stays within
    :data:`REST_SIGMAS` of the first window's noise (of the mean) from its level; at least
    :data:`MIN_REST_WINDOWS` windows of it are needed.
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
