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

from dataclasses import dataclass
from typing import Any

import numpy as np

from balancer_id.errors import UsageError
from balancer_id.notes import Note
from balancer_id.read.inference import Inference

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

    def __init__(
        self, message: str, hint: str, counts_per_g: int | None = None, spec: str = ""
    ) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint
        self.counts_per_g = counts_per_g
        self.spec = spec or (f"counts/{counts_per_g}g" if counts_per_g else "")


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


@dataclass(frozen=True)
class Rest:
    """How an acceleration rests: the evidence for its unit and for gravity.

    Attributes
    ----------
    level : float
        Median magnitude of the vector over the quietest quarter of the log's windows
        (in the values' own unit).
    spread : float
        Median size of the vector's fluctuation inside those windows.
    coherence : float
        Median over those windows of ``|mean vector| / mean magnitude``: near 1 when the
        vector holds one direction at rest (gravity), small when it wanders (noise of an
        acceleration without gravity).
    constancy : float
        Relative robust spread of the mean vector's length from one resting window to
        another: small for gravity, large for the slow sway of a hand.
    overall : float
        Length of the whole log's mean vector over ``level``: near 1 when gravity keeps
        its direction in the sensor's frame, small for a gravity-free acceleration.
    """

    level: float
    spread: float
    coherence: float
    constancy: float = 0.0
    overall: float = 1.0

    @property
    def steady(self) -> bool:
        """True when the resting vector holds one direction and one length (gravity).

        Its windows hold their direction, its fluctuation there is small beside its
        length, and either its length is the same from rest to rest or the whole log's
        mean vector is nearly as long (gravity held in the sensor's frame while it
        moves: walking, a ride). A hand's sway of a gravity-free acceleration fluctuates
        by a third of its length or more.
        """
        if self.coherence < STEADY_COHERENCE or self.spread > STEADY_SPREAD * self.level:
            return False
        return self.constancy <= STEADY_LENGTH or self.overall >= STEADY_OVERALL

    def said(self, unit: str = "") -> str:
        """The evidence in words: ``"resting magnitude 0.998 ± 0.004, constant direction"``.

        Parameters
        ----------
        unit : str
            Unit written after the numbers (``""``: none).

        Returns
        -------
        str
        """
        tail = f" {unit}" if unit else ""
        if self.steady:
            how = "constant direction"
        elif self.coherence < STEADY_COHERENCE:
            how = f"no constant direction (coherence {self.coherence:.2f})"
        else:
            how = f"its length changes from rest to rest by {100 * self.constancy:.0f} %"
        size = (
            f"{self.level:.3f} ± {self.spread:.3f}"
            if self.level < 100
            else (f"{self.level:.4g} ± {self.spread:.2g}")
        )
        return f"resting magnitude {size}{tail}, {how}"


#: A resting vector whose windows keep ``|mean| / mean |a|`` above this holds one direction.
STEADY_COHERENCE = 0.8
#: ... and gravity's length changes from one resting window to another by less than this
#: (relative robust spread); a hand-held sway of a gravity-free acceleration does not.
STEADY_LENGTH = 0.15
#: ... or the whole log's mean vector is this share of the resting magnitude or more.
STEADY_OVERALL = 0.8
#: Gravity's vector fluctuates in its quietest windows by less than this share of its length.
STEADY_SPREAD = 0.25


def rest_of(block: np.ndarray) -> Rest:
    """Measure how an acceleration block rests (see :class:`Rest`).

    The block is cut into windows (at least 40 of them, 5 to 200 samples each); the
    quietest quarter (smallest fluctuation of the vector) is where the sensor rests.

    Parameters
    ----------
    block : numpy.ndarray
        Shape ``(n, k)``; rows with a NaN are left out.

    Returns
    -------
    Rest
        Level, spread and coherence; NaN when the block has no finite row.
    """
    rows = block[np.all(np.isfinite(block), axis=1)]
    n, k = rows.shape
    if n == 0:
        return Rest(float("nan"), float("nan"), float("nan"))
    width = int(min(200, max(5, n // 40)))
    count = max(1, n // width)
    width = min(width, n)
    x = rows[: count * width].reshape(count, width, k)
    magnitude = np.sqrt(np.einsum("mwk,mwk->mw", x, x)).mean(axis=1)
    motion = np.sqrt((x.std(axis=1) ** 2).sum(axis=1))
    quiet = motion <= np.quantile(motion, 0.25)
    mean_vec = np.linalg.norm(x.mean(axis=1), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.where(magnitude > 0, mean_vec / magnitude, 0.0)
    lengths = mean_vec[quiet]
    middle = float(np.median(lengths))
    spread = float(np.median(np.abs(lengths - middle))) * 1.4826
    level = float(np.median(magnitude[quiet]))
    overall = float(np.linalg.norm(rows.mean(axis=0))) / level if level > 0 else 0.0
    return Rest(
        level,
        float(np.median(motion[quiet])),
        float(np.median(coherence[quiet])),
        spread / middle if middle > 0 else float("inf"),
        overall,
    )


def _scale_of(level: float) -> tuple[str, str, str] | None:
    """A level a power of ten away from gravity: ``(what, factor, spec)``, else None.

    ``9.87e9`` is 9.8 m/s^2 times 1e9 (a spreadsheet's scaling); ``1000`` is 1 g in mg.
    """
    options = []
    for base, unit in ((_G_STANDARD, "m/s^2"), (1.0, "g")):
        power = float(np.log10(level / base))
        k = round(power)
        if k >= 2 and abs(power - k) < 0.06:
            options.append((abs(power - k), unit, k))
    if not options:
        return None
    _, unit, k = min(options)
    return unit, f"1e{k}", f"1e-{k}{unit}"


def raw_scale_error(level: float) -> UnitMismatch:
    """The refusal of an acceleration resting at ``level`` > :data:`RAW_COUNTS_MIN`.

    A power of ten from gravity (``9.87e9``: m/s^2 times a billion; ``1000``: mg) is
    named as such; anything else is taken for raw counts (a power of two per g).

    Parameters
    ----------
    level : float
        The resting magnitude as read.

    Returns
    -------
    UnitMismatch
        With the scale to give in the column map.
    """
    scaled = _scale_of(level)
    if scaled is not None:
        unit, factor, spec = scaled
        words = {"1e3": "a thousand", "1e6": "a million", "1e9": "a billion"}
        size = words.get(factor, f"{factor}")
        if unit == "g" and factor == "1e3":
            return UnitMismatch(
                f"the acceleration rests at a magnitude of {level:.4g}: values in mg "
                "(thousandths of g), at no physical scale as g or m/s^2",
                "give the unit in the column map, e.g. ax=NAME:mg",
                spec="mg",
            )
        return UnitMismatch(
            f"the acceleration rests at a magnitude of {level:.4g}: {size} times too large "
            f"for {unit} (values at no physical scale: {level / float(factor):.3g} {unit} "
            f"× {factor}; a spreadsheet's re-export?)",
            f"export the values again unscaled, or give the scale: ax=NAME:{spec}",
            spec=spec,
        )
    per_g = int(2 ** round(np.log2(level)))
    return UnitMismatch(
        f"the acceleration rests at a magnitude of {level:.4g}, neither ~9.8 (m/s^2) nor "
        f"~1 (g): raw sensor counts (~{per_g} counts per g?) or another unit",
        f"give the scale in the column map, e.g. ax=NAME:counts/{per_g}g",
        counts_per_g=per_g,
    )


def resolve_accel(
    accel: np.ndarray,
    *,
    header_unit: str,
    includes_gravity: bool | None,
    accel_unit: str,
    g: float,
    gravity_given: bool = False,
) -> tuple[np.ndarray, bool, str | Note | None, list[Inference]]:
    """Convert an acceleration block to m/s^2 and decide whether it includes gravity.

    Decided by content, names only suggest: the resting vector (:func:`rest_of`) holds
    one direction and a magnitude near 1 (g) or 9.8 (m/s^2) when gravity is in it; an
    acceleration without gravity rests near 0 in no fixed direction and is never scaled
    as g.

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
    gravity_given : bool
        True when the user's column map gave ``includes_gravity`` (never overruled).

    Returns
    -------
    accel : numpy.ndarray
        In m/s^2.
    includes_gravity : bool
        The decision.
    warning : Note, str or None
        A message when the unit was guessed from the values, or a header unit or the
        header's with/without g was contradicted by them (``read.gravity_header``).
    inferences : list of Inference
        The unit and gravity decisions with their evidence.

    Raises
    ------
    UnitMismatch
        The resting magnitude contradicts a unit the user forced, or ``g``, or (auto)
        is beyond 25 (2.5 g): raw counts or values at no physical scale, refused with the
        scale to give.
    """
    said: list[Inference] = []
    if accel.size == 0:
        return accel, bool(includes_gravity) if includes_gravity is not None else True, None, said
    sub = accel[:: max(1, accel.shape[0] // 1_000_000)]  # a million samples tell the level
    rest = rest_of(sub)
    level = rest.level
    if not np.isfinite(level):
        return accel, bool(includes_gravity) if includes_gravity is not None else True, None, said
    explicit_g = accel_unit == "g" or (accel_unit == "auto" and header_unit == "g")
    if level > RAW_COUNTS_MIN:  # in any unit: no log's acceleration sits at 2.5 g
        raise raw_scale_error(level)
    gravity_note = None
    from_header = includes_gravity is not None
    if (
        accel_unit == "auto"
        and includes_gravity is not None
        and accel.shape[1] == 3
        and not gravity_given
    ):
        includes_gravity, gravity_note = _check_gravity_claim(sub, level, includes_gravity)
        from_header = gravity_note is None
    case = _Accel(accel, rest, header_unit, includes_gravity, accel_unit, g, gravity_given,
                  from_header)
    if explicit_g:
        return _resolve_as_g(case, gravity_note)
    return _resolve_as_ms2(case, gravity_note)


@dataclass(frozen=True)
class _Accel:
    """An acceleration block being resolved, and what is known of it."""

    accel: np.ndarray
    rest: Any
    header_unit: str
    includes_gravity: bool | None
    accel_unit: str
    g: float
    gravity_given: bool
    from_header: bool

    @property
    def level(self) -> float:
        return float(self.rest.level)

    def gravity(self, includes: bool, unit: str) -> Inference:
        """The gravity decision, as an inference."""
        return _gravity_inference(includes, self.rest, unit, self.from_header, self.gravity_given)


_Resolved = tuple[np.ndarray, bool, str | Note | None, list[Inference]]


def _resolve_as_g(case: _Accel, gravity_note: str | Note | None) -> _Resolved:
    """The unit is g (given, or the header's): converted, unless the values are m/s^2."""
    accel, rest, level, g = case.accel, case.rest, case.level, case.g
    includes_gravity = case.includes_gravity
    said: list[Inference] = []
    if includes_gravity is not False and _near(level, g) and g > 2 * _G_HIGH:
        if case.accel_unit == "g":
            raise UnitMismatch(
                f"the acceleration rests at {level:.2f}, which is {level * g:.0f} m/s^2 in g: "
                "the values are in m/s^2, not g",
                "pass --accel-unit m/s^2 or auto",
            )
        note = (
            f"the header says g but the acceleration rests at {level:.2f} "
            f"({level * g:.0f} m/s^2 as g): the values are taken as m/s^2, not converted"
        )
        if includes_gravity is None:
            includes_gravity = True
        _check_g(level, g)
        said.append(
            Inference(
                "acceleration unit", "m/s^2", rest.said() + "; the header says g", "--accel-unit g"
            )
        )
        said.append(case.gravity(True, "m/s^2"))
        return accel, includes_gravity, note, said
    where = "given with --accel-unit" if case.accel_unit == "g" else "the header says g"
    accel = accel * g
    level *= g
    if includes_gravity is None:
        includes_gravity = level > g / 2
    if includes_gravity:
        _check_g(level, g)
    said.append(
        Inference(
            "acceleration unit",
            "g",
            f"{where}; {rest.said('g')}",
            "" if case.accel_unit == "g" else "--accel-unit m/s^2",
        )
    )
    said.append(case.gravity(includes_gravity, "g"))
    return accel, includes_gravity, gravity_note, said


def _resolve_as_ms2(case: _Accel, gravity_note: str | Note | None) -> _Resolved:
    """No g stated: m/s^2 unless the values rest at g's magnitude (then converted)."""
    accel, rest, level = case.accel, case.rest, case.level
    if (
        case.accel_unit == "m/s^2"
        and accel.shape[1] > 1
        and case.includes_gravity is not False
        and _G_LOW < level < _G_HIGH
        and rest.steady
    ):
        raise UnitMismatch(
            f"the acceleration rests at a magnitude of {level:.2f} m/s^2 in a constant "
            "direction; an accelerometer that includes gravity reads ~9.8 m/s^2 at rest: "
            "the values look like g",
            "pass --accel-unit g or auto",
        )
    if (
        accel.shape[1] == 1
        and case.accel_unit == "auto"
        and not case.header_unit
        and case.includes_gravity is not False
        and rest.steady
        and 0.8 < level < 1.2
    ):  # one axis resting steadily at ~1: gravity in g (a kinematic acceleration rests at 0)
        said = [
            Inference(
                "acceleration unit",
                "g",
                f"no unit stated; one axis {rest.said()}: gravity in g, since a "
                "kinematic acceleration rests at 0",
                "--accel-unit m/s^2",
            ),
            case.gravity(True, "g"),
        ]
        warning = (
            f"the one acceleration axis rests steadily at {level:.2f}: gravity in g; "
            "converted to m/s^2 (pass --accel-unit m/s^2 if wrong)"
        )
        return accel * case.g, True, warning, said
    if case.accel_unit == "m/s^2" or accel.shape[1] == 1:
        return _declared_ms2(case)
    return _auto_ms2(case, gravity_note)


def _declared_ms2(case: _Accel) -> _Resolved:
    """m/s^2 given, or one axis (never taken for g from its values)."""
    includes_gravity = case.includes_gravity
    if includes_gravity is None:
        includes_gravity = case.level > case.g / 2
    if includes_gravity:
        _check_g(case.level, case.g)
    where = (
        "given with --accel-unit"
        if case.accel_unit == "m/s^2"
        else (
            "the header says m/s^2"
            if case.header_unit == "m/s^2"
            else "no unit stated; one axis is never taken for g from its values"
        )
    )
    said = [
        Inference(
            "acceleration unit",
            "m/s^2",
            f"{where}; {case.rest.said()}",
            "" if case.accel_unit == "m/s^2" else "--accel-unit g",
            weak=not case.header_unit and case.accel_unit == "auto" and not includes_gravity,
        ),
        case.gravity(includes_gravity, "m/s^2"),
    ]
    return case.accel, includes_gravity, None, said


def _auto_ms2(case: _Accel, gravity_note: str | Note | None) -> _Resolved:
    """Several axes, no unit given: g when they rest steadily at g's magnitude."""
    rest, level, g, header_unit = case.rest, case.level, case.g, case.header_unit
    looks_like_g = _G_LOW < level < _G_HIGH and rest.steady
    includes_gravity = case.includes_gravity
    if includes_gravity is None:
        includes_gravity = level >= _WITH_G_MIN or looks_like_g  # 4 m/s^2 at rest is g
    if includes_gravity and not looks_like_g:
        _check_g(level, g)
    if includes_gravity and looks_like_g:
        _check_g(level * g, g)
        warning = (
            f"acceleration magnitude at rest is {level:.2f}, which looks like g rather than "
            "m/s^2; converted to m/s^2 (pass accel_unit='m/s^2' or --accel-unit m/s^2 if wrong)"
        )
        said = [
            Inference(
                "acceleration unit",
                "g",
                rest.said() + ("; the header says m/s^2" if header_unit == "m/s^2" else ""),
                "--accel-unit m/s^2",
            ),
            case.gravity(True, "g"),
        ]
        return case.accel * g, True, warning, said
    weak = not includes_gravity and not header_unit
    said = [
        Inference(
            "acceleration unit",
            "m/s^2",
            (
                f"the header says m/s^2; {rest.said()}"
                if header_unit == "m/s^2"
                else f"no unit stated; {rest.said()}"
                + ("" if includes_gravity else ": no gravity to scale against, taken as m/s^2")
            ),
            "--accel-unit g",
            weak=weak,
        ),
        case.gravity(includes_gravity, "m/s^2"),
    ]
    return case.accel, includes_gravity, gravity_note, said

def _gravity_inference(
    with_g: bool, rest: Rest, unit: str, from_header: bool, given: bool
) -> Inference:
    """The ``gravity`` inference: in or out, from the column map, the header or the data."""
    decision = "included" if with_g else "removed (acceleration without g)"
    if given:
        return Inference("gravity", decision, "given in the column map")
    source = "the header names it; " if from_header else ""
    override = "--columns ...,gravity=" + ("no" if with_g else "yes")
    looks_with_g = rest.steady and (_near(rest.level, 1.0) or _near(rest.level, _G_STANDARD))
    weak = with_g != looks_with_g and not from_header
    return Inference("gravity", decision, source + rest.said(unit), override, weak=weak)


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
