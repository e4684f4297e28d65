"""Thrust onsets from the vertical acceleration alone (logs without a force channel).

The acceleration is split into rest and activity: a ``accel_window_s`` moving mean that
leaves the resting level by more than ``max(min_accel_step, accel_k_sigma * noise)`` is
active. The resting level is a long running median of the moving mean, refined by a
running median inside each rest stretch (so slow drift is followed). Active stretches
closer than ``merge_s`` are one. A trial is an active stretch that starts from rest and
lasts at least ``min_trial_s``; the stretch that follows it with the opposite sign and
lasts under ``max_catch_s`` is its catch (the person stopping the load), not a trial.
The onset is the start of the first-order rise that best fits the acceleration there.

An onset must stand out of the noise measured near it, coloured noise included (issue
19.4): a ride's or a hand's sway in travel leaves the resting level too. A change after
which the acceleration is back at rest is a stop or steady travel, not a new thrust. A
catch must stop the motion (its impulse takes back the velocity gained). A motion goes on
over a short drop-out: after it, its catch is still a catch, never a new trial (issue
17.6).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from balancer_id.segment.robust import (
    block_noise,
    block_range,
    clipped_mean,
    fill_nan,
    n_samples,
    odd,
    rate_of,
)
from balancer_id.segment.steps import Detection, Step, StepSettings

#: Window (s) of the running median that gives the first resting baseline.
BASELINE_S = 30.0

#: Time constants (s) tried when placing the onset of a first-order rise.
_RISE_T = np.geomspace(0.1, 1.0, 25)

#: Half-width (s) of the window over which a change of the acceleration while moving is
#: measured (:func:`step_trend`): longer than the drive lags (0.1-1 s) take to show.
CHANGE_HALF_S = 1.0

#: Lowest rate (Hz) at which changes while moving are searched: below it a drive lag of
#: 0.1-0.3 s spans too few samples for the step-over-trend test to tell a thrust change
#: from the decay, and only departures from rest are onsets (as before that test existed).
MIN_TREND_RATE_HZ = 50.0

#: Highest rate (Hz) of the onset search; faster logs are searched on block means first.
SEARCH_HZ = 200

#: An onset while moving must stand out of the noise measured near it
#: (:func:`level_noise`, over this many :data:`CHANGE_HALF_S` on either side, the quieter
#: side counting), not only of the log's resting noise: a ride's or a hand's sway in
#: travel is no thrust change.
LOCAL_NOISE_HALVES = 8
#: ... by this many standard deviations of that noise.
LOCAL_K_SIGMA = 4.0

#: After a change while moving, an acceleration back within this fraction of the change
#: from the resting level is a stop or steady travel (an elevator reaching its speed, a
#: winding-speed limit), not a new thrust level.
BACK_AT_REST_FRACTION = 0.2
#: ... or within this many noise standard deviations of a one-``CHANGE_HALF_S`` mean
#: measured around the change (:func:`level_noise`).
REST_K_SIGMA = 3.0

#: A motion not yet caught goes on over a drop-out up to this long (s): after it, a stretch
#: of the motion's opposite sign is its catch, never a new trial (issue 17.6).
MAX_CARRY_GAP_S = 1.0

#: A catch takes back the velocity gained since the onset to within this factor either
#: way (the integrals of the acceleration over the resting level; drift and tilt blur them).
CATCH_IMPULSE_FRACTION = 0.25


@dataclass(frozen=True)
class _Stretch:
    """An active stretch ``[start, stop)`` and the sign of its first part."""

    start: int
    stop: int
    sign: int
    reverses: bool


@dataclass(frozen=True)
class _AccelLevels:
    """The acceleration as the detector reads it: rate, gap-filled samples, noise, clip,
    moving-mean window and mean, threshold and resting level."""

    rate: float
    a: np.ndarray
    sigma: float
    clip: float
    w: int
    mean: np.ndarray
    thr: float
    rest: np.ndarray


def _accel_levels(time: np.ndarray, accel: np.ndarray, settings: StepSettings) -> _AccelLevels:
    """Measure the noise, the moving mean, the threshold and the resting level."""
    rate = rate_of(time)
    a = fill_nan(accel)
    block = n_samples(settings.noise_block_s, rate, 5)
    sigma = block_noise(a, block, floor=1e-3)
    clip = max(5 * sigma, block_range(a, block))
    w = odd(n_samples(settings.accel_window_s, rate, 3))
    # a plain moving mean: a median filter would undo the dithering of a quantized signal
    mean = ndimage.uniform_filter1d(a, w, mode="nearest")
    noise = max(block_noise(mean, block, floor=1e-4), sigma / np.sqrt(w))
    thr = max(settings.min_accel_step, settings.accel_k_sigma * noise)
    return _AccelLevels(rate, a, sigma, clip, w, mean, thr, _resting_level(mean, thr, rate))


class _DepartureScan:
    """The departures from rest of a log, gap-free stretch by stretch, with the state a
    motion not yet caught carries over a short drop-out (issue 17.6): its sign
    (``awaiting``), the onset of the trial it belongs to (``owner``; -1: begun at a
    drop-out), and whether its impulse is cut (``cut``)."""

    def __init__(
        self, time: np.ndarray, lv: _AccelLevels, settings: StepSettings, det: Detection
    ) -> None:
        self.time, self.lv, self.settings, self.det = time, lv, settings, det
        self.n = lv.a.size
        self.carried, self.owner = 0, -1
        self.awaiting, self.cut, self.moving_at_start = 0, False, False

    def goes_on(self, hi: int, sign: int) -> bool:
        """Whether the motion at the end of the stretch ending at ``hi`` goes on past the
        drop-out there: a short gap, and the acceleration off rest with the same sign
        after it (a motion cut by a drop-out, not a short stretch)."""
        n, lv, time = self.n, self.lv, self.time
        if hi >= n or time[hi] - time[hi - 1] > MAX_CARRY_GAP_S:
            return False
        after = lv.mean[hi : min(n, hi + lv.w)] - lv.rest[hi : min(n, hi + lv.w)]
        return after.size > 0 and float(np.median(after)) * sign > lv.thr

    def stretch(self, lo: int, hi: int) -> list[tuple[int, int]]:
        """Scan the gap-free stretch ``[lo, hi)``: its departures join ``det.steps``;
        returns its catches (the catch, the onset of the motion it stops)."""
        lv = self.lv
        dev = lv.mean[lo:hi] - lv.rest[lo:hi]
        stretches = _active(dev, lv.thr, n_samples(self.settings.merge_s, lv.rate))
        short_gap = lo > 0 and self.time[lo] - self.time[lo - 1] <= MAX_CARRY_GAP_S
        self.awaiting = self.carried if short_gap else 0  # sign of a trial not yet caught
        self.cut = bool(self.awaiting)  # its motion began before this stretch: impulse cut
        self.moving_at_start = bool(self.awaiting)
        catches: list[tuple[int, int]] = []
        for st in stretches:
            self._active_stretch(lo, hi, dev, st, catches)
        self.carried = self.awaiting
        return catches

    def _active_stretch(
        self, lo: int, hi: int, dev: np.ndarray, st: _Stretch, catches: list[tuple[int, int]]
    ) -> None:
        """One active stretch: a motion under way after a drop-out, a catch, a stretch too
        short, or a trial's departure."""
        s, w = self.settings, self.lv.w
        start, stop = lo + st.start, lo + st.stop
        length = (stop - start) / self.lv.rate
        if start - lo < w and lo > 0 and (not self.awaiting or st.sign == self.awaiting):
            self._under_way(lo, dev, st, catches)
            return
        since = max(self.owner, lo) - lo if self.owner >= 0 else 0
        if (
            self.awaiting
            and st.sign == -self.awaiting
            and length < s.max_catch_s
            and _stops(dev, since, st.start, st.stop, cut=self.cut or st.stop >= hi - lo - w)
        ):
            self.awaiting = 0
            catches.append((start, self.owner))
            self.det.reject("a catch")
            return
        cut_short = st.stop >= hi - lo - w and self.goes_on(hi, st.sign)
        if start - lo < w or (length < s.min_trial_s and not cut_short):
            self.det.reject("too short or too close to a gap or the run's edge")
            return  # a short stretch of an uncaught trial's sign is its motion
        self._departure(lo, hi, dev, st, catches)

    def _under_way(
        self, lo: int, dev: np.ndarray, st: _Stretch, catches: list[tuple[int, int]]
    ) -> None:
        """Moving when the drop-out ended: a motion under way, not a departure."""
        if not self.awaiting:
            self.awaiting, self.owner, self.cut, self.moving_at_start = st.sign, -1, True, True
        if st.reverses:  # ... and caught inside the stretch
            back_rel = np.flatnonzero(dev[st.start : st.stop] * st.sign < -self.lv.thr)[0]
            back = st.start + int(back_rel)
            if (st.stop - back) / self.lv.rate < self.settings.max_catch_s:
                catches.append((lo + back, self.owner))
                self.awaiting = 0
        self.det.reject("under way after a drop-out")

    def _departure(
        self, lo: int, hi: int, dev: np.ndarray, st: _Stretch, catches: list[tuple[int, int]]
    ) -> None:
        """A trial's onset (where the first-order rise starts) and its response, and its
        catch when it is caught inside its own stretch."""
        lv, rate, w = self.lv, self.lv.rate, self.lv.w
        # the mean leaves rest up to ~1 s after a slow, small rise begins
        k = rise_onset(self.time, lv.a, lo, hi, lo + st.start, n_samples(1.0, rate, 3))
        pre = lv.a[max(lo, k - w) : k]
        post = lv.a[k : min(hi, k + n_samples(self.settings.response_s, rate))]
        if pre.size < 3 or post.size < 3:
            self.det.reject("too close to a gap or the run's edge")
            return
        dep = clipped_mean(post, lv.clip) - clipped_mean(pre, lv.clip)
        z = abs(dep) / (lv.sigma * np.sqrt(1.0 / pre.size + 1.0 / post.size))
        self.det.steps.append(Step(int(k), float("nan"), float(dep), float(z), "accel"))
        self.awaiting, self.owner, self.cut = (0 if st.reverses else st.sign), int(k), False
        if st.reverses:  # caught inside its own stretch? the catch ends the motion
            back = st.start + int(np.flatnonzero(dev[st.start : st.stop] * st.sign < -lv.thr)[0])
            short = (st.stop - back) / rate < self.settings.max_catch_s
            ends_cut = st.stop >= hi - lo - w  # the drop-out cuts the catch
            if short and _stops(dev, k - lo, back, st.stop, cut=ends_cut):
                catches.append((lo + back, int(k)))


def detect_accel_steps(
    time: np.ndarray, accel: np.ndarray, breaks: np.ndarray, settings: StepSettings
) -> Detection:
    """Find thrust onsets from the vertical acceleration alone.

    Parameters
    ----------
    time, accel : numpy.ndarray
        Sample times (s) and vertical acceleration (m/s^2).
    breaks : numpy.ndarray
        First sample after each gap.
    settings : StepSettings
        Detector constants.

    Returns
    -------
    Detection
        Steps with ``source="accel"``, ``size`` NaN and ``response`` the change of the
        acceleration over the first ``response_s`` after the onset.
    """
    lv = _accel_levels(time, accel, settings)
    n = lv.a.size
    det = Detection([], float(np.max(np.abs(lv.mean - lv.rest))) if n else 0.0, lv.thr, "m/s^2")
    edges = np.concatenate([[0], breaks, [n]]).astype(int)
    half = n_samples(CHANGE_HALF_S, lv.rate, 3)
    scan = _DepartureScan(time, lv, settings, det)
    for lo, hi in itertools.pairwise(edges):
        if hi - lo < 2 * lv.w:
            continue
        first = len(det.steps)
        catches = scan.stretch(lo, hi)
        if hi - lo > 4 * half and lv.rate >= MIN_TREND_RATE_HZ:
            kept = _changes_while_moving(
                time, lv.a, lv.rest, lo, hi, det.steps[first:], catches, half, lv.thr,
                lv.sigma, lv.clip, lv.rate, settings, moving_at_start=scan.moving_at_start,
                earlier={st.onset for st in det.steps[:first]},
            )  # fmt: skip
            det.steps[first:] = kept
    return det


def step_trend(accel: np.ndarray, half: int) -> tuple[np.ndarray, float]:
    """The step of the acceleration at every sample, over its local linear trend.

    Fits ``b + m (x - k) + s H(x - k)`` by least squares over the ``2 half`` samples
    ``[k - half, k + half)`` and returns ``s``: a thrust change while moving makes a
    first-order change of the acceleration toward a new level on top of a slow trend
    (the viscous decay), which ``s`` measures and the trend does not bias.

    Parameters
    ----------
    accel : numpy.ndarray
        Acceleration without NaN (m/s^2).
    half : int
        Half-width of the window (samples).

    Returns
    -------
    step : numpy.ndarray
        ``s`` at every sample (NaN within ``half`` of the ends).
    gain : float
        The standard error of ``s`` for unit white noise (``s``'s noise is ``gain sigma``).
    """
    n = accel.size
    out = np.full(n, np.nan)
    if n <= 2 * half:
        return out, float("nan")
    x = np.arange(n, dtype=float)
    c0 = np.concatenate([[0.0], np.cumsum(accel)])
    c1 = np.concatenate([[0.0], np.cumsum(accel * x)])
    ks = np.arange(half, n - half)
    u = np.arange(-half, half, dtype=float)
    normal = np.array(
        [
            [2.0 * half, u.sum(), half],
            [u.sum(), u @ u, u[half:].sum()],
            [half, u[half:].sum(), half],
        ]
    )
    inv = np.linalg.inv(normal)
    sy = c0[ks + half] - c0[ks - half]
    suy = (c1[ks + half] - c1[ks - half]) - ks * sy
    shy = c0[ks + half] - c0[ks]
    out[ks] = inv[2, 0] * sy + inv[2, 1] * suy + inv[2, 2] * shy
    return out, float(np.sqrt(inv[2, 2]))


class _MotionScan:
    """The stages of :func:`_changes_while_moving` over one gap-free stretch ``[lo, hi)``:
    the step-over-trend measure, its peaks, and the tests a departure or a peak must pass
    while moving."""

    def __init__(
        self,
        time: np.ndarray,
        a: np.ndarray,
        rest: np.ndarray,
        span: tuple[int, int],
        catches: list[tuple[int, int]],
        half: int,
        levels: tuple[float, float, float],
        rate: float,
        settings: StepSettings,
    ) -> None:
        self.time, self.a, self.rest = time, a, rest
        self.lo, self.hi = span
        self.catches, self.half = catches, half
        self.thr, self.sigma, self.clip = levels
        self.step, self.gain = step_trend(a[self.lo : self.hi], half)
        self.level = max(settings.min_accel_step, settings.accel_k_sigma * self.sigma * self.gain)
        self.mag = np.nan_to_num(np.abs(self.step))
        self.catch_s = n_samples(settings.max_catch_s, rate)
        self.after, self.span = n_samples(0.5, rate), n_samples(settings.response_s, rate)
        self.w_pre = odd(n_samples(settings.accel_window_s, rate, 3))

    def local_noise(self, k: int) -> tuple[float, float]:
        """The noise near ``k`` (issue 19.4), as a white-equivalent sample noise and the
        noise of a ``half``-long mean: travel (a ride's sway, a hand's tremor) can be
        noisier, and slower, than the rest the log's ``sigma`` was measured on."""
        a, lo, hi, half = self.a, self.lo, self.hi, self.half
        side = LOCAL_NOISE_HALVES * half
        before = level_noise(a[max(lo, k - half - side) : max(lo, k - half)], half, self.sigma)
        after = level_noise(a[min(hi, k + half) : min(hi, k + half + side)], half, self.sigma)
        return min(before, after)  # another motion's edge on one side is no noise

    def peaks(self) -> list[int]:
        """The step's peaks above the level, largest first taken, each masking its side
        lobes within two half-widths; in time order."""
        mag, half = self.mag, self.half
        peaks: list[int] = []
        taken = np.zeros(mag.size, dtype=bool)
        for j in np.argsort(-mag):
            if mag[j] <= self.level:
                break
            if taken[j]:
                continue
            peaks.append(self.lo + int(j))
            taken[max(0, j - 2 * half) : j + 2 * half] = True
        return sorted(peaks)

    def abrupt(self, k: int) -> bool:
        """A catch is abrupt: a "catch" the step does not confirm is the level following
        the decay."""
        lo, half = self.lo, self.half
        return bool(np.any(self.mag[max(0, k - lo - half) : k - lo + half] > self.level))

    def events(self, steps: list[Step]) -> list[tuple[int, int, Step | None]]:
        """Departures (0), catches (1) and peaks (2), in time order."""
        # (near a drop-out the step cannot be measured: a catch there is taken as it is)
        kept = [c for c, _ in self.catches if self.abrupt(c) or self.hi - c <= 2 * self.half]
        return sorted(
            [(st.onset, 0, st) for st in steps]
            + [(c, 1, None) for c in kept]
            + [(p, 2, None) for p in self.peaks()]
        )

    def stands_out(self, st: Step) -> bool:
        """A departure while moving must stand out of the noise of the means around it
        (a ride's sway leaves the resting level too), not only of the resting noise,
        and reach a level away from rest (a return to rest is steady travel)."""
        _, per_mean = self.local_noise(st.onset)  # noise of a `half`-long mean
        pre_n, post_n = max(self.w_pre, 1), max(self.span, 1)
        se = per_mean * np.sqrt(self.half / pre_n + self.half / post_n)
        if abs(st.response) <= LOCAL_K_SIGMA * se:
            return False
        return self.new_level(st.onset, st.response, per_mean, (self.rest[st.onset],))

    def new_level(self, k: int, change: float, per_mean: float, levels: tuple[float, ...]) -> bool:
        """Whether the acceleration after ``k`` (up to the next catch) sits away from every
        level of ``levels`` (rest, the level before the motion): else the motion stopped
        or travels steadily, and no thrust level is new."""
        after = self.after
        ends = [c for c, _ in self.catches if c > k + after]
        seg = self.a[k + after : min(self.hi, k + self.span, *ends[:1])]
        if seg.size < 3:
            return False
        tol = max(self.thr, BACK_AT_REST_FRACTION * abs(change), REST_K_SIGMA * per_mean)
        reached = clipped_mean(seg, self.clip)
        return min(abs(reached - x) for x in levels) > tol

    def departs_while_moving(self, k: int, st: Step, out: list[Step]) -> bool:
        """A departure while moving must be abrupt (else it is the resting level following
        the slow decay), not already found, and stand out."""
        near = bool(out) and abs(k - out[-1].onset) <= 2 * self.half
        return self.abrupt(k) and not near and self.stands_out(st)

    def passed_over(
        self, k: int, out: list[Step], moving: bool, caught: int, steps: list[Step]
    ) -> bool:
        """Whether the peak at ``k`` is no new change: the one that started this motion
        (or its side lobe), a catch, or found from the resting level."""
        half = self.half
        if out and abs(k - out[-1].onset) <= 2 * half:
            return True  # the change that started this motion, or its side lobe
        if caught - half <= k <= caught + self.catch_s + half:
            return True  # the catch itself
        if any(0 <= c - k <= half for c, _ in self.catches):
            return True  # a catch ahead, inside the window that measured the change
        # at rest, departures are found from the resting level
        return not moving and bool(out or any(abs(k - d.onset) <= 2 * half for d in steps))

    def change_at(self, k: int, out: list[Step], moving: bool, earlier: set[int] | frozenset[int]
                  ) -> Step | None:
        """The thrust change at the peak ``k``, or None where it does not stand out of the
        noise around it or reach a new level."""
        a, lo, half = self.a, self.lo, self.half
        start = out[-1].onset if moving and out else k  # the motion's first onset
        if moving and not out and earlier:  # carried over a drop-out: its onset is back
            start = max(earlier)
        first = lo if start >= lo else 0  # (the rest before a carried motion is back too)
        pre = a[max(first, start - 2 * half) : max(first, start - half // 2)]
        still = clipped_mean(pre, self.clip) if pre.size >= half // 2 else self.rest[k]
        dep = float(self.step[k - lo])
        noise, mean_noise = self.local_noise(k)
        if abs(dep) <= LOCAL_K_SIGMA * noise * self.gain:
            return None  # does not stand out of the noise around it (steady travel)
        # a motion carried over a drop-out may also have stopped at the resting level
        levels = (still, self.rest[k]) if start < lo else (still,)
        if not self.new_level(k, dep, mean_noise, levels):
            return None  # the motion stopped or travels steadily: no new thrust level
        onset = rise_onset(self.time, a, lo, self.hi, k, half)
        if onset - lo < 3 or self.hi - onset < 3:
            return None
        return Step(int(onset), float("nan"), dep, abs(dep) / (noise * self.gain), "accel")


def _changes_while_moving(
    time: np.ndarray,
    a: np.ndarray,
    rest: np.ndarray,
    lo: int,
    hi: int,
    steps: list[Step],
    catches: list[tuple[int, int]],
    half: int,
    thr: float,
    sigma: float,
    clip: float,
    rate: float,
    settings: StepSettings,
    *,
    moving_at_start: bool = False,
    earlier: set[int] | frozenset[int] = frozenset(),
) -> list[Step]:
    """The onsets of one gap-free stretch, with the thrust changes made while moving.

    The departures from rest (``steps``) start the motions; a motion lasts until a catch
    (or the stretch's end). Inside a motion, a thrust change is a peak of
    :func:`step_trend` above the threshold (the largest first; others within two
    half-widths of it are its side lobes), after which the acceleration does not sit at
    the resting level (a stop is no change). A departure inside a motion that no such
    peak confirms is the resting level following the slow decay, not an onset.
    """
    scan = _MotionScan(
        time, a, rest, (lo, hi), catches, half, (thr, sigma, clip), rate, settings
    )
    stopped = dict(catches)  # catch -> the onset of the motion it stops
    out: list[Step] = []
    moving = moving_at_start  # a motion carried over a drop-out
    caught = -(10**12)  # start of the last catch
    for k, kind, st in scan.events(steps):
        if kind == 1:
            owner = stopped[k]
            if owner >= 0 and owner not in earlier and not any(d.onset == owner for d in out):
                continue  # the catch of a departure not kept (a sway) stops no motion
            moving, caught = False, k
        elif kind == 0:
            # a departure from rest starts a motion; one while moving must pass the tests
            if st is not None and (not moving or scan.departs_while_moving(k, st, out)):
                out.append(st)
                moving = True
        elif not scan.passed_over(k, out, moving, caught, steps):
            found = scan.change_at(k, out, moving, earlier)
            if found is not None:
                out.append(found)
                moving = True
    return sorted(out, key=lambda st: st.onset)


def level_noise(x: np.ndarray, block: int, sigma: float) -> tuple[float, float]:
    """The noise of ``x`` as it moves a mean over ``block`` samples, coloured noise included.

    The means of ``x`` over every ``block``-long window are differenced with those of the
    window that follows (a steady level cancels, a trend leaves a constant that is taken
    out; a single change moves the differences over ``2 block`` samples only) and the
    robust spread of the differences (1.4826 x their median absolute deviation) is the
    noise of a difference of two means, ``sqrt(2)`` times that of one. White noise of
    standard deviation ``s`` gives ``s / sqrt(block)`` per mean; slow sway (a ride, a
    hand) gives more.

    Parameters
    ----------
    x : numpy.ndarray
        Samples without NaN.
    block : int
        Length of the mean (samples).
    sigma : float
        The log's resting noise per sample: the floor of the white-equivalent noise.

    Returns
    -------
    white : float
        The per-sample noise a white signal would need to move means as much (at least
        ``sigma``).
    mean : float
        The noise of one ``block``-long mean (at least ``sigma / sqrt(block)``).
    """
    block = max(int(block), 1)
    floor = sigma / np.sqrt(block)
    if x.size < 3 * block:
        return sigma, floor
    c = np.concatenate([[0.0], np.cumsum(np.asarray(x, dtype=float))])
    means = (c[block:] - c[:-block]) / block
    d = means[block:] - means[:-block]
    one = 1.4826 * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2.0)
    return max(sigma, one * np.sqrt(block)), max(floor, one)


def _resting_level(mean: np.ndarray, thr: float, rate: float) -> np.ndarray:
    """Resting level at every sample.

    A first baseline is the running median of the moving mean over ``BASELINE_S`` (on a
    10 Hz copy), which trials of a few seconds do not move. Quiet samples lie within
    ``thr`` of it; inside each quiet stretch the level is a running median over 5 s
    (drift is followed); an active sample keeps the level of the rest before it.
    """
    step = max(1, round(rate / 10))
    coarse = mean[::step]
    base = ndimage.median_filter(coarse, size=odd(max(3, round(BASELINE_S * 10))), mode="reflect")
    base = np.interp(np.arange(mean.size), np.arange(coarse.size) * step, base)
    labels, _ = ndimage.label(np.abs(mean - base) <= thr)
    out = np.full(mean.size, np.nan)
    span = n_samples(5.0, rate, 3)
    for sl in ndimage.find_objects(labels):
        seg = mean[sl]
        out[sl] = ndimage.median_filter(seg, size=min(seg.size, span), mode="nearest")
    have = np.flatnonzero(np.isfinite(out))
    if have.size == 0:
        return base
    last = np.maximum.accumulate(np.where(np.isfinite(out), np.arange(mean.size), -1))
    return out[np.where(last >= 0, last, have[0])]


def _stops(dev: np.ndarray, onset: int, start: int, stop: int, *, cut: bool = False) -> bool:
    """Whether the opposite stretch ``[start, stop)`` can be the catch of the motion that
    began at ``onset``: a catch stops the load, so its impulse (the integral of the
    acceleration over the resting level) takes back the velocity gained since the onset,
    to within a factor :data:`CATCH_IMPULSE_FRACTION` either way. A ride's sway or a
    hand's tremor in steady travel leaves the resting level too, but stops nothing; a
    thrust reversed while moving takes back far more. When the motion began before a
    drop-out, or the catch is cut by one (``cut``), the impulses are unknown: an
    opposite stretch (what the caller checks) is taken as the catch.
    """
    if cut:
        return True
    gained = float(np.sum(dev[max(onset, 0) : start]))
    taken = float(np.sum(dev[start:stop]))
    share = abs(taken) / max(abs(gained), 1e-300)
    return gained * taken < 0 and CATCH_IMPULSE_FRACTION <= share <= 1 / CATCH_IMPULSE_FRACTION


def _active(dev: np.ndarray, thr: float, merge: int) -> list[_Stretch]:
    """Stretches where ``|dev| > thr``, those closer than ``merge`` samples joined."""
    labels, _ = ndimage.label(np.abs(dev) > thr)
    spans = ndimage.find_objects(labels)
    joined: list[list[int]] = []
    for sl in spans:
        start, stop = sl[0].start, sl[0].stop
        if joined and start - joined[-1][1] < merge:
            joined[-1][1] = stop
        else:
            joined.append([start, stop])
    out = []
    for start, stop in joined:
        seg = dev[start:stop]
        big = seg[np.abs(seg) > thr]
        sign = int(np.sign(big[0])) if big.size else 1
        out.append(_Stretch(start, stop, sign, bool(np.any(big * sign < 0))))
    return out


def rise_onset(time: np.ndarray, accel: np.ndarray, lo: int, hi: int, peak: int, w: int) -> int:
    """Onset of the first-order rise best fitting the acceleration near ``peak``.

    Fits ``b + A (1 - exp(-(t - t0)/T))`` (zero before ``t0``) by least squares for every
    candidate ``t0`` (a sample in ``[peak - w, peak + w/4]``) and every ``T`` of a grid
    over 0.1..1 s, over the samples from ``w/2`` before the earliest candidate to ``w``
    after ``peak``. Above :data:`SEARCH_HZ` the search runs on block means (at most
    :data:`SEARCH_HZ`) and is then refined at the full rate within one block of the
    coarse onset, so the cost grows linearly with the rate, not with its square.

    Parameters
    ----------
    time, accel : numpy.ndarray
        Sample times (s) and vertical acceleration (m/s^2).
    lo, hi : int
        Gap-free stretch ``[lo, hi)`` holding ``peak``.
    peak : int
        Centre of the search.
    w : int
        Half-width scale of the search (samples).

    Returns
    -------
    int
        Sample index of the onset.
    """
    k_lo, k_hi = max(lo + 2, peak - w), min(hi - 2, peak + w // 4)
    f_lo, f_hi = max(lo, k_lo - w // 2), min(hi, peak + w)
    t = time[f_lo:f_hi]
    y = accel[f_lo:f_hi] - accel[f_lo:f_hi].mean()
    # w spans ~1 s: blocks of `step` samples bring the search to at most SEARCH_HZ
    step = max(1, w // SEARCH_HZ)
    if step == 1 or k_hi - k_lo < 4 * step:
        ks = np.arange(k_lo, k_hi + 1)
        j, _ = _best_rise(t, y, time[ks], _RISE_T)
        return int(ks[j])
    nb = t.size // step
    tb = t[: nb * step].reshape(nb, step).mean(axis=1)
    yb = y[: nb * step].reshape(nb, step).mean(axis=1)
    first = f_lo + np.arange(nb) * step  # first sample of each block
    cand = np.flatnonzero((first >= k_lo) & (first <= k_hi))
    j, i_tau = _best_rise(tb, yb, time[first[cand]], _RISE_T)
    k = int(first[cand[j]])
    taus = _RISE_T[i_tau : i_tau + 1]
    while step > 1:  # refine within one block, ~10 candidates per stage
        stride = max(1, step // 10)
        ks = np.arange(max(k_lo, k - step), min(k_hi, k + step) + 1, stride)
        j, _ = _best_rise(t, y, time[ks], taus)
        k, step = int(ks[j]), stride if stride > 1 else 1
    return k


def _best_rise(t: np.ndarray, y: np.ndarray, t0: np.ndarray, taus: np.ndarray) -> tuple[int, int]:
    """Index of the onset ``t0`` and of the time constant with the least squared error."""
    lag = np.clip(t[None, :] - t0[:, None], 0.0, None)
    best = (np.inf, 0, 0)
    n, sy, yy = y.size, y.sum(), y @ y
    for i, tau in enumerate(taus):
        rise = -np.expm1(-lag / tau)  # (candidates, samples)
        # least squares on [1, rise]: closed form of the 2x2 normal equations per row
        s1, s2 = rise.sum(axis=1), (rise * rise).sum(axis=1)
        ry = rise @ y
        det = n * s2 - s1 * s1
        ok = det > 1e-12
        b = np.where(ok, (s2 * sy - s1 * ry) / np.where(ok, det, 1.0), sy / n)
        amp = np.where(ok, (n * ry - s1 * sy) / np.where(ok, det, 1.0), 0.0)
        sse = yy - b * sy - amp * ry
        j = int(np.argmin(sse))
        if sse[j] < best[0]:
            best = (float(sse[j]), j, i)
    return best[1], best[2]
