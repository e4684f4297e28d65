"""Write recordings as the logging programs do: for round-trip tests and the simulator.

Layouts (:data:`~balancer_id.read.recording.FORMATS`):

* ``pasco-capstone``: ``Time (s) Run #1``, ``Force (N) Run #1``,
  ``Acceleration x (m/s²) Run #1``, ``... y ...``, ``... z ...``; runs side by side,
  shorter runs padded with empty cells; unquoted header.
* ``pasco-sparkvue``: as Capstone with a ``Date and Time Run 1`` column first, run suffix
  ``Run 1`` (no ``#``), ``Acceleration - x (m/s²) Run 1``, quoted header.
* ``phyphox``: one run; ``Time (s)``, ``Acceleration x (m/s^2)`` (``Linear Acceleration``
  when gravity is not included); numbers like ``1.005775000E-2``; quoted header.
* ``generic``: one run; ``time,force,ax,ay,az`` (or ``a``).

PASCO and generic numbers keep 9 significant digits (``%.9g``), phyphox 10 (as phyphox).
Extra channels are written after the others under their ``extra`` key.
"""

from __future__ import annotations

import os
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

from balancer_id.errors import UsageError
from balancer_id.files import atomic_write, check_output
from balancer_id.read.recording import FORMATS, Recording

#: The layouts :func:`write_log` writes (the others in FORMATS are only read).
WRITABLE = ("pasco-capstone", "pasco-sparkvue", "phyphox", "generic")
_DELIMITERS = (",", ";", "\t")
_DECIMALS = (".", ",")
_SPARKVUE_START = datetime(2024, 1, 1, 12, 0, 0)

_Columns = list[tuple[str, np.ndarray]]


def write_log(
    path: str | os.PathLike[str],
    recordings: list[Recording],
    layout: str,
    *,
    delimiter: str = ",",
    decimal: str = ".",
    bom: bool = False,
    crlf: bool = False,
    overwrite: bool = False,
) -> Path:
    """Write recordings to a CSV file in one of the supported layouts, atomically.

    Parameters
    ----------
    path : str or path-like
        The file to write.
    recordings : list of Recording
        The runs; ``phyphox`` and ``generic`` hold exactly one.
    layout : str
        One of ``"pasco-capstone"``, ``"pasco-sparkvue"``, ``"phyphox"``, ``"generic"``.
    delimiter : {",", ";", "\\t"}
        Cell separator.
    decimal : {".", ","}
        Decimal mark; must differ from the delimiter.
    bom : bool
        Start the file with a UTF-8 byte-order mark.
    crlf : bool
        End lines with CR LF instead of LF.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    OutputExistsError
        The file exists and ``overwrite`` is False.
    UsageError
        Unknown layout, delimiter or decimal; a decimal equal to the delimiter; no
        recordings, or several for a one-run layout; channels whose lengths differ.
    """
    path = Path(path)
    _check_options(layout, delimiter, decimal, recordings)
    check_output(path, overwrite=overwrite, option="output")
    payload = render(recordings, layout, delimiter=delimiter, decimal=decimal, crlf=crlf)
    if bom:
        payload = b"\xef\xbb\xbf" + payload
    check_output(path, overwrite=overwrite, option="output")
    atomic_write(path, lambda fh: fh.write(payload))
    return path


def render(
    recordings: list[Recording],
    layout: str,
    *,
    delimiter: str = ",",
    decimal: str = ".",
    crlf: bool = False,
) -> bytes:
    """Return the CSV text of a layout as UTF-8 bytes (no BOM); see :func:`write_log`.

    Parameters
    ----------
    recordings : list of Recording
        The runs.
    layout : str
        One of the layouts.
    delimiter, decimal : str
        Cell separator and decimal mark.
    crlf : bool
        CR LF line ends.

    Returns
    -------
    bytes
        The file content.
    """
    _check_options(layout, delimiter, decimal, recordings)
    if layout == "pasco-capstone":
        columns = [c for i, rec in enumerate(recordings) for c in _capstone(rec, i + 1)]
        quote, fmt, na = False, "%.9G", ""
    elif layout == "pasco-sparkvue":
        columns = [c for i, rec in enumerate(recordings) for c in _sparkvue(rec, i + 1)]
        quote, fmt, na = True, "%.9G", ""
    elif layout == "phyphox":
        columns, quote, fmt, na = _phyphox(recordings[0]), True, "%.9E", "NaN"
    else:
        columns, quote, fmt, na = _generic(recordings[0]), False, "%.9g", ""
    eol = "\r\n" if crlf else "\n"
    names = [f'"{name}"' if quote else name for name, _ in columns]
    body = _format_rows([values for _, values in columns], fmt, delimiter, eol)
    body = body.replace("NAN", "nan").replace("nan", na)
    if layout == "phyphox":
        # phyphox writes exponents without "+" and leading zeros: E-02 -> E-2, E+00 -> E0.
        body = body.replace("E+00", "E0").replace("E+0", "E").replace("E+", "E")
        body = body.replace("E-0", "E-")
    if decimal != ".":
        body = body.replace(".", decimal)
    return (delimiter.join(names) + eol + body).encode("utf-8")


def _format_rows(columns: list[np.ndarray], fmt: str, delimiter: str, eol: str) -> str:
    """Format columns row by row (``%`` formatting, much faster than ``DataFrame.to_csv``).

    Shorter columns are padded with NaN (text columns with ``""``); NaN prints as ``nan``,
    which the caller replaces by the layout's empty cell. The decimal mark is ``.``.
    """
    n = max(len(values) for values in columns)
    cells: list[list[object]] = []
    formats: list[str] = []
    for values in columns:
        text = values.dtype == object
        pad = n - len(values)
        column = values if text else np.asarray(values, dtype=np.float64)
        cells.append(column.tolist() + ([""] if text else [float("nan")]) * pad)
        formats.append("%s" if text else fmt)
    row = delimiter.join(formats) + eol
    return "".join(map(row.__mod__, zip(*cells, strict=True)))


def _check_options(layout: str, delimiter: str, decimal: str, recordings: list[Recording]) -> None:
    if layout not in WRITABLE:
        known = "a layout that is only read" if layout in FORMATS else "unknown layout"
        raise UsageError(f"{known} {layout!r}; write one of {', '.join(WRITABLE)}")
    if delimiter not in _DELIMITERS:
        raise UsageError(f"delimiter must be one of {_DELIMITERS!r}, not {delimiter!r}")
    if decimal not in _DECIMALS or decimal == delimiter:
        raise UsageError(f"decimal must be '.' or ',' and differ from the delimiter {delimiter!r}")
    if not recordings:
        raise UsageError("nothing to write: no recordings")
    if layout in ("phyphox", "generic") and len(recordings) != 1:
        raise UsageError(f"the {layout} layout holds one run, got {len(recordings)} recordings")
    for rec in recordings:
        n = rec.time.shape[0]
        if rec.force is not None and rec.force.shape != (n,):
            raise UsageError(f"recording {rec.name!r}: force has {rec.force.shape}, time ({n},)")
        if rec.accel is not None and (
            rec.accel.ndim != 2 or rec.accel.shape != (n, len(rec.accel_axes))
        ):
            raise UsageError(
                f"recording {rec.name!r}: accel has shape {rec.accel.shape}, expected "
                f"({n}, {len(rec.accel_axes)}) for axes {rec.accel_axes}"
            )
        for key, values in rec.extra.items():
            if np.shape(values) != (n,):
                raise UsageError(f"recording {rec.name!r}: extra {key!r} length differs from time")


def _extras(rec: Recording, suffix: str) -> _Columns:
    return [(f"{key}{suffix}", np.asarray(v, dtype=np.float64)) for key, v in rec.extra.items()]


def _capstone(rec: Recording, run: int) -> _Columns:
    suffix = f" Run #{run}"
    out: _Columns = [(f"Time (s){suffix}", rec.time)]
    if rec.force is not None:
        out.append((f"Force (N){suffix}", rec.force))
    if rec.accel is not None:
        for k, axis in enumerate(rec.accel_axes):
            out.append((f"Acceleration {axis} (m/s²){suffix}", rec.accel[:, k]))
    return out + _extras(rec, suffix)


def _sparkvue(rec: Recording, run: int) -> _Columns:
    suffix = f" Run {run}"
    out: _Columns = [(f"Date and Time{suffix}", _clock(rec.time, run))]
    out.append((f"Time (s){suffix}", rec.time))
    if rec.force is not None:
        out.append((f"Force (N){suffix}", rec.force))
    if rec.accel is not None:
        for k, axis in enumerate(rec.accel_axes):
            out.append((f"Acceleration - {axis} (m/s²){suffix}", rec.accel[:, k]))
    return out + _extras(rec, suffix)


def _clock(time: np.ndarray, run: int) -> np.ndarray:
    """SPARKvue's wall-clock column, ``01/01/2024 12:00:05 pm``, one per second."""
    if time.size == 0:
        return np.array([], dtype=object)
    seconds = np.floor(time - time[0]).astype(np.int64)
    unique, inverse = np.unique(seconds, return_inverse=True)
    start = _SPARKVUE_START + timedelta(minutes=5 * (run - 1))
    text = [
        (start + timedelta(seconds=int(s))).strftime("%m/%d/%Y %I:%M:%S %p").lower() for s in unique
    ]
    return np.array(text, dtype=object)[inverse]


def _phyphox(rec: Recording) -> _Columns:
    out: _Columns = [("Time (s)", rec.time)]
    if rec.force is not None:
        out.append(("Force (N)", rec.force))
    if rec.accel is not None:
        name = "Acceleration" if rec.accel_includes_gravity else "Linear Acceleration"
        for k, axis in enumerate(rec.accel_axes):
            out.append((f"{name} {axis} (m/s^2)", rec.accel[:, k]))
    return out + _extras(rec, "")


def _generic(rec: Recording) -> _Columns:
    out: _Columns = [("time", rec.time)]
    if rec.force is not None:
        out.append(("force", rec.force))
    if rec.accel is not None:
        if rec.accel.shape[1] == 1:
            out.append(("a", rec.accel[:, 0]))
        else:
            out.extend((f"a{axis}", rec.accel[:, k]) for k, axis in enumerate(rec.accel_axes))
    return out + _extras(rec, "")
