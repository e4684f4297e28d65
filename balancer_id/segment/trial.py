"""A step trial: the window of one recording that follows one step of thrust."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from balancer_id.notes import Note


@dataclass
class Trial:
    """One step trial, ready for identification.

    Times are on the recording's own time base. ``accel`` is the vertical acceleration
    with gravity removed (up positive); ``force`` is the operating force, signed so that
    up is positive (MODEL.md), less its reading at the rest before the step (before the
    first step of the session when the trial ``continues`` the previous one's motion).

    Attributes
    ----------
    index : int
        Position of the trial in the log (0-based, over all runs).
    recording : str
        Name of the run the trial comes from.
    t_step : float
        Onset of the thrust step (s).
    t_start, t_end : float
        The analysis window (s): a little rest before the onset, up to the next event.
    thrust_N : float
        The signed thrust level from the onset on (N), up positive: the size of the step
        for a step from rest, the new level of the session for a change while moving.
    direction : str
        ``"up"`` or ``"down"``; agrees with the sign of ``thrust_N``.
    time : numpy.ndarray
        Sample times inside the window (s).
    accel : numpy.ndarray
        Vertical acceleration inside the window (m/s^2), gravity removed.
    force : numpy.ndarray or None
        Operating-force change inside the window (N), up positive, or None.
    end_reason : str
        What ended the window: ``"next step"``, ``"catch"``, ``"gap"``, ``"end of run"``.
    source : str
        The file the trial was read from.
    notes : list of str
        Anything unusual (thrust given by the user, saturation in the window, ...);
        a note starting with ``warning:`` is shown to the user.
    thrust_change_N : float or None
        The signed change of thrust at the onset (N); None: equal to ``thrust_N``.
    continues : bool
        The thrust changed while the previous trial's motion went on (a session): the
        trial starts in the state the previous one ended in.
    thrust_given : bool
        ``thrust_N`` was given by the user (``--thrust``); the model is then driven by
        the given levels rather than by the force channel.
    kind : str
        ``"step"`` (a thrust step), ``"guided"`` (a person's guided move: the force
        varies without steps; ``thrust_N`` is its signed peak) or ``"move"`` (a robot's
        reference move, :class:`~balancer_id.segment.move.MoveTrial`).
    vertical : str
        The up direction in the sensor frame (``"+z"``, ``"-x, 12 deg off"``).
    vertical_sign_known : bool
        False when the up sign is a convention (linear acceleration, nothing fixed it).
    initial_state : tuple of float or None
        The load's state ``(f, v, z)`` at the window's first sample when it does not start
        at rest (a window given by ``--window``); None: at rest.
    typed_notes : list of Note
        The trial's warnings with their codes (e.g. ``segment.thrust_sign``); each text is
        also in :attr:`notes`.
    """

    index: int
    recording: str
    t_step: float
    t_start: float
    t_end: float
    thrust_N: float
    direction: str
    time: np.ndarray
    accel: np.ndarray
    force: np.ndarray | None = None
    end_reason: str = "end of run"
    source: str = ""
    notes: list[str] = field(default_factory=list)
    thrust_change_N: float | None = None
    continues: bool = False
    thrust_given: bool = False
    kind: str = "step"
    vertical: str = ""
    vertical_sign_known: bool = True
    initial_state: tuple[float, float, float] | None = None
    typed_notes: list[Note] = field(default_factory=list)

    @property
    def change_N(self) -> float:
        """The signed change of thrust at the onset (N)."""
        return float(self.thrust_N if self.thrust_change_N is None else self.thrust_change_N)

    def to_dict(self) -> dict[str, object]:
        """Return the CONTRACT.md ``inspect`` trial record."""
        return {
            "index": self.index,
            "recording": self.recording,
            "t_step": round(float(self.t_step), 6),
            "t_start": round(float(self.t_start), 6),
            "t_end": round(float(self.t_end), 6),
            "thrust_N": round(float(self.thrust_N), 4),
            "thrust_change_N": round(self.change_N, 4),
            "continues": self.continues,
            "kind": self.kind,
            "direction": self.direction,
            "end_reason": self.end_reason,
            "n_samples": int(self.time.size),
            "vertical": self.vertical,
            "vertical_sign_known": self.vertical_sign_known,
            "notes": list(self.notes),
        }
