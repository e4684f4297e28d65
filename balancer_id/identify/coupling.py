"""Robot-balancer coupling (paper section IV): the closed loop of the lag, mass and servo.

With a position-controlled robot holding the load through a servo spring ``k_r`` and
damper ``c_r``, the drive lag closes a third-order loop::

    T_a m_a s^3 + (T_a D + m_a) s^2 + (D + c_r) s + k_r = 0

Routh-Hurwitz: stable only when ``(T_a D + m_a)(D + c_r) > T_a m_a k_r``. A stiff,
lightly damped servo therefore oscillates where a person (a soft, well damped "servo")
does not.
"""

from __future__ import annotations

import cmath
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

#: Below this damping ratio a stable loop still rings: the load vibrates (a warning).
LIGHTLY_DAMPED = 0.3


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
    terms : dict
        The terms of the stability condition: ``T_a*D``, ``m_a``, ``D``, ``c_r``,
        ``k_r``, and its two sides ``lhs = (T_a D + m_a)(D + c_r)``, ``rhs = T_a m_a k_r``.
    viscosity_factor : float
        The share of ``D0`` the loop was linearized at (1: at ``D0`` itself).
    """

    oscillation_hz: float
    damping_ratio: float
    stability_margin: float
    poles: tuple[complex, ...]
    terms: dict[str, float] = field(default_factory=dict)
    viscosity_factor: float = 1.0

    @property
    def stable(self) -> bool:
        """Whether every pole lies in the left half plane; with no servo stiffness the
        position's own pole at 0 (the load stays where it is left) is no instability."""
        free = self.terms.get("k_r", 1.0) == 0.0
        return all(p.real < 0 or (free and p == 0) for p in self.poles)

    @property
    def lightly_damped(self) -> bool:
        """Stable but ringing: an oscillating pole pair damped less than ``LIGHTLY_DAMPED``."""
        return self.stable and self.oscillation_hz > 0 and self.damping_ratio < LIGHTLY_DAMPED

    @property
    def verdict(self) -> str:
        """``unstable``, ``lightly damped`` or ``well damped`` (what the reports say)."""
        if not self.stable:
            return "unstable"
        return "lightly damped" if self.lightly_damped else "well damped"

    @property
    def damping_source(self) -> str:
        """Where the damping ratio comes from (the one damping ratio every output shows)."""
        text = "the identified model's closed-loop poles (least damped pair)"
        if self.viscosity_factor < 0.999:
            text += (
                f", linearized at the settling's effective viscosity "
                f"({100 * self.viscosity_factor:.0f} % of D0: the servo force lowers the "
                "variable viscosity)"
            )
        return text

    @property
    def dominant(self) -> str:
        """Which term carries the stabilizing side ``(T_a D + m_a)(D + c_r)`` (text)."""
        if not self.terms:
            return ""
        damping = (
            "the robot's damping c_r"
            if self.terms["c_r"] >= self.terms["D"]
            else "the balancer's viscosity D"
        )
        inertia = (
            "the virtual mass m_a"
            if self.terms["m_a"] >= self.terms["T_a*D"]
            else "the lag-viscosity product T_a D"
        )
        return f"{damping} (in D + c_r) and {inertia} (in T_a D + m_a)"

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md ``coupling`` record."""
        out: dict[str, object] = {
            "oscillation_hz": self.oscillation_hz,
            "damping_ratio": self.damping_ratio,
            "stability_margin": self.stability_margin,
            "stable": self.stable,
            "verdict": self.verdict,
            "damping_source": self.damping_source,
            "viscosity_factor": self.viscosity_factor,
            "poles": [[p.real, p.imag] for p in self.poles],
        }
        if self.terms:
            t = self.terms
            out["condition"] = {
                "lhs": t["lhs"],
                "rhs": t["rhs"],
                "difference": t["lhs"] - t["rhs"],
                "text": "(T_a D + m_a)(D + c_r) > T_a m_a k_r",
            }
            out["terms"] = dict(t)
            out["dominant"] = self.dominant
        return out


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
    terms = {
        "T_a*D": T_a * D,
        "m_a": m_a,
        "D": D,
        "c_r": c_r,
        "k_r": k_r,
        "lhs": (T_a * D + m_a) * (D + c_r),
        "rhs": T_a * m_a * k_r,
    }
    return Coupling(freq, zeta, margin, tuple(complex(p) for p in poles), terms)


def _loop_args(
    values: Mapping[str, float], viscosity_factor: float
) -> tuple[float, float, float, float, float]:
    """``m_a, T_a, D, k_r, c_r`` of a parameter set (see :func:`coupling_of`)."""
    if "T_a" in values:
        lag = float(values["T_a"])
    elif "T_up" in values and "T_down" in values:
        lag = 0.5 * (float(values["T_up"]) + float(values["T_down"]))
    else:  # every model has a drive lag; a hand-made mapping may not
        raise ValueError("the coupling needs the drive lag: T_a, or T_up and T_down")
    return (
        float(values["m_a"]),
        lag,
        float(viscosity_factor) * float(values.get("D0", 0.0)),
        float(values["k_r"]),
        float(values["c_r"]),
    )


def delay_margin_of(values: Mapping[str, float], viscosity_factor: float = 1.0) -> float:
    """:func:`delay_margin` of a parameter set (as :func:`coupling_of` reads it).

    Parameters
    ----------
    values : mapping of str to float
        As for :func:`coupling_of`.
    viscosity_factor : float
        As for :func:`coupling_of`.

    Returns
    -------
    float
        The largest servo delay (s) the loop stands.
    """
    return delay_margin(*_loop_args(values, viscosity_factor))


def coupling_of(values: Mapping[str, float], viscosity_factor: float = 1.0) -> Coupling:
    """The coupling figures of a parameter set (a fit's values).

    Uses ``T_a`` (or the mean of ``T_up`` and ``T_down`` with ``asymmetric_lag``) and the
    viscosity at zero operating force ``D0`` (0 without a viscosity effect).

    Parameters
    ----------
    values : mapping of str to float
        Parameter values by MODEL.md name; must hold ``m_a``, ``k_r``, ``c_r`` and the
        drive lag (``T_a``, or ``T_up`` and ``T_down``). A positive ``tau_r`` (a servo
        acting late, s) gives the delayed loop's figures (:func:`delayed_coupling`).
    viscosity_factor : float
        The settling's effective viscosity as a share of ``D0`` (``variable_viscosity``:
        the servo force lowers it); the loop is linearized at ``viscosity_factor * D0``.

    Returns
    -------
    Coupling

    Raises
    ------
    ValueError
        When the values hold no drive lag.
    """
    args = _loop_args(values, viscosity_factor)
    tau_r = float(values.get("tau_r", 0.0))
    found = delayed_coupling(*args, tau_r) if tau_r > 0 else coupling(*args)
    return replace(found, viscosity_factor=float(viscosity_factor))


#: Order of the Pade approximant of the servo delay whose roots start the Newton search
#: for the delayed loop's poles (accurate while |s tau_r| is a few units).
PADE_ORDER = 8


def _pade(tau: float, order: int = PADE_ORDER) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator (highest power first) of the Pade approximant of exp(-s tau)."""
    from math import factorial

    n = order
    c = [
        factorial(2 * n - k) * factorial(n) / (factorial(2 * n) * factorial(k) * factorial(n - k))
        for k in range(n + 1)
    ]
    num = np.array([c[k] * (-tau) ** k for k in range(n + 1)])[::-1]
    den = np.array([c[k] * tau**k for k in range(n + 1)])[::-1]
    return num, den


def delayed_poles(
    m_a: float, T_a: float, D: float, k_r: float, c_r: float, tau_r: float
) -> tuple[complex, ...]:
    """The slow poles of the loop whose servo acts ``tau_r`` late.

    The characteristic equation is the quasi-polynomial
    ``T_a m_a s^3 + (T_a D + m_a) s^2 + D s + (c_r s + k_r) exp(-s tau_r) = 0``: the roots
    of its Pade approximant (:data:`PADE_ORDER`), refined by Newton's method on the exact
    equation, kept where ``|s tau_r| < PADE_ORDER / 2`` (the rest are the approximant's own; the
    delay's own roots, far out, lie to the left: a retarded equation).

    Parameters
    ----------
    m_a, T_a, D, k_r, c_r : float
        As in :func:`coupling`.
    tau_r : float
        The servo's delay (s), at least 0.

    Returns
    -------
    tuple of complex
    """
    P = np.array([T_a * m_a, T_a * D + m_a, D, 0.0])
    Q = np.array([c_r, k_r])
    if tau_r <= 0:
        return tuple(complex(p) for p in np.roots(np.polyadd(P, Q)))
    num, den = _pade(tau_r)
    start = np.roots(np.polyadd(np.polymul(P, den), np.polymul(Q, num)))
    a3, a2, a1 = T_a * m_a, T_a * D + m_a, D
    out: list[complex] = []
    for s in (complex(x) for x in start):
        if abs(s * tau_r) >= 0.5 * PADE_ORDER:
            continue
        for _ in range(8):  # the approximant's root is close: a few Newton steps
            e = cmath.exp(-s * tau_r)
            q = c_r * s + k_r
            g = ((a3 * s + a2) * s + a1) * s + q * e
            dg = (3 * a3 * s + 2 * a2) * s + a1 + (c_r - tau_r * q) * e
            if dg == 0:
                break
            step = g / dg
            s -= step
            if abs(step) < 1e-12 * max(abs(s), 1.0):
                break
        if not any(abs(s - q) < 1e-6 * max(abs(s), 1) for q in out):
            out.append(s)
    return tuple(out)


def delay_margin(m_a: float, T_a: float, D: float, k_r: float, c_r: float) -> float:
    """The largest servo delay (s) the loop stands before it goes unstable.

    Open loop ``L(s) = (c_r s + k_r) / (T_a m_a s^3 + (T_a D + m_a) s^2 + D s)``: at each
    frequency where ``|L(j w)| = 1`` the delay that uses up the phase margin is
    ``(pi + arg L(j w)) / w``; the smallest over the crossings. Infinite when ``|L|``
    never reaches 1; 0 when the undelayed loop is unstable already.

    Parameters
    ----------
    m_a, T_a, D, k_r, c_r : float
        As in :func:`coupling`.

    Returns
    -------
    float
    """
    if not all(p.real < 0 for p in delayed_poles(m_a, T_a, D, k_r, c_r, 0.0)):
        return 0.0
    P = np.array([T_a * m_a, T_a * D + m_a, D, 0.0])
    Q = np.array([c_r, k_r])

    def gain(w):  # type: ignore[no-untyped-def]
        return np.log(np.abs(np.polyval(Q, 1j * w) / np.polyval(P, 1j * w)))

    w = np.logspace(-3, 4, 1400)
    g = gain(w)
    best = float("inf")
    for i in np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:])):
        from scipy.optimize import brentq

        wc = brentq(lambda x: float(gain(x)), w[i], w[i + 1], xtol=1e-12)
        L = np.polyval(Q, 1j * wc) / np.polyval(P, 1j * wc)
        phase = float(np.mod(np.pi + np.angle(L), 2 * np.pi))
        best = min(best, phase / wc)
    return best


def delayed_coupling(
    m_a: float, T_a: float, D: float, k_r: float, c_r: float, tau_r: float
) -> Coupling:
    """The coupling figures of the loop whose servo acts ``tau_r`` late.

    As :func:`coupling`, with the poles of :func:`delayed_poles`; the stability margin is
    then the delay's: ``delay_margin / tau_r - 1`` (positive when stable; the Routh
    condition's two sides, in ``terms``, are the undelayed loop's), and ``terms`` also
    hold ``tau_r`` and ``delay_margin``.

    Parameters
    ----------
    m_a, T_a, D, k_r, c_r : float
        As in :func:`coupling`.
    tau_r : float
        The servo's delay (s).

    Returns
    -------
    Coupling
    """
    plain = coupling(m_a, T_a, D, k_r, c_r)
    margin_s = delay_margin(m_a, T_a, D, k_r, c_r)
    terms = {**plain.terms, "tau_r": float(tau_r), "delay_margin": margin_s}
    if tau_r <= 0:
        return replace(plain, terms=terms)
    poles = delayed_poles(m_a, T_a, D, k_r, c_r, tau_r)
    complex_poles = [p for p in poles if abs(p.imag) > 1e-9]
    if complex_poles:
        p = max(complex_poles, key=lambda q: q.real / abs(q))
        freq, zeta = float(abs(p.imag) / (2 * np.pi)), float(-p.real / abs(p))
    else:
        freq, zeta = 0.0, 1.0
    return Coupling(freq, zeta, margin_s / tau_r - 1.0, poles, terms)
