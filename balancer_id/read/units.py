"""Acceleration units and gravity: is it in g or m/s^2, does it include g?

Rules (documented in the package docs):

* a header unit ``(g)`` (or ``accel_unit="g"``) -> multiply by g, no warning;
* ``accel_unit="m/s^2"`` -> take the values as they are;
* ``accel_unit="auto"`` and an acceleration that includes gravity: the median magnitude
  of the acceleration vector (the resting magnitude, since most of a log is at rest)
  is ~1 for values in g and ~9.8 for m/s^2. Values near 1 are converted and a warning
  says so;
* whether a three-axis acceleration includes gravity, when the layout does not say
  (PASCO, phyphox per-sensor files, generic logs): yes when the median magnitude is
  above 4 m/s^2 (or near 1 g), no when it is below 0.7;
* a single acceleration column (a motion sensor's ``Acceleration (m/s²)``, a generic
  ``a``) includes gravity when its median is beyond g/2 in size; it is never guessed to
  be in g (a kinematic acceleration of ~1 m/s^2 is common), only converted when its
  unit says ``g``.
"""

from __future__ import annotations

import numpy as np

from balancer_id.errors import UsageError

#: Values ``accel_unit`` accepts.
ACCEL_UNITS = ("auto", "m/s^2", "g")
_ALIASES = {"m/s²": "m/s^2", "m/s2": "m/s^2", "ms2": "m/s^2", "mps2": "m/s^2", "si": "m/s^2"}

_G_LOW, _G_HIGH = 0.7, 1.3
_WITH_G_MIN = 4.0


def check_accel_unit(accel_unit: str) -> str:
    """Normalise the ``accel_unit`` argument.

    Parameters
    ----------
    accel_unit : str
        ``"auto"``, ``"m/s^2"`` (also ``"m/s²"``, ``"m/s2"``) or ``"g"``.

    Returns
    -------
    str
        One of :data:`ACCEL_UNITS`.

    Raises
    ------
    UsageError
        Any other value.
    """
    key = str(accel_unit).strip()
    key = _ALIASES.get(key.lower(), key) if key.lower() != "g" else "g"
    if key not in ACCEL_UNITS:
        raise UsageError(f"accel_unit must be one of {', '.join(ACCEL_UNITS)}, not {accel_unit!r}")
    return key


def resolve_accel(
    accel: np.ndarray,
    *,
    header_unit: str,
    includes_gravity: bool | None,
    accel_unit: str,
    g: float,
) -> tuple[np.ndarray, bool, str | None]:
    """Convert an acceleration block to m/s^2 and decide whether it includes gravity.

    Parameters
    ----------
    accel : numpy.ndarray
        Shape ``(n, k)`` as read.
    header_unit : str
        ``"m/s^2"``, ``"g"`` or ``""`` from the header.
    includes_gravity : bool or None
        What the layout says, or None to decide from the data.
    accel_unit : str
        The user's choice, one of :data:`ACCEL_UNITS`.
    g : float
        Gravity (m/s^2) used to convert g.

    Returns
    -------
    accel : numpy.ndarray
        In m/s^2.
    includes_gravity : bool
        The decision.
    warning : str or None
        A message when the unit was guessed from the values.
    """
    if accel.size == 0:
        return accel, bool(includes_gravity) if includes_gravity is not None else True, None
    if accel.shape[1] == 1:
        level = float(np.abs(np.median(accel[:, 0])))
    else:
        level = float(np.median(np.sqrt(np.einsum("ij,ij->i", accel, accel))))
    explicit_g = accel_unit == "g" or (accel_unit == "auto" and header_unit == "g")
    if explicit_g:
        accel = accel * g
        level *= g
        if includes_gravity is None:
            includes_gravity = level > g / 2
        return accel, includes_gravity, None
    if accel_unit == "m/s^2" or accel.shape[1] == 1:
        if includes_gravity is None:
            includes_gravity = level > g / 2
        return accel, includes_gravity, None
    looks_like_g = _G_LOW < level < _G_HIGH
    if includes_gravity is None:
        includes_gravity = level >= _WITH_G_MIN or looks_like_g
    if includes_gravity and looks_like_g:
        warning = (
            f"acceleration magnitude at rest is {level:.2f}, which looks like g rather than "
            "m/s^2; converted to m/s^2 (pass accel_unit='m/s^2' or --accel-unit m/s^2 if wrong)"
        )
        return accel * g, True, warning
    return accel, includes_gravity, None
