"""Gravity's direction in the resting parts of a run: a sensor turned during the recording.

A phone put down flat, then on its side, then on its edge reads gravity on +z, then +y,
then +x. The resting parts of a with-g run (short windows of steady acceleration whose
magnitude is near g) are grouped by their gravity direction; more than one group means
the sensor was turned (issue 19.3). The reader warns (``read.turned_sensor``); the
segmentation gives each part its own vertical and leaves the turns out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from balancer_id.read.recording import Recording

#: Directions of gravity further apart than this (degrees) are different orientations.
TURN_DEG = 25.0
#: Window (s) over which rest is judged (steady acceleration of magnitude near g).
REST_WINDOW_S = 0.25
#: At rest, |a| within this fraction of g, and its short-window spread under this (m/s^2).
REST_G_TOLERANCE = 0.05
REST_SPREAD = 0.3
#: An orientation must rest at least this long in all (s) to count: a phone held still a
#: moment mid-turn is no orientation of its own.
MIN_PART_REST_S = 1.0
#: Samples per block of the resting test (bounds its working memory on long logs).
BLOCK = 1 << 18
#: The note names at most this many resting stretches.
MAX_SHOWN = 6


@dataclass(frozen=True)
class Orientation:
    """One orientation of the sensor: gravity's direction while it rests that way.

    Attributes
    ----------
    up : numpy.ndarray
        Unit vector of "up" (gravity's reading at rest) in the sensor frame.
    first, last : int
        First and last resting sample in this orientation.
    n_rest : int
        Resting samples in this orientation.
    sequence : tuple of (int, int, int)
        The run's rests in time order, as ``(orientation, first, last)``: the index of
        the orientation (in the returned list) and the rest's first and last sample,
        consecutive rests in one orientation joined (the same on every orientation).
    """

    up: np.ndarray
    first: int
    last: int
    n_rest: int
    sequence: tuple[tuple[int, int, int], ...] = ()


def orientations(rec: Recording, g: float) -> list[Orientation]:
    """The orientations a with-g run rests in, in order of their first rest.

    Parameters
    ----------
    rec : Recording
        One run; only a three-axis acceleration that includes gravity is looked at.
    g : float
        Gravity (m/s^2).

    Returns
    -------
    list of Orientation
        One per direction of gravity (those within :data:`TURN_DEG` of each other are
        one); empty when the run holds no with-g three-axis acceleration or no rest.
    """
    if rec.accel is None or not rec.accel_includes_gravity or rec.accel.ndim != 2:
        return []
    acc = np.asarray(rec.accel, dtype=float)
    if acc.shape[1] != 3 or acc.shape[0] < 8:
        return []
    ok = np.all(np.isfinite(acc), axis=1)
    if ok.sum() < 8:
        return []
    rate = rec.sample_rate_hz if np.isfinite(rec.sample_rate_hz) else 100.0
    w = max(3, round(REST_WINDOW_S * rate))
    rest, unit = _rest_directions(acc, ok, w, g)
    groups: list[list[int]] = []  # per orientation: [first, last, n]
    sums: list[np.ndarray] = []
    spans: list[tuple[int, int, int]] = []  # (orientation, first, last) of each rest
    for start, stop in _stretches(rest):
        if stop - start < w:
            continue
        d = unit[start:stop].sum(axis=0, dtype=np.float64)
        direction = d / np.linalg.norm(d)
        for j, s in enumerate(sums):
            if _angle(direction, s) <= TURN_DEG:
                sums[j] = s + d
                groups[j][1] = stop - 1
                groups[j][2] += stop - start
                break
        else:
            j = len(sums)
            sums.append(d)
            groups.append([start, stop - 1, stop - start])
        spans.append((j, start, stop - 1))
    min_rest = MIN_PART_REST_S * rate
    keep = [j for j, (_, _, n) in enumerate(groups) if n >= min_rest]
    out = [
        Orientation(sums[j] / np.linalg.norm(sums[j]), groups[j][0], groups[j][1], groups[j][2])
        for j in keep
    ]
    order = sorted(range(len(out)), key=lambda i: out[i].first)
    rank = {keep[i]: r for r, i in enumerate(order)}
    sequence = _sequence(spans, rank)
    return [
        Orientation(out[i].up, out[i].first, out[i].last, out[i].n_rest, tuple(sequence))
        for i in order
    ]


def _sequence(
    spans: list[tuple[int, int, int]], rank: dict[int, int]
) -> list[tuple[int, int, int]]:
    """The kept orientations in time order (rank, first, last), neighbours of the same
    orientation joined."""
    sequence: list[tuple[int, int, int]] = []
    for j, first, last in spans:
        if j not in rank:
            continue
        if sequence and sequence[-1][0] == rank[j]:
            sequence[-1] = (rank[j], sequence[-1][1], last)
        else:
            sequence.append((rank[j], first, last))
    return sequence


def _rest_directions(
    acc: np.ndarray, ok: np.ndarray, w: int, g: float
) -> tuple[np.ndarray, np.ndarray]:
    """Resting samples and the unit direction of the short-window mean acceleration.

    Computed in blocks of :data:`BLOCK` samples (each with ``w`` samples of its
    neighbours on either side, so that the moving windows are those of the whole run):
    the working arrays stay a block long whatever the log's length; the directions are
    kept as float32 (their sums over a rest are taken in float64).
    """
    from scipy import ndimage  # here: reading a log without gravity never needs it

    n = acc.shape[0]
    rest = np.zeros(n, dtype=bool)
    unit = np.zeros((n, 3), dtype=np.float32)
    for start in range(0, n, BLOCK):
        stop = min(n, start + BLOCK)
        lo, hi = max(0, start - w), min(n, stop + w)
        good = ok[lo:hi]
        filled = np.where(good[:, None], acc[lo:hi], 0.0)
        weight = np.maximum(ndimage.uniform_filter1d(good.astype(float), w, mode="nearest"), 1e-9)
        mean = ndimage.uniform_filter1d(filled, w, axis=0, mode="nearest") / weight[:, None]
        filled **= 2
        sq = ndimage.uniform_filter1d(filled, w, axis=0, mode="nearest") / weight[:, None]
        core = slice(start - lo, start - lo + stop - start)
        mean, sq, good = mean[core], sq[core], good[core]
        spread = np.sqrt(np.clip(sq - mean**2, 0.0, None).sum(axis=1))
        mag = np.linalg.norm(mean, axis=1)
        rest[start:stop] = (
            good & (np.abs(mag - g) <= REST_G_TOLERANCE * g) & (spread <= REST_SPREAD)
        )
        unit[start:stop] = mean / np.where(mag > 0, mag, 1.0)[:, None]
    return rest, unit


def _stretches(mask: np.ndarray) -> list[tuple[int, int]]:
    """The ``[start, stop)`` of every run of True in ``mask``, in order."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.view(np.int8), [0]))))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _angle(u: np.ndarray, v: np.ndarray) -> float:
    """Angle (degrees) between two vectors."""
    c = float(u @ v) / max(float(np.linalg.norm(u) * np.linalg.norm(v)), 1e-300)
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def axis_name(up: np.ndarray, axes: tuple[str, ...] = ("x", "y", "z")) -> str:
    """``"+z"`` or ``"-x, 12 deg off"``: the nearest signed axis of ``up``.

    Parameters
    ----------
    up : numpy.ndarray
        A direction in the sensor frame.
    axes : tuple of str
        Names of its components.

    Returns
    -------
    str
    """
    up = np.asarray(up, dtype=float)
    names = axes if len(axes) == up.size else ("x", "y", "z")[: up.size]
    j = int(np.argmax(np.abs(up)))
    norm = float(np.linalg.norm(up)) or 1.0
    angle = float(np.degrees(np.arccos(np.clip(abs(up[j]) / norm, -1.0, 1.0))))
    text = f"{'+' if up[j] >= 0 else '-'}{names[j]}"
    return text if angle <= 1.0 else f"{text}, {angle:.0f} deg off"


def turned_note_text(rec: Recording, parts: list[Orientation]) -> str:
    """The ``read.turned_sensor`` sentence for a run resting in several orientations.

    Parameters
    ----------
    rec : Recording
        The run.
    parts : list of Orientation
        Its orientations (more than one).

    Returns
    -------
    str
    """
    t = rec.time
    names = [axis_name(p.up, tuple(rec.accel_axes)) for p in parts]
    steps = parts[0].sequence
    shown = [f"{names[j]} ({t[a]:.1f}-{t[b]:.1f} s)" for j, a, b in steps[:MAX_SHOWN]]
    if len(steps) > MAX_SHOWN:
        shown.append(f"... ({len(steps)} resting stretches)")
    where = ", then ".join(shown)
    return (
        f"{rec.name}: the sensor was turned during the run: gravity along {where}; each "
        "part gets its own vertical and the turns are no trials (record with the sensor "
        "fixed to the load, or cut the log at the turns)"
    )
