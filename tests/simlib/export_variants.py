"""Export variants: the known layouts crossed with the ways real exports differ (issue 32).

Each class of :data:`CLASSES` draws random variants of a force/acceleration log (a thrust
step and the load's damped response, gravity on a tilted axis, noise): separators and
decimal commas, header names in the apps' languages, units (g, m/s^2, mg, raw counts,
time in ms/µs/ns), no header, reordered, renamed and extra channels, gravity in or out,
event-timed channels beside sampled ones, values at no physical scale, clipping at a
sensor's range, values repeated in pairs. A :class:`Variant` holds the file's bytes and
what a right reading is (or the words a right refusal holds); :func:`judge` reads it as a
user would and says ``right``, ``clear`` (refused, naming the cause), ``unhelpful`` or
``misread``. ``tests/test_read_variants.py`` runs a few of each class;
``benchmarks/bench_layouts.py`` many, with a printed seed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from balancer_id.constants import G_DEFAULT

OUTCOMES = ("right", "clear", "unhelpful", "misread")


@dataclass
class Signals:
    """The truth of one log: time (s), force (N), acceleration (m/s^2, x y z)."""

    t: np.ndarray
    force: np.ndarray
    accel: np.ndarray
    gravity: bool
    rate: float


@dataclass
class Variant:
    """One export variant and its right reading.

    Attributes
    ----------
    cls, name : str
        The class (a row of the bench's table) and what this variant is.
    filename : str
        The file's name (some layouts are told by it).
    content : bytes
        The file.
    expect : str
        ``"read"`` or ``"refuse"``.
    truth : Signals
        What a right reading holds.
    facts : dict
        What is checked of a reading: ``format``, ``force`` (bool), ``gravity`` (bool),
        ``notes`` (codes), ``rate`` (Hz, default the truth's), ``n`` (samples).
    mention : tuple of str
        Words a right refusal holds (lower case).
    """

    cls: str
    name: str
    filename: str
    content: bytes
    expect: str
    truth: Signals
    facts: dict[str, Any] = field(default_factory=dict)
    mention: tuple[str, ...] = ()


def signals(
    rng: np.random.Generator, *, gravity: bool = True, rate: float | None = None
) -> Signals:
    """A seeded log: a thrust step and the load's damped response, tilted sensor, noise.

    Parameters
    ----------
    rng : numpy.random.Generator
        The random source.
    gravity : bool
        True for an accelerometer that includes gravity.
    rate : float, optional
        Sample rate (Hz); drawn from 50, 100, 200, 500 when not given.

    Returns
    -------
    Signals
    """
    rate = float(rate or rng.choice([50, 100, 200, 500]))
    n = int(rate * rng.uniform(6.0, 12.0))
    t = np.arange(n) / rate
    t_step = rng.uniform(0.35, 0.6) * t[-1]
    step = rng.uniform(3.0, 15.0) * rng.choice([-1.0, 1.0])
    force = rng.uniform(0.0, 20.0) + step * (t >= t_step) + 0.02 * rng.standard_normal(n)
    tau = np.clip(t - t_step, 0.0, None)
    wn, zeta = rng.uniform(3.0, 15.0), rng.uniform(0.1, 0.5)
    motion = np.sign(step) * rng.uniform(0.5, 4.0) * np.exp(-zeta * wn * tau)
    motion *= np.cos(wn * np.sqrt(1 - zeta**2) * tau) * (t >= t_step)
    up = np.zeros(3)
    up[rng.integers(3)] = rng.choice([-1.0, 1.0])
    up = up + rng.normal(0.0, 0.25, 3)
    up /= np.linalg.norm(up)
    noise = rng.uniform(0.01, 0.05)
    accel = np.outer(G_DEFAULT * gravity + motion, up) + noise * rng.standard_normal((n, 3))
    return Signals(t, force, accel, gravity, rate)


# ---------------------------------------------------------------- writing a file


def _cells(values: np.ndarray, fmt: str, decimal: str) -> list[str]:
    out = [("" if not np.isfinite(v) else fmt % v) for v in values]
    return [c.replace(".", ",") for c in out] if decimal == "," else out


def render(
    header: list[str] | None,
    columns: list[np.ndarray | list[str]],
    *,
    delimiter: str = ",",
    decimal: str = ".",
    fmt: str = "%.9g",
    quote_header: bool = False,
) -> bytes:
    """The CSV text of a table: a header (or none) and columns of numbers or text.

    Parameters
    ----------
    header : list of str or None
        The column names (None: no header line).
    columns : list
        Arrays (formatted with ``fmt``, NaN blank) or lists of text cells.
    delimiter, decimal : str
        Cell separator and decimal mark.
    fmt : str
        printf format of the numbers.
    quote_header : bool
        Quote each header cell (phyphox, SPARKvue).

    Returns
    -------
    bytes
        UTF-8 text.
    """
    cells = [c if isinstance(c, list) else _cells(np.asarray(c), fmt, decimal) for c in columns]
    lines = []
    if header is not None:
        lines.append(delimiter.join(f'"{h}"' if quote_header else h for h in header))
    lines += [delimiter.join(row) for row in zip(*cells, strict=True)]
    return ("\n".join(lines) + "\n").encode("utf-8")


_SEPARATORS = ((",", "."), (";", ","), (";", "."), ("\t", "."), ("\t", ","))


def _layout(sig: Signals, layout: str) -> tuple[list[str], list[Any], str, dict[str, Any]]:
    """Header, columns, file name and facts of a log written as ``layout`` writes it."""
    ax, ay, az = sig.accel.T
    if layout == "pasco-capstone":
        header = ["Time (s) Run #1", "Force (N) Run #1"] + [
            f"Acceleration {a} (m/s²) Run #1" for a in "xyz"
        ]
        return header, [sig.t, sig.force, ax, ay, az], "capstone.csv", {"force": True}
    if layout == "pasco-sparkvue":
        dates = [f"01/13/2026 08:{33 + int(s) // 60:02d}:{int(s) % 60:02d} am" for s in sig.t]
        norm = np.linalg.norm(sig.accel, axis=1)
        header = ["Date and Time Run 1", "Time (s) Run 1", "Force (N) Run 1"]
        header += [f"Acceleration - {a} (m/s²) Run 1" for a in "xyz"]
        header += ["Accel (Resultant) (m/s²) Run 1"]
        cols = [dates, sig.t, sig.force, ax, ay, az, norm]
        return header, cols, "ExportedData.csv", {"force": True}
    if layout == "phyphox":
        word = "Acceleration" if sig.gravity else "Linear Acceleration"
        header = ["Time (s)"] + [f"{word} {a} (m/s^2)" for a in "xyz"]
        header += ["Absolute acceleration (m/s^2)"]
        cols = [sig.t + 0.0123, ax, ay, az, np.linalg.norm(sig.accel, axis=1)]
        return header, cols, "Raw Data.csv", {"force": False}
    if layout == "sensor-logger":
        clock = (1_760_565_906_000_000_000 + np.round(sig.t * 1e9)).astype(np.int64)
        header = ["time", "seconds_elapsed", "z", "y", "x"]
        scale = 1.0 if not sig.gravity else 1.0 / G_DEFAULT
        name = "Accelerometer.csv" if not sig.gravity else "AccelerometerUncalibrated.csv"
        cols = [[str(c) for c in clock], sig.t, az * scale, ay * scale, ax * scale]
        return header, cols, name, {"force": False}
    if layout == "vernier":
        header = ["Run 1: Time (s)", "Run 1: Force (N)"]
        header += [f"Run 1: {a.upper()}-axis acceleration (m/s²)" for a in "xyz"]
        return header, [sig.t, sig.force, ax, ay, az], "vernier.csv", {"force": True}
    header = ["t", "F", "ax", "ay", "az"]
    return header, [sig.t, sig.force, ax, ay, az], "log.csv", {"force": True}


LAYOUTS = ("pasco-capstone", "pasco-sparkvue", "phyphox", "sensor-logger", "vernier", "generic")


def _variant(cls: str, name: str, sig: Signals, layout: str, **kw: Any) -> Variant:
    header, cols, filename, facts = _layout(sig, layout)
    facts["format"] = layout
    sep, dec = kw.pop("sep", (",", "."))
    fmt = "%.9E" if layout == "phyphox" else "%.9g"
    content = render(
        header,
        cols,
        delimiter=sep,
        decimal=dec,
        fmt=fmt,
        quote_header=layout in ("phyphox", "pasco-sparkvue"),
    )
    return Variant(cls, name, filename, content, "read", sig, facts)


# ---------------------------------------------------------------- the classes


def layout_separators(rng: np.random.Generator) -> Variant:
    """A known layout written with a separator and decimal mark of a locale."""
    layout = str(rng.choice(LAYOUTS))
    gravity = layout != "sensor-logger" or bool(rng.integers(2))
    sig = signals(rng, gravity=gravity)
    sep, dec = _SEPARATORS[rng.integers(len(_SEPARATORS))]
    if layout == "sensor-logger":
        sep, dec = ",", "."  # the app writes one locale
    name = f"{layout} sep={sep!r} decimal={dec!r}"
    return _variant("layout x separator", name, sig, layout, sep=(sep, dec))


_LANGUAGES = {
    "de": ("Zeit", "Kraft", "Beschleunigung", "Lineare Beschleunigung", "Absolute Beschleunigung"),
    "es": ("Tiempo", "Fuerza", "Aceleración", "Aceleración lineal", "Aceleración absoluta"),
    "fr": ("Temps", "Force", "Accélération", "Accélération linéaire", "Accélération absolue"),
    "pl": (
        "Czas",
        "Siła",
        "Przyspieszenie",
        "Przyspieszenie liniowe",
        "Przyspieszenie bezwzględne",
    ),
    "pt": ("Tempo", "Força", "Aceleração", "Aceleração linear", "Aceleração absoluta"),
    "it": ("Tempo", "Forza", "Accelerazione", "Accelerazione lineare", "Accelerazione assoluta"),
    "nl": ("Tijd", "Kracht", "Versnelling", "Lineaire versnelling", "Absolute versnelling"),
}


def header_language(rng: np.random.Generator) -> Variant:
    """phyphox or a generic export with its header in another language."""
    lang = str(rng.choice(sorted(_LANGUAGES)))
    time, force, accel, linear, absolute = _LANGUAGES[lang]
    gravity = bool(rng.integers(2))
    sig = signals(rng, gravity=gravity)
    ax, ay, az = sig.accel.T
    if rng.integers(2):
        word = accel if gravity else linear
        header = [f"{time} (s)"] + [f"{word} {a} (m/s^2)" for a in "xyz"]
        header += [f"{absolute} (m/s^2)"]
        cols = [sig.t, ax, ay, az, np.linalg.norm(sig.accel, axis=1)]
        content = render(header, cols, fmt="%.9E", quote_header=True)
        facts = {"format": "phyphox", "force": False, "gravity": gravity}
        return Variant(
            "header language", f"phyphox {lang}", "Raw Data.csv", content, "read", sig, facts
        )
    header = [f"{time} (s)", f"{force} (N)"] + [f"{accel} {a} (m/s²)" for a in "xyz"]
    content = render(header, [sig.t, sig.force, ax, ay, az], delimiter=";", decimal=",")
    facts = {"format": "generic", "force": True, "gravity": gravity}
    return Variant("header language", f"generic {lang}", "log.csv", content, "read", sig, facts)


def accel_units(rng: np.random.Generator) -> Variant:
    """Acceleration in g, m/s^2 or mg, stated in the header or not."""
    sig = signals(rng, gravity=True)
    unit = str(rng.choice(["g", "m/s^2", "mg"]))
    stated = bool(rng.integers(2))
    factor = {"g": 1 / G_DEFAULT, "m/s^2": 1.0, "mg": 1000 / G_DEFAULT}[unit]
    names = ["AccX", "AccY", "AccZ"]
    suffix = f" ({unit})" if stated else ""
    header = ["Time (s)", "Force (N)"] + [n + suffix for n in names]
    cols = [sig.t, sig.force, *(sig.accel.T * factor)]
    content = render(header, cols)
    name = f"{unit} {'in the header' if stated else 'not stated'}"
    if unit == "mg" and not stated:
        return Variant(
            "acceleration unit",
            name,
            "log.csv",
            content,
            "refuse",
            sig,
            mention=("mg", "--columns"),
        )
    return Variant(
        "acceleration unit",
        name,
        "log.csv",
        content,
        "read",
        sig,
        {"format": "generic", "force": True},
    )


def raw_counts(rng: np.random.Generator) -> Variant:
    """An IMU's raw counts (a power of two per g): refused with the scale to give."""
    sig = signals(rng, gravity=True)
    per_g = int(rng.choice([2048, 4096, 8192, 16384]))
    counts = np.round(sig.accel / G_DEFAULT * per_g)
    header = ["millis", "accX", "accY", "accZ"]
    cols = [np.round(sig.t * 1000), *counts.T]
    content = render(header, cols)
    return Variant(
        "raw counts",
        f"{per_g} counts/g",
        "imu.csv",
        content,
        "refuse",
        sig,
        mention=("counts", "--columns"),
    )


def time_units(rng: np.random.Generator) -> Variant:
    """Time in ms, µs or ns: named, in the header, under an '(s)' header, or a clock."""
    sig = signals(rng, gravity=True, rate=float(rng.choice([50, 100, 200, 250])))
    how = str(
        rng.choice(
            [
                "ms header",
                "ms name",
                "ms under (s)",
                "us header",
                "ns clock",
                "ms counter",
                "Time sec",
            ]
        )
    )
    ax, ay, az = sig.accel.T
    if how == "ms header":
        header, t = ["Time (ms)"], np.round(sig.t * 1e3, 3)
    elif how == "ms name":
        header, t = ["time_ms"], np.round(sig.t * 1e3, 3)
    elif how == "ms under (s)":
        header, t = ["Time (s)"], np.round(sig.t * 1e3)
    elif how == "us header":
        header, t = ["t (us)"], np.round(sig.t * 1e6)
    elif how == "clock text":
        start = rng.uniform(0, 86_000)
        header = ["Time"]
        t = [
            f"{int(v // 3600) % 24:02d}:{int(v % 3600 // 60):02d}:{v % 60:06.3f}"
            for v in start + sig.t
        ]
    elif how == "ISO text":
        header = ["timestamp"]
        t = [
            f"2025-03-0{1 + int(v // 86400)}T{int(v % 86400 // 3600):02d}:"
            f"{int(v % 3600 // 60):02d}:{v % 60:06.3f}Z"
            for v in 40_000 + sig.t
        ]
    elif how == "Time sec":
        header, t = ["Time sec"], sig.t
    elif how == "ns clock":
        header, t = ["timestamp"], 1_700_000_000_000_000_000 + np.round(sig.t * 1e9)
    else:
        header, t = ["t"], 123_456 + np.round(sig.t * 1e3)
    header = [*header, "Force (N)", "ax", "ay", "az"]
    tcol: Any = [str(int(v)) for v in t] if how == "ns clock" else t
    content = render(header, [tcol, sig.force, ax, ay, az], fmt="%.10g")
    return Variant(
        "time unit", how, "log.csv", content, "read", sig, {"format": "generic", "force": True}
    )


def headerless(rng: np.random.Generator) -> Variant:
    """A file whose header line was lost: refused, saying the header is missing."""
    layout = str(rng.choice(["sensor-logger", "generic", "pasco-capstone"]))
    sig = signals(rng, gravity=True)
    _, cols, filename, _ = _layout(sig, layout)
    content = render(None, cols)
    return Variant(
        "headerless", layout, filename, content, "refuse", sig, mention=("header line is missing",)
    )


_FAMILIES = (
    "Acceleration{A}",
    "acc_{a}",
    "acc{A}",
    "a_{a}",
    "{A}-axis acceleration",
    "Accel-{A}",
    "Acceleration {a}",
    "ACC_{A}",
    "accel_{a}_ms2",
    "a{a}",
)
_EXTRAS = (
    "gyro_x",
    "gyro_y",
    "gyro_z",
    "temperature (C)",
    "mag_x",
    "pressure (hPa)",
    "Gate State",
    "humidity",
)


def renamed_reordered(rng: np.random.Generator) -> Variant:
    """A generic log with its axis family named any way, columns shuffled, extra channels."""
    sig = signals(rng, gravity=True)
    family = str(rng.choice(_FAMILIES))
    names = [family.format(a=a, A=a.upper()) for a in "xyz"]
    sep, dec = _SEPARATORS[rng.integers(len(_SEPARATORS))]
    columns = [("Time (s)", sig.t), ("Force (N)", sig.force)]
    columns += list(zip(names, sig.accel.T, strict=True))
    extras = rng.choice(len(_EXTRAS), size=int(rng.integers(0, 4)), replace=False)
    columns += [(_EXTRAS[int(k)], rng.standard_normal(sig.t.size)) for k in extras]
    order = [0, *(1 + rng.permutation(len(columns) - 1))]  # time first, the rest shuffled
    if rng.integers(2):
        order = list(rng.permutation(len(columns)))
    chosen = [columns[int(k)] for k in order]
    content = render([n for n, _ in chosen], [v for _, v in chosen], delimiter=sep, decimal=dec)
    name = f"{names[0]}.. sep={sep!r}, {len(extras)} extra, order {order}"
    return Variant(
        "renamed/reordered/extra",
        name,
        "log.csv",
        content,
        "read",
        sig,
        {"format": "generic", "force": True},
    )


def _hand_held(rng: np.random.Generator, sig: Signals) -> None:
    """Make a gravity-free acceleration hand-held: slow sway of ~0.8 m/s^2 and a bias."""
    n = sig.t.size
    width = max(3, int(sig.rate * rng.uniform(0.1, 0.5)))
    sway = np.apply_along_axis(
        lambda x: np.convolve(x, np.ones(width) / np.sqrt(width), mode="same"),
        0,
        rng.standard_normal((n, 3)),
    )
    bias = rng.normal(0.0, 1.0, 3)
    bias *= rng.uniform(0.3, 0.7) / np.linalg.norm(bias)
    sig.accel = sig.accel + 0.8 * sway + bias


def sensorlog_ios(rng: np.random.Generator) -> Variant:
    """iOS SensorLog: raw accelerometer in g beside the motion's user acceleration and gravity."""
    sig = signals(rng, gravity=True, rate=float(rng.choice([30, 50, 100])))
    n = sig.t.size
    raw = sig.accel / G_DEFAULT
    gravity_vec = np.tile(np.mean(raw[: n // 5], axis=0), (n, 1))
    columns: list[tuple[str, Any]] = [
        ("loggingTime(txt)", [f"2024-05-01 10:00:{s:06.3f}" for s in sig.t % 60]),
        ("loggingSample(N)", np.arange(n, dtype=float)),
        ("accelerometerTimestamp_sinceReboot(s)", 5000.0 + sig.t),
    ]
    columns += [(f"accelerometerAcceleration{a}(G)", raw[:, k]) for k, a in enumerate("XYZ")]
    columns += [
        (f"motionUserAcceleration{a}(G)", raw[:, k] - gravity_vec[:, k])
        for k, a in enumerate("XYZ")
    ]
    columns += [(f"motionGravity{a}(G)", gravity_vec[:, k]) for k, a in enumerate("XYZ")]
    columns += [(f"gyroRotation{a}(rad/s)", rng.standard_normal(n) * 0.01) for a in "XYZ"]
    content = render([c for c, _ in columns], [v for _, v in columns], fmt="%.9g")
    return Variant(
        "renamed/reordered/extra",
        "iOS SensorLog",
        "sensorlog.csv",
        content,
        "read",
        sig,
        {"format": "generic", "force": False},
    )


def other_apps(rng: np.random.Generator) -> Variant:
    """Other apps' exports: Physics Toolbox (g-force), Capstone in another language, metadata
    lines above the header, an Arduino sketch's millis() and g columns, iOS SensorLog."""
    which = str(
        rng.choice(
            ["physics toolbox", "capstone localized", "metadata lines", "arduino", "sensorlog"]
        )
    )
    if which == "sensorlog":
        variant = sensorlog_ios(rng)
        variant.cls = "other apps"
        return variant
    sig = signals(rng, gravity=True)
    ax, ay, az = sig.accel.T
    if which == "physics toolbox":
        g_axes = sig.accel / G_DEFAULT
        cols = [sig.t, *g_axes.T, np.linalg.norm(g_axes, axis=1)]
        content = render(["time", "gFx", "gFy", "gFz", "TgF"], cols, fmt="%.4f")
        return Variant(
            "other apps",
            which,
            "physics_toolbox.csv",
            content,
            "read",
            sig,
            {"format": "generic", "force": False, "accel_tol": 0.002 * G_DEFAULT},
        )
    if which == "capstone localized":
        run = str(rng.choice(["Lauf", "Ejecución", "Essai", "Prova", "Serie"]))
        time, force, accel = _LANGUAGES[str(rng.choice(sorted(_LANGUAGES)))][:3]
        header = [f"{time} (s) {run} #1", f"{force} (N) {run} #1"]
        header += [f"{accel} {a} (m/s²) {run} #1" for a in "xyz"]
        content = render(header, [sig.t, sig.force, ax, ay, az], delimiter=";", decimal=",")
        return Variant(
            "other apps",
            f"capstone '{run} #1'",
            "capstone.csv",
            content,
            "read",
            sig,
            {"format": "pasco-capstone", "force": True},
        )
    if which == "metadata lines":
        lines = ["Device: Phone X", f"Sample rate: {sig.rate:g} Hz", "Exported: 2026-01-13", ""]
        body = render(["Time (s)", "Force (N)", "ax", "ay", "az"], [sig.t, sig.force, ax, ay, az])
        content = ("\n".join(lines) + "\n").encode() + body
        return Variant(
            "other apps",
            which,
            "log.csv",
            content,
            "read",
            sig,
            {"format": "generic", "force": True},
        )
    g_axes = sig.accel / G_DEFAULT
    header = ["millis", "force_N", "ax_g", "ay_g", "az_g"]
    content = render(header, [np.round(sig.t * 1000), sig.force, *g_axes.T], fmt="%.6g")
    return Variant(
        "other apps",
        which,
        "arduino.csv",
        content,
        "read",
        sig,
        {"format": "generic", "force": True},
    )


def gravity_in_out(rng: np.random.Generator) -> Variant:
    """Acceleration with or without gravity, named or not, in g or m/s^2, or hand-held."""
    gravity = bool(rng.integers(2))
    sig = signals(rng, gravity=gravity)
    how = (
        str(rng.choice(["named", "unnamed", "unnamed g"]))
        if gravity
        else str(rng.choice(["named", "unnamed", "hand-held"]))
    )
    if how in ("hand-held", "walking"):
        _hand_held(rng, sig)
    if how == "walking":  # steps at ~2 Hz of ±3 m/s^2 on top of the sway, gravity in
        sig.accel[:, 2] += 3.0 * np.sin(2 * np.pi * rng.uniform(1.6, 2.2) * sig.t)
    prefix = "linear_" if how == "named" and not gravity else ""
    names = [f"{prefix}acc_{a}" for a in "xyz"]
    factor = 1 / G_DEFAULT if how == "unnamed g" else 1.0
    content = render(["time", "force", *names], [sig.t, sig.force, *(sig.accel.T * factor)])
    name = f"{'with' if gravity else 'without'} g, {how}"
    return Variant(
        "gravity in/out",
        name,
        "log.csv",
        content,
        "read",
        sig,
        {"format": "generic", "force": True, "gravity": gravity},
    )


def event_timed(rng: np.random.Generator) -> Variant:
    """A force beside a photogate's event rows: on its own time column, or under the events'."""
    sig = signals(rng, gravity=True, rate=float(rng.choice([50, 100])))
    n = sig.t.size
    k = int(rng.integers(5, 20))
    events = np.full(n, np.nan)
    events[:k] = np.sort(rng.uniform(0, sig.t[-1], k))
    state = np.full(n, np.nan)
    state[:k] = np.arange(k) % 2
    ax, ay, az = sig.accel.T
    how = int(rng.integers(3))
    if how == 2:
        header = [
            "Run 1: Gate Time (s)",
            "Run 1: Gate State",
            "Run 1: Time (s)",
            "Run 1: Force (N)",
        ]
        header += [f"Run 1: {a.upper()}-axis acceleration (m/s²)" for a in "xyz"]
        content = render(header, [events, state, sig.t, sig.force, ax, ay, az])
        return Variant(
            "event-timed channel",
            "events first, own time column",
            "v.csv",
            content,
            "read",
            sig,
            {"format": "vernier", "force": True},
        )
    if how == 1:
        header = ["Run 1: Time (s)", "Run 1: Force (N)"]
        header += [f"Run 1: {a.upper()}-axis acceleration (m/s²)" for a in "xyz"]
        header += ["Run 1: Gate Time (s)", "Run 1: Gate State"]
        content = render(header, [sig.t, sig.force, ax, ay, az, events, state])
        return Variant(
            "event-timed channel",
            "own time column",
            "v.csv",
            content,
            "read",
            sig,
            {"format": "vernier", "force": True},
        )
    header = ["Run 1: Time (s)", "Run 1: Gate State", "Run 1: Force (N)"]
    content = render(header, [events, state, sig.force])
    return Variant(
        "event-timed channel",
        "force under the events' time",
        "v.csv",
        content,
        "refuse",
        sig,
        mention=("clocks of their own",),
    )


def no_scale(rng: np.random.Generator) -> Variant:
    """Every value a power of ten too large (a spreadsheet's re-export with decimal commas)."""
    sig = signals(rng, gravity=True)
    power = int(rng.choice([6, 9]))
    header = ["Time (s)", "ax (m/s^2)", "ay (m/s^2)", "az (m/s^2)"]
    content = render(
        header, [sig.t, *(sig.accel.T * 10.0**power)], delimiter=";", decimal=",", fmt="%.2E"
    )
    word = {6: "million", 9: "billion"}[power]
    return Variant(
        "values at no scale",
        f"x1e{power}",
        "mangled.csv",
        content,
        "refuse",
        sig,
        mention=(word, "scale"),
    )


def clipping(rng: np.random.Generator) -> Variant:
    """Shocks beyond the accelerometer's range (±2, ±4, ±8 g): pinned samples noted."""
    sig = signals(rng, gravity=True)
    limit = float(rng.choice([2.0, 4.0, 8.0])) * G_DEFAULT
    n = sig.t.size
    for start in rng.choice(np.arange(10, n - 20), size=int(rng.integers(2, 5)), replace=False):
        axis = int(np.argmax(np.abs(sig.accel[start])))
        sig.accel[start : start + int(rng.integers(3, 8)), axis] = limit * np.sign(
            sig.accel[start, axis]
        )
    ax, ay, az = sig.accel.T
    content = render(["t", "F", "ax", "ay", "az"], [sig.t, sig.force, ax, ay, az])
    return Variant(
        "clipping",
        f"±{limit / G_DEFAULT:g} g",
        "log.csv",
        content,
        "read",
        sig,
        {"format": "generic", "force": True, "notes": ["read.sensor_limit"]},
    )


def repeated_pairs(rng: np.random.Generator) -> Variant:
    """A sensor exported at twice its rate: every row written twice (times advance)."""
    sig = signals(rng, gravity=True, rate=float(rng.choice([10, 20, 50])))
    rep = np.repeat(np.arange(sig.t.size), 2)
    t2 = np.arange(rep.size) / (2 * sig.rate)
    truth = Signals(t2, sig.force[rep], sig.accel[rep], True, 2 * sig.rate)
    ax, ay, az = truth.accel.T
    content = render(["t", "F", "ax", "ay", "az"], [t2, truth.force, ax, ay, az])
    return Variant(
        "repeated pairs",
        f"{sig.rate:g} Hz as {2 * sig.rate:g} Hz",
        "log.csv",
        content,
        "read",
        truth,
        {"format": "generic", "force": True, "notes_text": ["repeated 2 times"]},
    )


#: The classes of the bench's table, each a drawer of random variants.
CLASSES: dict[str, Callable[[np.random.Generator], Variant]] = {
    "layout x separator": layout_separators,
    "header language": header_language,
    "acceleration unit": accel_units,
    "raw counts": raw_counts,
    "time unit": time_units,
    "headerless": headerless,
    "renamed/reordered/extra": renamed_reordered,
    "gravity in/out": gravity_in_out,
    "event-timed channel": event_timed,
    "values at no scale": no_scale,
    "clipping": clipping,
    "repeated pairs": repeated_pairs,
    "other apps": other_apps,
}


# ---------------------------------------------------------------- judging


def _wrong(log: Any, v: Variant) -> list[str]:
    """What in the reading contradicts the variant's truth (empty: right)."""
    facts, truth = v.facts, v.truth
    wrong: list[str] = []
    if len(log.recordings) != 1:
        return [f"{len(log.recordings)} runs, expected 1"]
    (rec,) = log.recordings
    if "format" in facts and log.format != facts["format"]:
        wrong.append(f"format {log.format}, expected {facts['format']}")
    if rec.n_samples != truth.t.size:
        wrong.append(f"{rec.n_samples} samples, expected {truth.t.size}")
    if not np.isclose(rec.sample_rate_hz, truth.rate, rtol=0.01):
        wrong.append(f"rate {rec.sample_rate_hz:.4g} Hz, expected {truth.rate:g}")
    if facts.get("force"):
        if rec.force is None:
            wrong.append("no force")
        elif rec.n_samples == truth.t.size and not np.allclose(rec.force, truth.force, atol=0.01):
            wrong.append("force values wrong")
    if rec.accel is None or rec.accel.shape[1] != 3:
        wrong.append("no three-axis acceleration")
        return wrong
    if rec.accel_includes_gravity != truth.gravity:
        wrong.append(f"includes gravity {rec.accel_includes_gravity}, expected {truth.gravity}")
    if rec.n_samples == truth.t.size:
        err = float(np.max(np.abs(rec.accel - truth.accel)))
        if err > facts.get("accel_tol", 0.02 * G_DEFAULT):
            wrong.append(f"acceleration off by up to {err:.3g} m/s^2 (unit or axes misread)")
    codes = {n.code for n in log.notes}
    wrong += [f"no note {c}" for c in facts.get("notes", []) if c not in codes]
    text = " ".join(n.text for n in log.notes)
    wrong += [f"no note saying {w!r}" for w in facts.get("notes_text", []) if w not in text]
    return wrong


def judge(v: Variant, folder: Path) -> tuple[str, str]:
    """Write the variant, read it as a user would, and judge the outcome.

    Parameters
    ----------
    v : Variant
        The variant.
    folder : pathlib.Path
        Where to write it (a folder of its own: the file name may matter).

    Returns
    -------
    outcome : str
        One of :data:`OUTCOMES`.
    detail : str
        The refusal or what is wrong.
    """
    from balancer_id.errors import BalancerIdError
    from balancer_id.read import read_log

    folder.mkdir(parents=True, exist_ok=True)
    path = folder / v.filename
    path.write_bytes(v.content)
    try:
        log = read_log(path)
    except BalancerIdError as exc:
        message = str(exc)
        said = message.replace(str(path), "<file>").lower()
        if "\n" in message.strip():
            return "unhelpful", f"refusal of more than one line: {message}"
        if v.expect == "refuse":
            missing = [w for w in v.mention if w.lower() not in said]
            if missing:
                return "unhelpful", f"refusal lacks {missing}: {message}"
            return "clear", message
        return "unhelpful", f"refused: {message}"
    if v.expect == "refuse":
        return "misread", f"read ({log.format}), expected a refusal naming {v.mention}"
    wrong = _wrong(log, v)
    return ("misread", "; ".join(wrong)) if wrong else ("right", log.format)
