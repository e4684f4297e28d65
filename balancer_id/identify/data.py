"""Trials as the fitters see them: simulation inputs plus the measured acceleration."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.ndimage import median_filter

from balancer_id.errors import IdentificationError, UsageError
from balancer_id.identify.input_noise import noise_sigma, piecewise_constant
from balancer_id.model.spec import Model
from balancer_id.segment.decimate import Decimation, decimate_trial
from balancer_id.segment.robust import rate_of
from balancer_id.segment.steps import StepSettings
from balancer_id.segment.trial import Trial
from balancer_id.simulation.engine import DEFAULT_SUBSTEPS, PackedTrials, TrialInput
from balancer_id.simulation.inputs import Thrust, Trapezoid

#: Centred median filter on the measured force before it drives the model (s): removes
#: spikes and quantization flicker, keeps a step's edge where it is (no time shift).
FORCE_MEDIAN_S = 0.025


@dataclass
class TrialData:
    """One trial ready for fitting.

    Attributes
    ----------
    index : int
        Trial index (over all logs of a fit).
    thrust_N : float
        Signed thrust level (N).
    direction : str
        ``"up"`` or ``"down"``.
    t_step : float
        Onset of the thrust (s).
    input : TrialInput
        What drives the simulation (state ``input.x0`` at ``input.time[0]``).
    accel : numpy.ndarray
        Measured vertical acceleration at ``input.time`` (m/s^2).
    source : str
        File and run the trial came from.
    continues : bool
        The simulation continues from the end of the previous trial of the same run (a
        session): its state at ``input.time[0]`` is where the model left the previous one.
    previous : TrialData or None
        For a trial that ``continues``: the trial of the session it continues. The
        session before it (:attr:`lead_in`) is built from this chain only when asked for,
        so a long session holds each sample once.
    decimation : Decimation or None
        How the trial was decimated for fitting (None: fitted at the log's own rate).
    level_se_N : float or None
        Standard error (N) of the held thrust level read from the noisy force (its
        noise over the samples after the onset), for a step trial driven by its measured
        force; None otherwise. The level's error moves the whole response at once
        (errors in variables); :mod:`~balancer_id.identify.structure` allows for it.
    zero_se_N : float or None
        Standard error (N) of the force's zero, read in the rest before the first step of
        the trial's chain (its 20 %-trimmed mean) and subtracted from every level after it:
        an error shared by a session's trials. None where ``level_se_N`` is None.
        :mod:`~balancer_id.identify.level_errors` carries both into the standard errors.
    """

    index: int
    thrust_N: float
    direction: str
    t_step: float
    input: TrialInput
    accel: np.ndarray
    source: str = ""
    continues: bool = False
    previous: TrialData | None = field(default=None, repr=False)
    decimation: Decimation | None = None
    level_se_N: float | None = None
    zero_se_N: float | None = None
    #: How far the force moves over the rest where its zero is read (N, a line's rise
    #: over that stretch) and that rise's standard error; None where ``zero_se_N`` is.
    zero_drift_N: tuple[float, float] | None = None

    @property
    def lead_in(self) -> TrialInput | None:
        """The session from its start up to this trial (None unless it ``continues``).

        Lets a continuing trial be simulated without the previous trials in the same fit.
        Built on each call from the chain of :attr:`previous` trials.
        """
        if not self.continues or self.previous is None:
            return None
        chain: list[TrialInput] = []
        trial: TrialData | None = self.previous
        while trial is not None:
            chain.append(trial.input)
            trial = trial.previous if trial.continues else None
        return join_inputs(chain[::-1])

    @property
    def time(self) -> np.ndarray:
        """Sample times (s)."""
        return self.input.time

    @property
    def rate_hz(self) -> float:
        """The rate the trial is fitted at (Hz): its samples' median rate."""
        return rate_of(self.input.time) if self.input.time.size >= 2 else float("nan")

    @classmethod
    def from_trial(
        cls, trial: Trial, index: int | None = None, trajectory: Trapezoid | None = None
    ) -> TrialData:
        """Build from one segmented :class:`~balancer_id.segment.trial.Trial`, alone.

        The model is driven by the trial's measured force (see :func:`measured_thrust`)
        where there is one, the thrust was not given and no robot move drives the trial
        (a robot's force is its servo's answer, not an input), else by a step of
        ``trial.thrust_N`` at ``trial.t_step``. Samples without an acceleration value
        (blank cells of a multi-rate export) are left out. A trial faster than 400 Hz is
        first decimated to 200-400 Hz, anti-aliased
        (:func:`~balancer_id.segment.decimate.decimate_trial`). A trial that continues a
        session is simulated from rest here; :func:`from_trials` chains it.

        Parameters
        ----------
        trial : Trial
            A segmented trial.
        index : int, optional
            Index to give the trial; None keeps ``trial.index``.
        trajectory : Trapezoid, optional
            The robot's reference move, evaluated at the sample times (``servo``).

        Returns
        -------
        TrialData

        Raises
        ------
        IdentificationError
            When the trial has (almost) no acceleration samples.
        """
        return from_trials([trial], trajectory=trajectory, chain=False, index=index)[0]


def measured_thrust(
    time: np.ndarray,
    force: np.ndarray,
    held: bool = False,
    fine: tuple[np.ndarray, np.ndarray] | None = None,
    smooth: bool = False,
) -> Thrust:
    """The measured operating force as the model's input ``u(t)``, never shifted in time.

    A centred median over :data:`FORCE_MEDIAN_S` removes spikes and flicker and keeps
    step edges in place. A held force (a step trial's) changes halfway between the two
    samples that bracket each change (:func:`centred_changes`): the step happened
    somewhere between them, on average halfway. Holding each sample's value until the
    next put every change half a sample late: the acceleration led its force by half a
    sample on every step log, which the timing test called a late force channel on clean
    logs (issue 31). A guided move's force (``smooth``) holds each sample's value from
    halfway back to the sample before (:func:`centred_samples`): it changes continuously,
    and held from its sample on, it drove the model half a sample late. A window's force
    keeps each sample's value until the next: held at each interval's mean instead, a
    real load-cell rig's lag (its sensors' filters, about a sample) came out as a drive
    lag of one sample that its data cannot determine, where the hold's half sample had
    absorbed it.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s), increasing.
    force : numpy.ndarray
        Operating force at those times (N, up positive); NaN samples are interpolated.
    held : bool
        The force is held between changes (a step trial's): its noise is averaged out
        between the changes it shows
        (:func:`~balancer_id.identify.input_noise.piecewise_constant`, errors in
        variables).
    fine : tuple of numpy.ndarray, optional
        The trial's time and force before decimation: a held force's changes are found
        and placed at that rate (an anti-aliased step spreads over several decimated
        samples, and its pieces would each be held).
    smooth : bool
        The force changes smoothly (a guided move's): its noise is smoothed out
        (:func:`smooth_force`, errors in variables).

    Returns
    -------
    Thrust
        One breakpoint per sample.
    """
    time = np.asarray(time, float)
    u = np.asarray(force, float)
    ok = np.isfinite(u)
    if not ok.all():
        u = np.interp(time, time[ok], u[ok]) if ok.any() else np.zeros_like(time)
    dt = float(np.median(np.diff(time))) if time.size > 1 else 1.0
    width = max(1, round(FORCE_MEDIAN_S / dt))
    width += 1 - width % 2
    if held and fine is not None and fine[0].size > time.size:
        ft, fu = fine
        hu_fine = measured_thrust(ft, fu, held=True)
        return _on_coarse(time, hu_fine)
    if held:  # issue 31: the held force the noise hides, not the noise
        held_u = piecewise_constant(
            median_filter(u, size=width, mode="nearest") if width >= 3 and u.size > width else u,
            noise_sigma(u),
        )
        return Thrust(centred_changes(time, held_u), held_u)
    if width >= 3 and u.size > width:
        u = median_filter(u, size=width, mode="nearest")
    elif u is force:
        u = u.copy()
    if smooth:  # issue 31: held about each sample, not from it
        return Thrust(centred_samples(time), smooth_force(time, u))
    return Thrust(time, u)  # the trial's own times, not a copy (a long log is held once)


def centred_samples(time: np.ndarray) -> np.ndarray:
    """Breakpoints of a continuously changing force: each sample's value holds from
    halfway back to the sample before it to halfway on to the next (the first from its
    own time).

    A sample reads the force at its instant; holding it until the next sample puts the
    drive half a sample late on average against the force the load felt (a person's push
    changes continuously), and the fit bent T_a, m_a and A to absorb it: A 3-12 % low on
    clean guided moves (issue 31). Held about the sample, the drive's timing is right on
    average, with a spread of ``dt^2 / 12``.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s), increasing.

    Returns
    -------
    numpy.ndarray
        A new array of the breakpoints.
    """
    out = np.array(time, dtype=float, copy=True)
    if out.size > 1:
        out[1:] = 0.5 * (time[1:] + time[:-1])
    return out


#: Fewest samples a smooth force needs before its noise is smoothed out.
SMOOTH_MIN_SAMPLES = 50


def smooth_force(time: np.ndarray, u: np.ndarray) -> np.ndarray:
    """A smoothly varying force without its noise: a cubic smoothing spline whose weight
    is chosen by generalized cross-validation (zero phase: nothing moves in time).

    The measured force drives the model; its noise enters the simulated acceleration and
    biases a least-squares fit that treats the input as exact (errors in variables: a
    guided move with a load cell's 5 % noise gave T_a 3 standard errors long and A 4
    short). Cross-validation keeps what the samples show beyond their noise.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s), increasing.
    u : numpy.ndarray
        The force at those times (N).

    Returns
    -------
    numpy.ndarray
        The smoothed force; ``u`` itself when the spline cannot be made.
    """
    if u.size < SMOOTH_MIN_SAMPLES or not np.all(np.diff(time) > 0):
        return u
    from scipy.interpolate import make_smoothing_spline

    try:
        with np.errstate(all="ignore"):
            out = make_smoothing_spline(time, u)(time)
    except (ValueError, np.linalg.LinAlgError):
        return u
    return out if np.all(np.isfinite(out)) else u


def _on_coarse(time: np.ndarray, fine: Thrust) -> Thrust:
    """A held thrust found at a fine rate, given one breakpoint per coarse sample: each
    coarse sample's held value, the breakpoint moved to the fine change before it."""
    idx = np.clip(np.searchsorted(fine.times, time, side="right") - 1, 0, fine.times.size - 1)
    values = fine.values[idx]
    bt = np.array(time, dtype=float, copy=True)
    changed = np.flatnonzero(np.diff(values)) + 1
    fine_changes = np.flatnonzero(np.diff(fine.values)) + 1
    if changed.size and fine_changes.size:
        pos = np.searchsorted(fine_changes, idx[changed], side="right") - 1
        moved = fine.times[fine_changes[np.clip(pos, 0, None)]]
        ok = (pos >= 0) & (moved > time[changed - 1]) & (moved <= time[changed])
        bt[changed[ok]] = moved[ok]
    return Thrust(bt, values)


def centred_changes(time: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Breakpoints of a held series: each sample's time, but halfway back to the previous
    sample where the value changes there.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times (s), increasing.
    u : numpy.ndarray
        The held values at those times.

    Returns
    -------
    numpy.ndarray
        ``time`` itself when nothing changes, else a copy with the changes moved.
    """
    changed = np.flatnonzero(u[1:] != u[:-1]) + 1 if u.size > 1 else np.zeros(0, dtype=int)
    if changed.size == 0:
        return time
    out = np.array(time, dtype=float, copy=True)
    out[changed] = 0.5 * (time[changed] + time[changed - 1])
    return out


def _kept(x: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``x[keep]``; a view when ``keep`` is one stretch (a long log is held once)."""
    idx = np.flatnonzero(keep)
    if idx.size and idx[-1] - idx[0] + 1 == idx.size:
        return x[idx[0] : idx[-1] + 1]
    return x[keep]


def _continues(chain: bool, trial: Trial, prev: Trial | None, out: list[TrialData]) -> bool:
    """Whether ``trial`` goes on from the previous one (same run, thrust changed while
    moving) and ends after it."""
    return bool(
        chain
        and trial.continues
        and prev is not None
        and out
        and prev.source == trial.source
        and prev.recording == trial.recording
        and out[-1].time[-1] < trial.time[-1]
    )


def _fitted_samples(
    time: np.ndarray, accel: np.ndarray, after: float, t_step: float
) -> tuple[np.ndarray, np.ndarray]:
    """The samples fitted (finite, after ``after``) and the tail after a long drop-out.

    A drop-out longer than the bridging limit: the model cannot be carried across it (its
    input may have changed unseen); the trial ends before it, and a trial after it starts
    from the state estimated from the data (:class:`_Motion`). The tail is not fitted;
    the motion goes on through it.
    """
    keep = np.isfinite(accel) & np.isfinite(time) & (time > after)
    kept = np.flatnonzero(keep)
    long_gaps = np.flatnonzero(np.diff(time[kept]) > LONG_GAP_S) if kept.size else kept
    tail = np.zeros_like(keep)
    if long_gaps.size and kept[long_gaps[0]] >= np.searchsorted(time, t_step) + 10:
        tail[kept[long_gaps[0] + 1 :]] = True
        keep[kept[long_gaps[0] + 1] :] = False
    return keep, tail


def _level_se(trial: Trial, fine: tuple[np.ndarray, np.ndarray] | None) -> float | None:
    """The standard error (N) of a step trial's held level read from its measured force:
    the force's white noise (:func:`~balancer_id.identify.input_noise.noise_sigma`) over
    the samples after the onset; None for a trial not driven by a held measured force."""
    if (
        fine is None
        or trial.kind != "step"
        or trial.thrust_given
        or getattr(trial, "reference", None) is not None
    ):
        return None
    t, f = fine
    after = np.isfinite(f) & (t >= trial.t_step)
    n = int(after.sum())
    if n < 3:
        return None
    sigma = noise_sigma(f[np.isfinite(f)])
    return float(sigma / np.sqrt(n)) if np.isfinite(sigma) else None


#: Variance of a 20 %-trimmed mean of normal samples against their plain mean's (the
#: force's zero, :func:`~balancer_id.segment.robust.level`).
TRIMMED_MEAN_VARIANCE = 1.2


def _zero_se(trial: Trial, fine: tuple[np.ndarray, np.ndarray] | None) -> float | None:
    """The standard error (N) of the force's zero read in the rest before a step trial's
    onset (the 20 %-trimmed mean that segmentation subtracts, up to its guard before the
    onset); None where :func:`_level_se` is None or no rest is seen."""
    if _level_se(trial, fine) is None or fine is None:
        return None
    t, f = fine
    ok = np.isfinite(f)
    before = ok & (t < trial.t_step - StepSettings().guard_before_s)
    n = int(before.sum())
    if n < 3:
        return None
    sigma = noise_sigma(f[ok])
    return float(sigma * np.sqrt(TRIMMED_MEAN_VARIANCE / n)) if np.isfinite(sigma) else None


def zero_drift(
    trial: Trial, fine: tuple[np.ndarray, np.ndarray] | None
) -> tuple[float, float] | None:
    """How far a step trial's force rises over the rest where its zero is read (a line
    fitted there, N) and that rise's standard error; None where :func:`_zero_se` is.

    A force that moves there is no zero: a push or a tension already acting (a guided
    move read as steps), and subtracting its mean as an offset moves every level.

    Parameters
    ----------
    trial : Trial
        A segmented trial.
    fine : tuple of numpy.ndarray or None
        Its time and force before decimation.

    Returns
    -------
    tuple of float or None
        The rise (N) and its standard error (N).
    """
    if _zero_se(trial, fine) is None or fine is None:
        return None
    t, f = fine
    ok = np.isfinite(f)
    before = ok & (t < trial.t_step - StepSettings().guard_before_s)
    tb, fb = t[before], f[before]
    span = float(tb[-1] - tb[0]) if tb.size > 1 else 0.0
    sxx = float(np.sum((tb - tb.mean()) ** 2))
    sigma = noise_sigma(f[ok])
    if not (span > 0 and sxx > 0 and np.isfinite(sigma)):
        return None
    slope = float(np.sum((tb - tb.mean()) * (fb - fb.mean())) / sxx)
    return slope * span, float(sigma * span / np.sqrt(sxx))


def _trial_thrust(
    trial: Trial,
    time: np.ndarray,
    keep: np.ndarray,
    continues: bool,
    fine: tuple[np.ndarray, np.ndarray] | None,
    reference: Any,
    before: float | None,
) -> Thrust:
    """The thrust driving a trial: the measured force (from the first kept sample of a
    trial that continues), else a step, from the previous trial's level (``before``) when
    it continues."""
    if trial.force is not None and not trial.thrust_given and reference is None:
        thrust = measured_thrust(
            time, trial.force, held=trial.kind == "step", fine=fine,
            smooth=trial.kind == "guided",
        )  # fmt: skip
        if continues:
            first = np.searchsorted(time, time[keep][0])  # by sample, not by time
            thrust = Thrust(thrust.times[first:], thrust.values[first:])
        return thrust
    if continues:
        return Thrust(
            np.array([time[keep][0], trial.t_step]), np.array([before, trial.thrust_N])
        )
    return Thrust.step(trial.t_step, trial.thrust_N)


def from_trials(
    trials: Sequence[Trial],
    *,
    trajectory: Trapezoid | None = None,
    chain: bool = True,
    index: int | None = None,
) -> list[TrialData]:
    """Build the TrialData of segmented trials, chaining the trials of a session.

    A trial that ``continues`` the previous one (same run, the thrust changed while the
    load moved) keeps only its samples after the previous trial's last one, and the
    simulation runs on through it from the state the previous trial ended in
    (:meth:`FitData.build` stitches them); its ``lead_in`` holds the session before it.

    Parameters
    ----------
    trials : sequence of Trial
        Segmented trials, in time order.
    trajectory : Trapezoid, optional
        The robot's reference move, evaluated at the sample times (``servo``).
    chain : bool
        Chain the trials of a session; False simulates every trial from rest.
    index : int, optional
        Index to give a single trial; None keeps each ``trial.index``.

    Returns
    -------
    list of TrialData
        One per trial, in order.

    Raises
    ------
    IdentificationError
        When a trial has (almost) no acceleration samples.
    """
    out: list[TrialData] = []
    prev: Trial | None = None
    motion = _Motion()
    for trial in trials:
        continues = _continues(chain, trial, prev, out)
        after = out[-1].time[-1] if continues else -np.inf
        fine = (
            (np.asarray(trial.time, float), np.asarray(trial.force, float))
            if trial.force is not None
            else None
        )
        trial, decimation = decimate_trial(trial)  # above 400 Hz: to 200-400 Hz
        time = np.asarray(trial.time, float)
        accel = np.asarray(trial.accel, float)
        keep, tail = _fitted_samples(time, accel, after, trial.t_step)
        restart = bool(continues and keep.any() and time[keep][0] - out[-1].time[-1] > LONG_GAP_S)
        if keep.sum() < 10:
            raise IdentificationError(
                f"{trial.source} [{trial.recording}], trial at {trial.t_step:.2f} s: no "
                "acceleration samples; identification needs the acceleration channel"
            )
        reference = getattr(trial, "reference", None) or trajectory  # a robot move's own
        thrust = _trial_thrust(
            trial, time, keep, continues, fine if decimation.factor > 1 else None, reference,
            out[-1].thrust_N if continues else None,
        )  # fmt: skip
        if (continues or getattr(trial, "continues", False)) and decimation.factor > 1:
            # moving at its step, the model's acceleration jumps there (the viscosity
            # follows the thrust at once, times the speed): the anti-aliased samples within
            # the filter's reach of it blend both sides, and are not fitted (the thrust,
            # built above, still changes at its own time)
            clear = keep & (np.abs(time - trial.t_step) > decimation.reach_s)
            keep = clear if clear.sum() >= 10 else keep
        time, accel = _kept(time, keep), _kept(accel, keep)
        z_ref = v_ref = None
        if reference is not None:
            z_ref, v_ref = reference.evaluate(time)
        x0 = getattr(trial, "initial_state", None)
        if restart:
            x0 = motion.state_at(time, accel, float(thrust.at(time[:1])[0]))
            continues = False
        elif not continues:
            motion = _Motion()
        motion.add(time, accel, trial.t_step if not (continues or restart) else None)
        if tail.any():
            motion.add(np.asarray(trial.time, float)[tail], np.asarray(trial.accel, float)[tail])
        out.append(
            TrialData(
                index=trial.index if index is None else index,
                thrust_N=float(trial.thrust_N),
                direction=trial.direction,
                t_step=float(trial.t_step),
                input=TrialInput(time, thrust, z_ref, v_ref, x0),
                accel=accel,
                source=f"{trial.source} [{trial.recording}]",
                continues=bool(continues),
                previous=out[-1] if continues else None,
                decimation=decimation if decimation.factor > 1 else None,
                level_se_N=_level_se(trial, fine),
                zero_se_N=(
                    out[-1].zero_se_N  # one zero for a chain (segmentation's ref_chain)
                    if out and getattr(trial, "continues", False)
                    else _zero_se(trial, fine)
                ),
                zero_drift_N=(
                    None if out and getattr(trial, "continues", False) else zero_drift(trial, fine)
                ),
            )
        )
        prev = trial
    return out


#: A drop-out longer than this (s) is not simulated across (the bridging limit of
#: segmentation, :class:`~balancer_id.segment.steps.StepSettings`).
LONG_GAP_S = StepSettings().bridge_gap_s


class _Motion:
    """Velocity and position of a run's motion, integrated from its measured acceleration.

    The motion starts from rest (v = 0) at its first trial; the acceleration is the
    segmentation's vertical acceleration, whose resting level is already removed over the
    whole run (a mean over the short rest before an onset would be noisier). Between
    samples, and across a drop-out, the acceleration is taken as linear. Used to start a
    trial that follows a drop-out in motion.
    """

    def __init__(self) -> None:
        self.t: float | None = None
        self.a: float | None = None
        self.v = self.z = 0.0

    def add(self, time: np.ndarray, accel: np.ndarray, onset: float | None = None) -> None:
        """Integrate the samples ``time, accel`` (after those added before).

        Parameters
        ----------
        time, accel : numpy.ndarray
            Sample times (s) and vertical acceleration (m/s^2), finite.
        onset : float, optional
            A motion from rest starts here (the state is reset to rest).
        """
        if time.size == 0:
            return
        if onset is not None:
            self.t, self.a, self.v, self.z = None, None, 0.0, 0.0
        a = accel
        if self.t is not None and self.a is not None:
            self._advance(time[0], a[0])
        dt = np.diff(time)
        dv = 0.5 * (a[1:] + a[:-1]) * dt
        v = self.v + np.concatenate([[0.0], np.cumsum(dv)])
        self.z += float(np.sum(0.5 * (v[1:] + v[:-1]) * dt))
        self.v, self.t, self.a = float(v[-1]), float(time[-1]), float(a[-1])

    def _advance(self, t1: float, a1: float) -> None:
        assert self.t is not None and self.a is not None
        h = t1 - self.t
        self.z += self.v * h + (2.0 * self.a + a1) * h * h / 6.0
        self.v += 0.5 * (self.a + a1) * h
        self.t, self.a = t1, a1

    def state_at(
        self, time: np.ndarray, accel: np.ndarray, thrust: float
    ) -> tuple[float, float, float]:
        """The state at ``time[0]``, after a drop-out: ``(f, v, z)``.

        The acceleration at the end of the drop-out is the mean of the first 0.1 s after
        it; the drive force is the thrust at ``time[0]`` (its steady state: a thrust
        held longer than a few drive lags).

        Parameters
        ----------
        time, accel : numpy.ndarray
            The samples after the drop-out (s, m/s^2).
        thrust : float
            The thrust at ``time[0]`` (N).

        Returns
        -------
        tuple of float
            Drive force (N), velocity (m/s) and position (m) at ``time[0]``.
        """
        if self.t is None:
            return (thrust, 0.0, 0.0)
        first = accel[time <= time[0] + 0.1]
        self._advance(float(time[0]), float(np.mean(first)))
        return (thrust, self.v, self.z)


def join_inputs(inputs: Sequence[TrialInput]) -> TrialInput:
    """One continuous input from consecutive ones (each one's samples come later).

    Each input's thrust holds until the next input's first sample; the state starts at
    the first input's ``x0``. The arrays are concatenated once (a long session joined
    pairwise would copy its history once per trial).

    Parameters
    ----------
    inputs : sequence of TrialInput
        The inputs in time order (at least one).

    Returns
    -------
    TrialInput
        Their samples, thrust and references end to end.
    """
    if len(inputs) == 1:
        return inputs[0]
    times, values = [], []
    for first, second in itertools.pairwise(inputs):
        cut = np.searchsorted(first.thrust.times, second.time[0])
        times.append(first.thrust.times[:cut])
        values.append(first.thrust.values[:cut])
    times.append(inputs[-1].thrust.times)
    for k, (first, second) in enumerate(itertools.pairwise(inputs)):
        # a held force that changes right at the next input's first sample changes
        # halfway back to the sample before it, as within a series (centred_changes)
        nxt = second.thrust
        if (
            values[k].size >= 2
            and nxt.values.size >= 2
            and nxt.times[0] == second.time[0]
            and values[k][-1] == values[k][-2]
            and nxt.values[0] == nxt.values[1]
            and nxt.values[0] != values[k][-1]
        ):
            moved = times[k + 1].copy()
            moved[0] = 0.5 * (second.time[0] + first.time[-1])
            times[k + 1] = moved
    values.append(inputs[-1].thrust.values)
    with_refs = all(i.z_ref is not None and i.v_ref is not None for i in inputs)
    return TrialInput(
        np.concatenate([i.time for i in inputs]),
        Thrust(np.concatenate(times), np.concatenate(values)),
        np.concatenate([i.z_ref for i in inputs]) if with_refs else None,  # type: ignore[misc]
        np.concatenate([i.v_ref for i in inputs]) if with_refs else None,  # type: ignore[misc]
        inputs[0].x0,
    )


def _percentiles(x: np.ndarray, qs: Sequence[float]) -> list[float]:
    """``np.percentile(x, qs)`` (linear interpolation) of a 1-D array without its overhead."""
    pos = [q / 100.0 * (x.size - 1) for q in qs]
    ends = [(int(p), min(int(p) + 1, x.size - 1)) for p in pos]
    xs = np.partition(x, sorted({i for pair in ends for i in pair}))
    return [
        float(xs[lo] + (xs[hi] - xs[lo]) * (p - lo)) for p, (lo, hi) in zip(pos, ends, strict=True)
    ]


def thrust_levels(trials: Sequence[TrialData], rel_tol: float = 0.1) -> list[float]:
    """Distinct thrust magnitudes (N), merging those within ``rel_tol`` of each other.

    Each trial counts with ``|thrust_N|``; a trial driven by a measured force also with
    the 20th and 80th percentiles of ``|u|`` over its samples where ``|u|`` is above a
    quarter of its peak, so that a guided move, whose force sweeps a range, counts as
    the range of operating forces it covers.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials.
    rel_tol : float
        Relative tolerance: a magnitude within ``rel_tol`` above the last level found
        belongs to that level.

    Returns
    -------
    list of float
        The lowest magnitude of each level (N), ascending.
    """
    found: list[float] = []
    for t in trials:
        found.append(abs(t.thrust_N))
        if t.input.thrust.times.size > 2:
            u = np.abs(t.input.thrust.at(t.time))
            big = u[u >= 0.25 * u.max()] if u.size and u.max() > 0 else u[:0]
            if big.size:
                found += _percentiles(big, (20.0, 80.0))
    levels: list[float] = []
    for f in sorted(found):
        if not levels or f > levels[-1] * (1 + rel_tol):
            levels.append(f)
    return levels


class SessionPack:
    """Packed segments whose simulated rows are selected back to the trials' samples.

    Used when a trial is simulated with its session's lead-in (samples that are not
    fitted); :meth:`run` returns rows aligned with :attr:`FitData.y`, as
    :meth:`PackedTrials.run` does for trials simulated alone.

    Attributes
    ----------
    inner : PackedTrials
        The continuous segments.
    rows : numpy.ndarray
        Row of ``inner``'s output for each fitted sample.
    offsets : numpy.ndarray
        Start of each trial in the selected rows (and the total at the end).
    """

    def __init__(self, inner: PackedTrials, rows: np.ndarray, offsets: np.ndarray) -> None:
        self.inner = inner
        self.rows = rows
        self.offsets = offsets
        self.t_all = inner.t_all[rows]

    def run(self, model: Model, pvec: np.ndarray, substeps: int = DEFAULT_SUBSTEPS) -> np.ndarray:
        """Simulate every segment; return the rows of the fitted samples.

        Parameters
        ----------
        model : Model
            The model.
        pvec : numpy.ndarray
            Parameter values in ``model.param_names`` order.
        substeps : int
            RK4 steps per sample interval.

        Returns
        -------
        numpy.ndarray
            ``(n_fitted, 5)``, columns as :meth:`PackedTrials.run`.
        """
        return self.inner.run(model, pvec, substeps)[self.rows]

    def run_sens(
        self, model: Model, pvec: np.ndarray, cols: Sequence[int], substeps: int = DEFAULT_SUBSTEPS
    ) -> tuple[np.ndarray, np.ndarray]:
        """Simulate with sensitivities (where the engine has them); rows of the fitted samples.

        Parameters
        ----------
        model : Model
            The model.
        pvec : numpy.ndarray
            Parameter values in ``model.param_names`` order.
        cols : sequence of int
            What to differentiate with respect to (as ``PackedTrials.run_sens``).
        substeps : int
            RK4 steps per sample interval.

        Returns
        -------
        out : numpy.ndarray
            As :meth:`run`.
        sens : numpy.ndarray
            The sensitivities of the fitted samples' acceleration.
        """
        out, sens = self.inner.run_sens(model, pvec, cols, substeps)  # type: ignore[attr-defined]
        return out[self.rows], sens[self.rows]

    def sens_runner(
        self, model: Model, cols: Sequence[int], substeps: int = DEFAULT_SUBSTEPS
    ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """:meth:`PackedTrials.sens_runner`, the fitted samples' rows only.

        Parameters
        ----------
        model : Model
            The model.
        cols : sequence of int
            What to differentiate with respect to.
        substeps : int
            RK4 steps per sample interval.

        Returns
        -------
        callable
            ``pvec`` to ``(out, sens)`` as :meth:`run_sens`.
        """
        inner = self.inner.sens_runner(model, cols, substeps)
        rows = self.rows

        def run(pvec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            out, sens = inner(pvec)
            return out[rows], sens[rows]

        return run

    def stream(
        self, model: Model, pvec: np.ndarray, max_rows: int, substeps: int = DEFAULT_SUBSTEPS
    ) -> Iterator[tuple[int, np.ndarray]]:
        """:meth:`PackedTrials.stream`, each block's fitted rows only.

        Parameters
        ----------
        model : Model
            The model.
        pvec : numpy.ndarray
            Parameter values in ``model.param_names`` order.
        max_rows : int
            Simulated rows per block.
        substeps : int
            RK4 steps per sample interval.

        Yields
        ------
        first : int
            The first fitted row of the block.
        out : numpy.ndarray
            Its fitted rows of :meth:`run`'s output.
        """
        for first, out in self.inner.stream(model, pvec, max_rows, substeps):
            a, b = self._fitted(first, out.shape[0])
            if b > a:
                yield a, out[self.rows[a:b] - first]

    def stream_sens(
        self,
        model: Model,
        pvec: np.ndarray,
        cols: Sequence[int],
        max_rows: int,
        substeps: int = DEFAULT_SUBSTEPS,
    ) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        """:meth:`PackedTrials.stream_sens`, each block's fitted rows only.

        Parameters
        ----------
        model : Model
            The model.
        pvec : numpy.ndarray
            Parameter values in ``model.param_names`` order.
        cols : sequence of int
            What to differentiate with respect to (as ``PackedTrials.run_sens``).
        max_rows : int
            Simulated rows per block.
        substeps : int
            RK4 steps per sample interval.

        Yields
        ------
        first : int
            The first fitted row of the block.
        out, sens : numpy.ndarray
            Its fitted rows of the output and the sensitivities.
        """
        for first, out, sens in self.inner.stream_sens(model, pvec, cols, max_rows, substeps):
            a, b = self._fitted(first, out.shape[0])
            if b > a:
                pick = self.rows[a:b] - first
                yield a, out[pick], sens[pick]

    def _fitted(self, first: int, size: int) -> tuple[int, int]:
        """The fitted rows ``[a, b)`` simulated in the inner rows ``[first, first+size)``."""
        a = int(np.searchsorted(self.rows, first, side="left"))
        b = int(np.searchsorted(self.rows, first + size, side="left"))
        return a, b


@dataclass
class FitData:
    """Several trials packed once for repeated simulation.

    Trials that continue each other (a session) are packed as one continuous segment,
    so the state runs on from one trial to the next; a continuing trial whose
    predecessor is not in the set is preceded by its lead-in, simulated but not fitted.
    """

    trials: list[TrialData]
    packed: PackedTrials | SessionPack
    y: np.ndarray

    @classmethod
    def build(cls, trials: Sequence[TrialData]) -> FitData:
        """Pack ``trials`` (in order).

        Parameters
        ----------
        trials : sequence of TrialData
            The trials to fit together.

        Returns
        -------
        FitData
            The trials, their inputs packed for :meth:`PackedTrials.run` (continuous
            through a session) and the measured accelerations concatenated (m/s^2).
        """
        trials = list(trials)
        segments: list[list[TrialInput]] = []
        rows: list[np.ndarray] = []
        lead = False
        n = 0
        for i, td in enumerate(trials):
            joined = (
                td.continues
                and i > 0
                and td.previous is not None
                and trials[i - 1].source == td.source
                and td.previous.time[-1] == trials[i - 1].time[-1]
            )
            lead_in = None if joined else td.lead_in
            if joined:
                segments[-1].append(td.input)
            elif lead_in is not None:
                segments.append([lead_in, td.input])
                n += lead_in.time.size
                lead = True
            else:
                segments.append([td.input])
            rows.append(np.arange(n, n + td.time.size))
            n += td.time.size
        inner = PackedTrials.pack([join_inputs(parts) for parts in segments])
        sizes = np.array([td.time.size for td in trials], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        packed: PackedTrials | SessionPack = inner
        if lead:  # lead-in samples are simulated, not fitted
            packed = SessionPack(inner, np.concatenate(rows), offsets)
        return cls(trials=trials, packed=packed, y=np.concatenate([t.accel for t in trials]))

    def slices(self) -> list[slice]:
        """The slice of each trial in the packed (fitted) arrays."""
        sizes = [td.time.size for td in self.trials]
        o = np.concatenate([[0], np.cumsum(sizes)])
        return [slice(int(o[j]), int(o[j + 1])) for j in range(len(self.trials))]


def group_trials(trials: Sequence[TrialData], by: str) -> list[tuple[str, list[TrialData]]]:
    """Split trials into groups that are identified separately (``fit --group-by``).

    Parameters
    ----------
    trials : sequence of TrialData
        The trials, in order.
    by : str
        ``"run"`` (each run of each log), ``"log"`` (each file), or ``"runs:1-3,4-6"``
        (runs counted from 1 in recording order over all logs, joined in the groups
        given; a run not named is left out).

    Returns
    -------
    list of (str, list of TrialData)
        Each group's label and trials, in order of first appearance.

    Raises
    ------
    UsageError
        For an unknown ``by`` or a run number that does not exist.
    """
    runs: list[str] = []
    for t in trials:
        if t.source not in runs:
            runs.append(t.source)
    if by == "run":
        key = {r: r for r in runs}
    elif by == "log":
        key = {r: r.split(" [")[0] for r in runs}
    elif by.startswith("runs:"):
        key = {}
        parts = [part.strip() for part in by[5:].split(",")]
        if not all(parts):
            raise UsageError(
                f"--group-by '{by}': give run numbers or ranges separated by commas, "
                "e.g. runs:1-3,4-6"
            )
        for part in parts:
            lo, _, hi = part.partition("-")
            try:
                a, b = int(lo), int(hi or lo)
            except ValueError:
                raise UsageError(f"--group-by '{by}': '{part}' is not N or N-M") from None
            if not 1 <= a <= b <= len(runs):
                raise UsageError(
                    f"--group-by '{by}': runs {part} not in 1-{len(runs)} (the runs found)"
                )
            label = f"runs {a}-{b}" if b > a else f"run {a}"
            taken = [runs[i - 1] for i in range(a, b + 1) if runs[i - 1] in key]
            if taken:
                raise UsageError(
                    f"--group-by '{by}': run {runs.index(taken[0]) + 1} is in two groups; "
                    "give each run to one group"
                )
            key.update({runs[i - 1]: label for i in range(a, b + 1)})
    else:
        raise UsageError(f"--group-by must be run, log or runs:1-3,4-6, not {by!r}")
    groups: dict[str, list[TrialData]] = {}
    for t in trials:
        if t.source in key:
            groups.setdefault(key[t.source], []).append(t)
    return list(groups.items())
