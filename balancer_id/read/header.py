"""Column-name parsing: ``"Force (N) Run #1"`` -> quantity ``Force``, unit ``N``, run ``Run #1``.

Every export names a column ``<quantity> (<unit>) <run>``: PASCO Capstone
(``Time (s) Run #1``, ``Time (s) Auto``), PASCO SPARKvue (``Force (N) Run 1`` or a run
name the user typed, ``Force (N) 9.9``), phyphox (``Acceleration x (m/s^2)``, no run).
:func:`parse_column` splits a name into these parts and :func:`classify` says what the
column holds (time, force, acceleration, gyro, other numbers, or something to ignore).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: Column kinds :func:`classify` returns.
KINDS = ("time", "datetime", "force", "accel", "gyro", "ignore", "other")

_PAREN = re.compile(r"\(([^()]*)\)")
_UNIT_CHARS = re.compile(r"^[\w\s/^*·.\-%°²³⁻¹µμ]+$")
_RUN_ONLY = re.compile(r"^(?P<q>.*?)\s+(?P<r>Run\s*#?\s*\d+)$", re.IGNORECASE)
_DATETIME = re.compile(r"^(date\s*(and|&)\s*time|date/time|datetime|date|clock time)\b", re.I)

TIME_WORDS = frozenset(
    {
        "time",
        "t",
        "zeit",
        "tiempo",
        "czas",
        "temps",
        "tempo",
        "tijd",
        "tid",
        "aika",
        "время",
        "timestamp",
        "elapsed time",
    }
)
FORCE_WORDS = ("force", "kraft", "fuerza", "siła", "sila", "forza", "força", "kracht", "сила")
ACCEL_WORDS = (
    "accel",
    "beschleunigung",
    "aceleración",
    "aceleracion",
    "aceleração",
    "aceleracao",
    "przyspieszenie",
    "accélération",
    "acceleration",
    "accelerazione",
    "versnelling",
    "acceleratie",
    "acceleración",
    "ускорение",
    "ivme",
)
#: Words that mark a magnitude column (|a|), which the readers ignore.
MAGNITUDE_WORDS = (
    "resultant",
    "absolu",
    "magnitude",
    "norm",
    "total",
    "betrag",
    "bezwzgl",
)
GYRO_WORDS = ("gyro", "angular velocity", "rotation rate")

_ACCEL_UNITS = {
    "m/s^2": "m/s^2",
    "m/s²": "m/s^2",
    "m/s2": "m/s^2",
    "m/s/s": "m/s^2",
    "m s^-2": "m/s^2",
    "m·s⁻²": "m/s^2",
    "ms^-2": "m/s^2",
    "m/sec^2": "m/s^2",
    "g": "g",
}
#: Unit words that may end an acceleration column's name (``acc_x_g``).
_NAME_ACCEL_UNITS = {"g": "g", "ms2": "m/s^2", "mps2": "m/s^2", "m/s²": "m/s^2"}
#: Time units -> factor to seconds (headers, column names and the column map).
TIME_UNITS = {
    "s": 1.0,
    "sec": 1.0,
    "secs": 1.0,
    "seconds": 1.0,
    "ms": 1e-3,
    "msec": 1e-3,
    "millis": 1e-3,
    "us": 1e-6,
    "µs": 1e-6,
    "μs": 1e-6,
    "micros": 1e-6,
    "ns": 1e-9,
    "nanos": 1e-9,
    "min": 60.0,
}
_TIME_UNITS = TIME_UNITS
_GYRO_UNITS = ("rad/s", "deg/s", "°/s", "dps")


@dataclass(frozen=True)
class Column:
    """One parsed and classified column header.

    Attributes
    ----------
    index : int
        Position of the column in the header (0-based).
    raw : str
        The header cell as written (BOM and surrounding blanks removed).
    quantity : str
        The name before the unit (``"Acceleration x"``, ``"Accel (Resultant)"``).
    unit : str
        The unit as written, without parentheses (``"m/s²"``), ``""`` when none.
    run : str
        What follows the unit: ``"Run #1"``, ``"Run 1"``, ``"9.9"``, ``"Auto"`` or ``""``.
    kind : str
        One of :data:`KINDS`.
    axis : str
        ``"x"``, ``"y"``, ``"z"`` or ``""`` when the column names no axis.
    linear : bool
        True for a "Linear Acceleration" column (phyphox "without g").
    """

    index: int
    raw: str
    quantity: str
    unit: str
    run: str
    kind: str = "other"
    axis: str = ""
    linear: bool = False

    @property
    def label(self) -> str:
        """The name without its run suffix, ``"Position (m)"``; used for ``extra`` keys."""
        return f"{self.quantity} ({self.unit})" if self.unit else self.quantity

    @property
    def accel_unit(self) -> str:
        """Normalised acceleration unit, ``"m/s^2"``, ``"g"`` or ``""`` when unknown.

        From the unit in parentheses, else from a unit word ending the name
        (``acc_x_g``, ``AccX_ms2``).
        """
        if self.unit:
            return normalize_accel_unit(self.unit)
        last = name_tokens(self.quantity)[-1:]
        return _NAME_ACCEL_UNITS.get(last[0], "") if last else ""

    @property
    def time_scale(self) -> float:
        """Factor that turns this column's time unit into seconds (1.0 when unknown)."""
        return _TIME_UNITS.get(self.unit.strip().lower(), 1.0)


def normalize_accel_unit(unit: str) -> str:
    """Return ``"m/s^2"``, ``"g"`` or ``""`` for an acceleration unit as written.

    Parameters
    ----------
    unit : str
        The unit text, e.g. ``"m/s²"``, ``"m/s^2"``, ``"m/s2"``, ``"g"``.

    Returns
    -------
    str
        The normalised unit, ``""`` when it is not an acceleration unit.
    """
    key = unit.strip().replace(" ", " ")
    if key in _ACCEL_UNITS:
        return _ACCEL_UNITS[key]
    return _ACCEL_UNITS.get(key.lower(), "")


def split_name(raw: str) -> tuple[str, str, str]:
    """Split a header cell into ``(quantity, unit, run)``.

    The unit is the last parenthesised group that looks like a unit (it holds a
    letter, ``%`` or ``°``); what precedes it is the quantity and what follows it is the
    run. ``"Accel (Resultant) (m/s²) Run 1"`` -> ``("Accel (Resultant)", "m/s²", "Run 1")``;
    ``"Date and Time Run 1"`` -> ``("Date and Time", "", "Run 1")``.

    Parameters
    ----------
    raw : str
        The header cell.

    Returns
    -------
    tuple of str
        Quantity, unit and run, each stripped; unit and run may be ``""``.
    """
    name = raw.strip()
    for match in reversed(list(_PAREN.finditer(name))):
        inner = match.group(1).strip()
        if not inner or not _UNIT_CHARS.match(inner) or not re.search(r"[^\W\d_]|%|°", inner):
            continue
        quantity = name[: match.start()].strip()
        if not quantity:
            continue
        return quantity, inner, name[match.end() :].strip()
    only = _RUN_ONLY.match(name)
    if only:
        return only.group("q").strip(), "", only.group("r").strip()
    if _DATETIME.match(name):
        rest = _DATETIME.sub("", name).strip()
        return name[: len(name) - len(rest)].strip(), "", rest
    return name, "", ""


def _has_word(text: str, words: tuple[str, ...] | frozenset[str]) -> bool:
    return any(w in text for w in words)


def name_tokens(text: str) -> list[str]:
    """Split a column name into lower-case words, whatever the separator or naming.

    ``"AccelerationX"`` -> ``["acceleration", "x"]``, ``"acc_x"`` -> ``["acc", "x"]``,
    ``"Time sec"`` -> ``["time", "sec"]``, ``"Linear Acceleration x"`` ->
    ``["linear", "acceleration", "x"]``.

    Parameters
    ----------
    text : str
        The name (without its unit and run).

    Returns
    -------
    list of str
        The words, in order.
    """
    text = re.sub(r"([a-zà-ÿ])([A-Z])", r"\1 \2", text)
    return [t for t in re.split(r"[^\w²^µμ]+|_", text.lower()) if t]


#: Words (whole tokens) that name a time column.
TIME_TOKENS = TIME_WORDS | {
    "sec",
    "secs",
    "seconds",
    "elapsed",
    "timestamp",
    "timestamps",
    "millis",
    "micros",
    "nanos",
    "msec",
}
#: Words (whole tokens) that name a force column.
FORCE_TOKENS = frozenset({*FORCE_WORDS, "f", "load", "fz", "loadcell"})
#: A token that names an acceleration axis by itself: ``ax``, ``accX``, ``accelz``.
_AXIS_TOKEN = re.compile(r"^(?:a|acc|accel|acceleration)([xyz])$")
#: A g-force column (``gFx``, ``g-force z``, ``TgF`` its total): acceleration in g.
_G_FORCE = re.compile(r"^(t)?g-?f(?:orce)?[-_]?([xyz])?$")
#: Words that mark the gravity vector of a phone (iOS ``gravityX``): not an acceleration.
GRAVITY_WORDS = frozenset({"gravity", "grav", "schwerkraft"})
#: Words that mark an acceleration without gravity (phyphox, iOS ``userAcceleration``).
LINEAR_WORDS = frozenset(
    {
        "linear",
        "lin",
        "user",
        "linacc",
        "lineare",
        "lineal",
        "linéaire",
        "lineaire",
        "liniowe",
        "lineair",
        "linear_acceleration",
    }
)
_FORCE_UNITS = ("n", "kn", "mn", "lbf", "kgf", "")


def _is_accel_word(token: str) -> bool:
    """``acc``, ``accel...``, ``accx`` or a word of :data:`ACCEL_WORDS` (not ``accuracy``)."""
    return (
        token in ("acc", "accs")
        or _AXIS_TOKEN.match(token) is not None
        or _has_word(token, ACCEL_WORDS)
    )


def _axis_of(tokens: list[str]) -> str:
    """The axis a name's words give (``x``, ``y``, ``z``), ``""`` when none."""
    for token in tokens:
        if token in ("x", "y", "z"):
            return token
        found = _AXIS_TOKEN.match(token)
        if found:
            return found.group(1)
    return ""


def _time_like(tokens: list[str], unit: str) -> bool:
    """True for a time column's name: a time word, the rest time words or units."""
    if not tokens or not (unit in TIME_UNITS or unit == ""):
        return False
    words = set(tokens)
    if not words & TIME_TOKENS:
        return False
    if unit:  # a time word and a time unit: "accelerometerTimestamp_sinceReboot (s)"
        return True
    allowed = TIME_TOKENS | set(TIME_UNITS) | {"since", "start", "relative", "rel", "run"}
    return tokens[0] in TIME_TOKENS or words <= allowed


def classify(index: int, raw: str) -> Column:
    """Parse and classify one header cell: the one column recognition of every layout.

    The name is split into words whatever its separator or naming (``AccelerationX``,
    ``acc_x``, ``Acceleration - x``, ``X-axis acceleration``); the words and the unit
    suggest what the column holds. Names only suggest: the units and whether gravity is
    included are decided from the values (:mod:`~balancer_id.read.units`,
    :mod:`~balancer_id.read.timebase`).

    Parameters
    ----------
    index : int
        Position of the column in the header.
    raw : str
        The header cell as written.

    Returns
    -------
    Column
        The parsed column with its kind, axis and "linear" flag.
    """
    raw = raw.replace("\ufeff", "").strip()
    quantity, unit, run = split_name(raw)
    q = quantity.lower().strip()
    u = unit.strip().lower()
    tokens = name_tokens(quantity)
    words = set(tokens)
    kind = "other"
    axis = ""
    linear = False
    accel_unit = normalize_accel_unit(unit)
    gforce = _G_FORCE.match(q.replace(" ", ""))
    if gforce and (not u or accel_unit == "g"):  # Physics Toolbox's gFx, gFy, gFz, TgF
        total = gforce.group(1) == "t" or not gforce.group(2)
        kind = "ignore" if total else "accel"
        axis = "" if total else gforce.group(2)
        return Column(index, raw, quantity, unit or "g", run, kind, axis, False)
    kind = _kind_of(q, u, tokens, accel_unit)
    if kind == "accel-like":
        kind = "ignore" if _has_word(q, MAGNITUDE_WORDS) or "abs" in words else "accel"
        linear = bool(words & LINEAR_WORDS)
    if kind in ("accel", "gyro"):
        axis = _axis_of(tokens)
    return Column(index, raw, quantity, unit, run, kind, axis, linear)


def _kind_of(q: str, u: str, tokens: list[str], accel_unit: str) -> str:
    """What a column's name and unit say it holds (``accel-like``: an acceleration or its
    magnitude)."""
    words = set(tokens)
    if _DATETIME.match(q):
        return "datetime"
    if (q in TIME_WORDS and (u in _TIME_UNITS or u == "")) or _time_like(tokens, u):
        return "time"
    if (words & FORCE_TOKENS or _has_word(q, FORCE_WORDS)) and u in _FORCE_UNITS:
        return "force"
    if _has_word(q, GYRO_WORDS) or u in _GYRO_UNITS or "rotation" in words:
        return "gyro"
    if words & GRAVITY_WORDS:
        return "other"
    return "accel-like" if _accel_name(q, u, tokens, accel_unit) else "other"


def _accel_name(q: str, u: str, tokens: list[str], accel_unit: str) -> bool:
    """Whether the name reads as an acceleration (a word, an axis letter, ``a_x``)."""
    return bool(
        any(_is_accel_word(t) for t in tokens)
        or _has_word(q, ACCEL_WORDS)
        or (len(tokens) == 1 and _AXIS_TOKEN.match(tokens[0]) is not None)
        or (tokens in (["x"], ["y"], ["z"]) and accel_unit != "")
        or (
            tokens[:1] == ["a"]
            and (accel_unit or not u)
            and (len(tokens) == 1 or _axis_of(tokens[1:]) != "")
        )
    )


def classify_header(names: list[str]) -> list[Column]:
    """Classify every cell of a header row.

    Parameters
    ----------
    names : list of str
        The header cells in file order.

    Returns
    -------
    list of Column
        One per cell, same order.
    """
    return [classify(i, name) for i, name in enumerate(names)]
