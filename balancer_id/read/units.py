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

Plausibility (the resting magnitude against the unit and ``g``), never fitted silently:

* values taken as g (``accel_unit="g"``, or a ``(g)`` header) that rest at ~g (so ~g^2,
  ~96 m/s^2, once converted) are m/s^2: refused when the user forced ``g``
  (:class:`UnitMismatch`), kept as m/s^2 with a warning when only the header said g;
* three axes forced to ``m/s^2`` that include gravity and rest at ~1 are in g: refused;
* an acceleration with gravity that rests at ~9.8 m/s^2 while ``g`` is far from it
  (``g=1``): the ``g`` setting is refused.
"""

from __future__ import annotations

import numpy as np

from balancer_id.errors import UsageError
from balancer_id.notes import Note

#: Values ``accel_unit`` accepts.
ACCEL_UNITS = ("auto", "m/s^2", "g")
_ALIASES = {"m/s²": "m/s^2", "m/s2": "m/s^2", "ms2": "m/s^2", "mps2": "m/s^2", "si": "m/s^2"}

_G_LOW, _G_HIGH = 0.7, 1.3
_WITH_G_MIN = 4.0
#: A median magnitude beyond this (m/s^2 or g; 2.5 g) is no log's acceleration: raw counts
#: (or a unit such as ft/s^2, 32.2 at rest).
RAW_COUNTS_MIN = 25.0
_G_STANDARD = 9.80665


class UnitMismatch(ValueError):
    """The resting magnitude of the acceleration contradicts its unit or ``g``.

    Parameters
    ----------
    message : str
        What contradicts what.
    hint : str
        What to do.
    """

    def __init__(self, message: str, hint: str, counts_per_g: int | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint
        self.counts_per_g = counts_per_g


def _near(value: float, target: float) -> bool:
    return _G_LOW * target < value < _G_HIGH * target


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
) -> tuple[np.ndarray, bool, str | Note | None]:
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
    warning : Note, str or None
        A message when the unit was guessed from the values, or a header unit or the
        header's with/without g was contradicted by them (``read.gravity_header``).

    Raises
    ------
    UnitMismatch
        The resting magnitude contradicts a unit the user forced, or ``g``, or (auto)
        is beyond 25 (2.5 g): raw counts, refused with the scale to give.
    """
    if accel.size == 0:
        return accel, bool(includes_gravity) if includes_gravity is not None else True, None
    sub = accel[:: max(1, accel.shape[0] // 1_000_000)]  # a million samples tell the level
    if accel.shape[1] == 1:
        level = float(np.abs(np.median(sub[:, 0])))
    else:
        level = float(np.median(np.sqrt(np.einsum("ij,ij->i", sub, sub))))
    explicit_g = accel_unit == "g" or (accel_unit == "auto" and header_unit == "g")
    if level > RAW_COUNTS_MIN:  # in any unit: no log's acceleration sits at 2.5 g
        per_g = int(2 ** round(np.log2(level)))
        raise UnitMismatch(
            f"the acceleration rests at a magnitude of {level:.4g}, neither ~9.8 (m/s^2) nor "
            f"~1 (g): raw sensor counts (~{per_g} counts per g?) or another unit",
            f"give the scale in the column map, e.g. ax=NAME:counts/{per_g}g",
            counts_per_g=per_g,
        )
    gravity_note = None
    if accel_unit == "auto" and includes_gravity is not None and accel.shape[1] == 3:
        includes_gravity, gravity_note = _check_gravity_claim(sub, level, includes_gravity)
    if explicit_g and includes_gravity is not False and _near(level, g) and g > 2 * _G_HIGH:
        if accel_unit == "g":
            raise UnitMismatch(
                f"the acceleration rests at {level:.2f}, which is {level * g:.0f} m/s^2 in g: "
                "the values are in m/s^2, not g",
                "pass --accel-unit m/s^2 or auto",
            )
        explicit_g = False
        note = (
            f"the header says g but the acceleration rests at {level:.2f} "
            f"({level * g:.0f} m/s^2 as g): the values are taken as m/s^2, not converted"
        )
        if includes_gravity is None:
            includes_gravity = True
        _check_g(level, g)
        return accel, includes_gravity, note
    if explicit_g:
        accel = accel * g
        level *= g
        if includes_gravity is None:
            includes_gravity = level > g / 2
        if includes_gravity:
            _check_g(level, g)
        return accel, includes_gravity, gravity_note
    if (
        accel_unit == "m/s^2"
        and accel.shape[1] > 1
        and includes_gravity is not False
        and _G_LOW < level < _G_HIGH
    ):
        raise UnitMismatch(
            f"the acceleration rests at a magnitude of {level:.2f} m/s^2; an accelerometer "
            "that includes gravity reads ~9.8 m/s^2 at rest: the values look like g",
            "pass --accel-unit g or auto",
        )
    if accel_unit == "m/s^2" or accel.shape[1] == 1:
        if includes_gravity is None:
            includes_gravity = level > g / 2
        if includes_gravity:
            _check_g(level, g)
        return accel, includes_gravity, None
    looks_like_g = _G_LOW < level < _G_HIGH
    if includes_gravity is None:
        includes_gravity = level >= _WITH_G_MIN or looks_like_g
    if includes_gravity and not looks_like_g:
        _check_g(level, g)
    if includes_gravity and looks_like_g:
        _check_g(level * g, g)
        warning = (
            f"acceleration magnitude at rest is {level:.2f}, which looks like g rather than "
            "m/s^2; converted to m/s^2 (pass accel_unit='m/s^2' or --accel-unit m/s^2 if wrong)"
        )
        return accel * g, True, warning
    return accel, includes_gravity, gravity_note


def _check_gravity_claim(sub: np.ndarray, level: float, claimed: bool) -> tuple[bool, Note | None]:
    """Compare what the header says about gravity with the data.

    With gravity, the mean vector of a log (gravity, mostly at rest) is large and the
    magnitude sits near 9.8 (or 1 in g); without it, both are small. A header that says
    "with g" over data whose magnitude and mean vector are both small (under 0.7 and
    2 m/s^2) is data without gravity; a "without g" header over data whose mean vector is
    near 9.8 m/s^2 is data with gravity. Either is warned (``read.gravity_header``) and
    the data decide.
    """
    mean = float(np.linalg.norm(np.nanmean(sub, axis=0)))
    if claimed and level < _G_LOW and mean < 2.0:
        return False, Note(
            "read.gravity_header",
            f"the header names acceleration with g, but the values hold no gravity (magnitude "
            f"{level:.2f}, mean vector {mean:.2f}): read as acceleration without g",
        )
    if not claimed and _near(mean, _G_STANDARD) and _near(level, _G_STANDARD):
        return True, Note(
            "read.gravity_header",
            f"the header names acceleration without g, but the values hold gravity (mean "
            f"vector {mean:.2f} m/s^2): read as acceleration with g",
        )
    return claimed, None


def _check_g(level: float, g: float) -> None:
    """Refuse a ``g`` setting that the resting magnitude (m/s^2) of a with-g log contradicts."""
    if _near(level, _G_STANDARD) and not _near(g, _G_STANDARD):
        raise UnitMismatch(
            f"the acceleration rests at {level:.2f} m/s^2 (gravity), which contradicts "
            f"g = {g:g} m/s^2",
            f"pass --g {_G_STANDARD:.2f} or the local gravity",
        )
