"""Robot-balancer coupling (paper section IV): the closed loop of the lag, mass and servo.

With a position-controlled robot holding the load through a servo spring ``k_r`` and
damper ``c_r``, the drive lag closes a third-order loop::

    T_a m_a s^3 + (T_a D + m_a) s^2 + (D + c_r) s + k_r = 0

Routh-Hurwitz: stable only when ``(T_a D + m_a)(D + c_r) > T_a m_a k_r``. A stiff,
lightly damped servo therefore oscillates where a person (a soft, well damped "servo")
does not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Coupling:
    """Dominant oscillation of the robot-balancer loop.

    Attributes
    ----------
    oscillation_hz : float
        Frequency of the least damped complex pole pair (0 when all poles are real).
    damping_ratio : float
        Its damping ratio (negative when unstable).
    stability_margin : float
        ``(T_a D + m_a)(D + c_r) / (T_a m_a k_r) - 1``: positive when stable.
    poles : tuple of complex
        All closed-loop poles.
    """

    oscillation_hz: float
    damping_ratio: float
    stability_margin: float
    poles: tuple[complex, ...]

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md ``coupling`` record."""
        return {
            "oscillation_hz": self.oscillation_hz,
            "damping_ratio": self.damping_ratio,
            "stability_margin": self.stability_margin,
            "poles": [[p.real, p.imag] for p in self.poles],
        }


def coupling(m_a: float, T_a: float, D: float, k_r: float, c_r: float) -> Coupling:
    """Poles, oscillation and stability margin of the robot-balancer loop.

    Parameters
    ----------
    m_a, T_a : float
        Virtual mass (kg) and drive lag (s).
    D : float
        Viscosity at the operating force of interest (kg/s).
    k_r, c_r : float
        Robot servo stiffness (N/m) and damping (N s/m).

    Returns
    -------
    Coupling
    """
    poly = [T_a * m_a, T_a * D + m_a, D + c_r, k_r]
    poles = np.roots(poly)
    complex_poles = [p for p in poles if abs(p.imag) > 1e-9]
    if complex_poles:
        p = max(complex_poles, key=lambda q: q.real / abs(q))
        freq = float(abs(p.imag) / (2 * np.pi))
        zeta = float(-p.real / abs(p))
    else:
        freq, zeta = 0.0, 1.0
    margin = (
        float((T_a * D + m_a) * (D + c_r) / (T_a * m_a * k_r) - 1.0) if k_r > 0 else float("inf")
    )
    return Coupling(freq, zeta, margin, tuple(complex(p) for p in poles))
