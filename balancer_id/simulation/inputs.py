"""What drives a simulation: the thrust and, for a robot, its reference move."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Thrust:
    """A piecewise-constant operating thrust ``u(t)`` (N, up positive).

    ``u(t) = values[k]`` for ``times[k] <= t < times[k+1]`` and 0 before ``times[0]``.

    Attributes
    ----------
    times : numpy.ndarray
        Breakpoints (s), increasing.
    values : numpy.ndarray
        The thrust from each breakpoint on (N).
    """

    times: np.ndarray
    values: np.ndarray

    @classmethod
    def step(cls, t0: float, f_in: float) -> Thrust:
        """A step of ``f_in`` newtons at ``t0`` seconds.

        Parameters
        ----------
        t0 : float
            Onset of the step (s); the thrust is 0 before it.
        f_in : float
            Thrust from the onset on (N, up positive).

        Returns
        -------
        Thrust
        """
        return cls(np.array([float(t0)]), np.array([float(f_in)]))

    @classmethod
    def series(cls, t: np.ndarray, u: np.ndarray) -> Thrust:
        """A measured force series, held constant between samples (zero-order hold).

        Parameters
        ----------
        t : numpy.ndarray
            Sample times (s), increasing; the thrust is 0 before ``t[0]``.
        u : numpy.ndarray
            Thrust at each sample (N, up positive), same shape as ``t``.

        Returns
        -------
        Thrust
            Holding copies of ``t`` and ``u``.

        Raises
        ------
        ValueError
            When ``t`` and ``u`` are not 1-D arrays of equal length.
        """
        t = np.asarray(t, dtype=float)
        u = np.asarray(u, dtype=float)
        if t.shape != u.shape or t.ndim != 1:
            raise ValueError("thrust series: time and force must be 1-D arrays of equal length")
        return cls(t.copy(), u.copy())

    def at(self, t: np.ndarray) -> np.ndarray:
        """Evaluate ``u`` at times ``t`` (right-continuous).

        Parameters
        ----------
        t : numpy.ndarray
            Times (s).

        Returns
        -------
        numpy.ndarray
            The thrust at each time (N); 0 before the first breakpoint.
        """
        idx = np.searchsorted(self.times, np.asarray(t, dtype=float), side="right") - 1
        return np.where(idx >= 0, self.values[np.clip(idx, 0, None)], 0.0)


@dataclass(frozen=True)
class Trapezoid:
    """A robot's point-to-point move with a trapezoidal speed profile (paper section II.A).

    Attributes
    ----------
    distance : float
        Signed travel (m), up positive.
    speed : float
        Cruise speed (m/s, > 0).
    accel : float
        Acceleration and deceleration (m/s^2, > 0).
    start : float
        Start time of the move (s).
    """

    distance: float
    speed: float
    accel: float
    start: float = 0.0

    def __post_init__(self) -> None:
        values = (self.distance, self.speed, self.accel, self.start)
        if not all(math.isfinite(v) for v in values):
            raise ValueError("trapezoid: distance, speed, accel and start must be finite numbers")
        if self.speed <= 0 or self.accel <= 0:
            raise ValueError("trapezoid: speed and accel must be positive")
        if self.distance == 0:
            raise ValueError("trapezoid: distance must not be 0 (a move of 0 m is no move)")

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reference position and velocity at times ``t``.

        A move too short to reach :attr:`speed` has a triangular speed profile.

        Parameters
        ----------
        t : numpy.ndarray
            Times (s), on the same clock as :attr:`start`.

        Returns
        -------
        z_ref : numpy.ndarray
            Position (m), 0 before the start and ``distance`` after the end.
        v_ref : numpy.ndarray
            Velocity (m/s), 0 outside the move.
        """
        t = np.asarray(t, dtype=float) - self.start
        dist = abs(self.distance)
        sign = 1.0 if self.distance >= 0 else -1.0
        t_acc = self.speed / self.accel
        if self.accel * t_acc**2 > dist:  # triangular profile
            t_acc = float(np.sqrt(dist / self.accel))
        v_peak = self.accel * t_acc
        t_cruise = max(dist - self.accel * t_acc**2, 0.0) / v_peak if v_peak > 0 else 0.0
        t_end = 2 * t_acc + t_cruise
        tc = np.clip(t, 0.0, t_end)
        z = np.where(
            tc < t_acc,
            0.5 * self.accel * tc**2,
            np.where(
                tc < t_acc + t_cruise,
                0.5 * self.accel * t_acc**2 + v_peak * (tc - t_acc),
                dist - 0.5 * self.accel * np.clip(t_end - tc, 0.0, None) ** 2,
            ),
        )
        v = np.where(
            (t <= 0) | (t >= t_end),
            0.0,
            np.where(
                tc < t_acc,
                self.accel * tc,
                np.where(tc < t_acc + t_cruise, v_peak, self.accel * (t_end - tc)),
            ),
        )
        return sign * z, sign * v


def parse_trajectory(text: str) -> Trapezoid:
    """Parse ``"trapezoid:distance=-0.2,speed=0.1,accel=0.5[,start=1.0]"`` (CONTRACT.md).

    Parameters
    ----------
    text : str
        The ``--trajectory`` value: ``distance`` in m (up positive), ``speed`` in m/s,
        ``accel`` in m/s^2 and optionally ``start`` in s.

    Returns
    -------
    Trapezoid

    Raises
    ------
    ValueError
        With what is wrong and the expected form.
    """
    kind, _, rest = text.partition(":")
    if kind.strip() != "trapezoid":
        raise ValueError(
            f"trajectory '{text}': expected 'trapezoid:distance=D,speed=V,accel=A[,start=T]' "
            "or a CSV file with time,position"
        )
    fields: dict[str, float] = {}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        try:
            fields[key.strip()] = float(value)
        except ValueError:
            raise ValueError(f"trajectory '{text}': '{item}' is not NAME=NUMBER") from None
        if not math.isfinite(fields[key.strip()]):
            raise ValueError(f"trajectory '{text}': '{item}' is not a finite number")
    missing = {"distance", "speed", "accel"} - fields.keys()
    unknown = fields.keys() - {"distance", "speed", "accel", "start"}
    if missing or unknown:
        raise ValueError(
            f"trajectory '{text}': missing {sorted(missing)} / unknown {sorted(unknown)}; "
            "use distance, speed, accel and optionally start"
        )
    return Trapezoid(**fields)
