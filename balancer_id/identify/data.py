"""Trials as the fitters see them: simulation inputs plus the measured acceleration."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from balancer_id.errors import IdentificationError
from balancer_id.segment.decimate import Decimation, decimate_trial
from balancer_id.segment.robust import rate_of
from balancer_id.segment.trial import Trial
from balancer_id.simulation.engine import PackedTrials, TrialInput
from balancer_id.simulation.inputs import Thrust, Trapezoid


@dataclass
class TrialData:
    """One trial ready for fitting.

    Attributes
    ----------
    index : int
        Trial index (over all logs of a fit).
    thrust_N : float
        Signed thrust (N).
    direction : str
        ``"up"`` or ``"down"``.
    t_step : float
        Onset of the thrust (s).
    input : TrialInput
        What drives the simulation (rest at ``input.time[0]``).
    accel : numpy.ndarray
        Measured vertical acceleration at ``input.time`` (m/s^2).
    source : str
        File and run the trial came from.
    decimation : Decimation or None
        How the trial was decimated for fitting (None: fitted at the log's own rate).
    """

    index: int
    thrust_N: float
    direction: str
    t_step: float
    input: TrialInput
    accel: np.ndarray
    source: str = ""
    decimation: Decimation | None = None

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
        """Build from a segmented :class:`~balancer_id.segment.trial.Trial` (step thrust).

        Samples without an acceleration value (blank cells of a multi-rate export) are
        left out; the simulation runs at the sample times that remain. A trial faster
        than 400 Hz is first decimated to 200-400 Hz, anti-aliased
        (:func:`~balancer_id.segment.decimate.decimate_trial`).

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
            Driven by a step of ``trial.thrust_N`` (N) at ``trial.t_step`` (s).

        Raises
        ------
        IdentificationError
            When the trial has (almost) no acceleration samples.
        """
        trial, decimation = decimate_trial(trial)  # above 400 Hz: to 200-400 Hz
        time = np.asarray(trial.time, float)
        accel = np.asarray(trial.accel, float)
        keep = np.isfinite(accel) & np.isfinite(time)
        if keep.sum() < 10:
            raise IdentificationError(
                f"{trial.source} [{trial.recording}], trial at {trial.t_step:.2f} s: no "
                "acceleration samples; identification needs the acceleration channel"
            )
        time, accel = time[keep], accel[keep]
        z_ref = v_ref = None
        trajectory = getattr(trial, "reference", None) or trajectory  # a robot move's own
        if trajectory is not None:
            z_ref, v_ref = trajectory.evaluate(time)
        return cls(
            index=trial.index if index is None else index,
            thrust_N=float(trial.thrust_N),
            direction=trial.direction,
            t_step=float(trial.t_step),
            input=TrialInput(time, Thrust.step(trial.t_step, trial.thrust_N), z_ref, v_ref),
            accel=accel,
            source=f"{trial.source} [{trial.recording}]",
            decimation=decimation if decimation.factor > 1 else None,
        )


def thrust_levels(trials: Sequence[TrialData], rel_tol: float = 0.1) -> list[float]:
    """Distinct thrust magnitudes (N), merging those within ``rel_tol`` of each other.

    Parameters
    ----------
    trials : sequence of TrialData
        The trials; only ``|thrust_N|`` matters.
    rel_tol : float
        Relative tolerance: a magnitude within ``rel_tol`` above the last level found
        belongs to that level.

    Returns
    -------
    list of float
        The lowest magnitude of each level (N), ascending.
    """
    levels: list[float] = []
    for f in sorted(abs(t.thrust_N) for t in trials):
        if not levels or f > levels[-1] * (1 + rel_tol):
            levels.append(f)
    return levels


@dataclass
class FitData:
    """Several trials packed once for repeated simulation."""

    trials: list[TrialData]
    packed: PackedTrials
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
            The trials, their inputs packed for :meth:`PackedTrials.run` and the
            measured accelerations concatenated (m/s^2).
        """
        trials = list(trials)
        return cls(
            trials=trials,
            packed=PackedTrials.pack([t.input for t in trials]),
            y=np.concatenate([t.accel for t in trials]),
        )

    def slices(self) -> list[slice]:
        """The slice of each trial in the packed arrays."""
        o = self.packed.offsets
        return [slice(int(o[j]), int(o[j + 1])) for j in range(len(self.trials))]
