"""Parse the numeric columns of a sniffed log with pandas' C engine.

The fast path reads the wanted columns straight to float64. Only when that fails (a
non-numeric cell) the columns are read again as text to find the first bad cell, so
the error can name its line and column. Empty cells and ``NaN`` become NaN.
"""

from __future__ import annotations

import io
import os
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from balancer_id.errors import LogReadError
from balancer_id.read.sniff import BoundedReader, FileTooLarge, Sniffed, open_regular
from balancer_id.status import tell

if TYPE_CHECKING:
    import pandas as pd

#: Missing-value spellings on top of pandas' defaults (``""``, ``NaN``, ``nan``, ``NA``, ...).
_NA_EXTRA = ["NAN", "-NAN", "Nan", "nan(ind)", "-nan(ind)", "#NV", "#WERT!", "#VALUE!"]
_LINE_IN_MESSAGE = re.compile(r"\b(line|row) (\d+)")
#: Values beyond this magnitude are not measurements (and would overflow squares).
DEFAULT_BOUND = 1e12


@dataclass
class Table:
    """Numeric columns of a log, by header index.

    Attributes
    ----------
    columns : dict
        Header index -> float64 array (NaN for empty cells); every array has ``n_rows``.
    n_rows : int
        Number of data rows (blank lines included, so row ``i`` is file line
        ``first_line + i``).
    first_line : int
        File line number of row 0.
    dropped : dict
        Header index -> (line, cell) of the first non-numeric cell, for columns that were
        allowed to fail (extra channels) and were left out.
    notes : list of str
        What was done to the numbers (a cut last line dropped, values beyond the column's
        bound or infinite treated as missing).
    beyond : dict
        Header index -> the column as read, for columns with values beyond their bound
        (the reader names values at no physical scale from them).
    """

    columns: dict[int, np.ndarray]
    n_rows: int
    first_line: int
    dropped: dict[int, tuple[int, str]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    beyond: dict[int, np.ndarray] = field(default_factory=dict)

    def line_of(self, row: int | np.integer) -> int:
        """Return the file line number of data row ``row``.

        Parameters
        ----------
        row : int
            Index of a row of the table (0 for the first data row).

        Returns
        -------
        int
            ``first_line + row``: the line of the file the row was read from, as error
            messages number it.
        """
        return self.first_line + int(row)


#: Rows per chunk when a big file is parsed from disk.
CHUNK_ROWS = 1 << 18


def _read(
    sniffed: Sniffed, usecols: list[int], dtype: object, encoding: str
) -> pd.DataFrame | dict[int, np.ndarray]:
    """Parse; float64 columns come back as a dict (a streamed file read in chunks)."""
    import pandas as pd  # lazy: importing balancer_id.read stays cheap

    kwargs: dict[str, object] = {
        "header": None,
        "names": list(range(len(sniffed.header))),
        "usecols": usecols,
        "dtype": dtype,
        "decimal": sniffed.decimal,
        "skip_blank_lines": False,
        "engine": "c",
        "encoding": encoding,
        "quotechar": '"',
        "na_values": _NA_EXTRA,
    }
    if sniffed.delimiter == " ":
        kwargs["sep"] = r"\s+"
    else:
        kwargs["sep"] = sniffed.delimiter
    if not sniffed.stream:
        buffer = io.BytesIO(sniffed.data)
        buffer.seek(sniffed.data_start)
        frame = pd.read_csv(buffer, **kwargs)
        if dtype is str:
            return frame
        return {c: frame[c].to_numpy(dtype=np.float64) for c in usecols}
    # streamed from disk: never the whole file in memory; the limit counts bytes read
    raw = BoundedReader(open_regular(sniffed.path), sniffed.limit, sniffed.raw_offset)
    with io.BufferedReader(raw, buffer_size=1 << 20) as stream:
        if dtype is str:
            return pd.read_csv(stream, **kwargs)
        # chunk by chunk into columns allocated once for the rows the file size promises
        # (grown if it promised too few): the peak is the numbers once plus one chunk
        expected = _expected_rows(sniffed)
        size = max(16, int(expected * 1.03) + 16)
        columns = {c: np.empty(size) for c in usecols}
        n = 0
        with pd.read_csv(stream, chunksize=CHUNK_ROWS, **kwargs) as chunks:
            for chunk in chunks:
                if expected > CHUNK_ROWS:  # a long log: say how far the reading is
                    tell(f"reading rows: {min(n / expected, 0.99):.0%} of ~{expected:,}")
                k = len(chunk)
                if n + k > size:
                    size = max(n + k, size + size // 4)
                    for c in usecols:
                        columns[c] = _grown(columns[c], size)
                for c in usecols:
                    columns[c][n : n + k] = chunk[c].to_numpy(dtype=np.float64)
                n += k
                del chunk
    for c in usecols:
        columns[c] = _grown(columns[c], n)
    return columns


def _expected_rows(sniffed: Sniffed) -> int:
    """Rows the file holds if its lines are as long as those of its head."""
    head = sniffed.data[sniffed.data_start :]
    lines = max(1, head.count(b"\n"))
    per_line = max(1.0, len(head) / lines)
    try:
        size = os.stat(sniffed.path).st_size
    except OSError:
        return lines
    return int((size - sniffed.raw_offset) / per_line) + 1


def _grown(values: np.ndarray, size: int) -> np.ndarray:
    """``values`` resized to ``size`` in place when it can be, else as a copy."""
    try:
        values.resize(size, refcheck=False)
    except ValueError:
        values = np.resize(values, size)
    return values


def _read_any(
    sniffed: Sniffed, usecols: list[int], dtype: object
) -> pd.DataFrame | dict[int, np.ndarray]:
    """Read; a streamed UTF-8 file with other bytes further on is read again as cp1252."""
    encoding = sniffed.read_encoding if sniffed.stream else "utf-8"
    try:
        return _read(sniffed, usecols, dtype, encoding)
    except UnicodeDecodeError:
        if not sniffed.stream or encoding != "utf-8":
            raise
        return _read(sniffed, usecols, dtype, "cp1252")


def read_table(
    sniffed: Sniffed,
    wanted: list[int],
    optional: set[int] | None = None,
    limits: dict[int, float] | None = None,
    clocks: set[int] | None = None,
) -> Table:
    """Parse the columns ``wanted`` as float64.

    A last line that :func:`~balancer_id.read.sniff.sniff` found cut is dropped, and
    values that are infinite or beyond their column's bound (``limits``, default
    :data:`DEFAULT_BOUND`) become NaN (missing samples); both are said in ``notes``.

    Parameters
    ----------
    sniffed : Sniffed
        The sniffed file.
    wanted : list of int
        Header indexes to parse.
    optional : set of int, optional
        Columns that may be dropped (reported in ``Table.dropped``) instead of failing
        when they hold text.
    limits : dict, optional
        Header index -> largest plausible magnitude of that column's values.
    clocks : set of int, optional
        Time columns: written as clock text (``10:15:42.125``, ``2024-05-01
        10:15:42``) they are read as seconds (of the day, or since 1970), and said.

    Returns
    -------
    Table
        The parsed columns.

    Raises
    ------
    LogReadError
        A non-numeric cell in a required column (names its line and column), or a
        malformed file.
    """
    optional = optional or set()
    usecols = sorted(set(wanted))
    first_line = sniffed.header_line + 1
    try:
        columns = _read_any(sniffed, usecols, np.float64)
    except ValueError as exc:  # a cell that is not a number (or a malformed row): slow path
        if isinstance(exc, UnicodeDecodeError):
            raise _parser_error(sniffed, exc, first_line) from None
        table = _read_slow(sniffed, usecols, optional, first_line, clocks or set())
    except Exception as exc:  # never a traceback: pandas' other errors become LogReadError
        raise _parser_error(sniffed, exc, first_line) from None
    else:
        if not isinstance(columns, dict):  # pragma: no cover - numbers come back as a dict
            raise TypeError("numeric columns expected")
        table = Table(columns, len(columns[usecols[0]]) if usecols else 0, first_line)
    return _finish(sniffed, table, limits or {})


def _finish(sniffed: Sniffed, table: Table, limits: dict[int, float]) -> Table:
    """Drop a cut last line; values infinite or beyond their column's bound become NaN."""
    if sniffed.cut_last and table.n_rows:
        line = table.line_of(table.n_rows - 1)
        table.columns = {c: v[:-1] for c, v in table.columns.items()}
        table.n_rows -= 1
        table.notes.append(
            f"line {line}, the last, has no line end and looks cut "
            f"({sniffed.cut_last.strip()[:40]!r}); dropped"
        )
    for col, values in list(table.columns.items()):
        bound = limits.get(col, DEFAULT_BOUND)
        with np.errstate(invalid="ignore"):
            bad = np.abs(values) > bound  # NaN compares False; inf is beyond any bound
        n_bad = int(np.count_nonzero(bad))
        if n_bad:
            table.beyond[col] = values.copy()  # as read: the size of values at no scale
            first = int(np.argmax(bad))
            table.notes.append(
                f"column '{sniffed.header[col]}': {n_bad} value(s) infinite or beyond "
                f"±{bound:g} (first {values[first]:g} on line {table.line_of(first)}) "
                "treated as missing samples"
            )
            values = values.copy()  # pandas' arrays may be read-only
            values[bad] = np.nan
            table.columns[col] = values
    return table


def _read_slow(
    sniffed: Sniffed,
    usecols: list[int],
    optional: set[int],
    first_line: int,
    clocks: set[int] | None = None,
) -> Table:
    """Read as text, convert column by column, and name the first bad cell."""
    import pandas as pd

    try:
        frame = _read_any(sniffed, usecols, str)
    except Exception as exc:  # ParserError, UnicodeDecodeError, MemoryError, ...
        raise _parser_error(sniffed, exc, first_line) from None
    if isinstance(frame, dict):  # pragma: no cover - text is always read as a frame
        raise TypeError("text columns expected")
    columns: dict[int, np.ndarray] = {}
    dropped: dict[int, tuple[int, str]] = {}
    clock_notes: list[str] = []
    bad_required: tuple[int, int, str] | None = None
    for col in usecols:
        text = frame[col]
        present = text.notna().to_numpy()
        clean = text.str.strip()
        if sniffed.decimal == ",":
            clean = clean.str.replace(",", ".", regex=False)
        values = pd.to_numeric(clean, errors="coerce").to_numpy(dtype=np.float64)
        blank = (clean == "").to_numpy(dtype=bool, na_value=True) | clean.str.lower().isin(
            ("nan", "-nan", "+nan")
        ).to_numpy(dtype=bool)
        bad = np.flatnonzero(present & ~blank & np.isnan(values))
        if bad.size and col in (clocks or set()):
            parsed = clock_seconds(clean)
            if parsed is not None:
                values, said = parsed
                bad = bad[:0]
                clock_notes.append(f"time column '{sniffed.header[col]}' read from {said}")
        if bad.size:
            row = int(bad[0])
            where = (first_line + row, str(text.iloc[row]))
            if col in optional:
                dropped[col] = where
                continue
            if bad_required is None or row < bad_required[0]:
                bad_required = (row, col, where[1])
        columns[col] = values
    if bad_required is not None:
        row, col, cell = bad_required
        raise LogReadError(
            sniffed.path,
            f"non-numeric value {cell.strip()[:40]!r} in a numeric column",
            line=first_line + row,
            column=sniffed.header[col],
            hint="fix or delete that cell, or export the data again with numbers only",
        )
    return Table(columns, len(frame), first_line, dropped, clock_notes)


_TIME_OF_DAY = r"^(\d{1,2}):(\d{2}):(\d{2})(?:[.,:](\d{1,9}))?$"
#: Share of a time column's cells that must parse as clock text.
CLOCK_SHARE = 0.9


def clock_seconds(cells: pd.Series) -> tuple[np.ndarray, str] | None:
    """A time column written as clock text, in seconds; None when it is not clock text.

    ``10:15:42.125`` (or ``10:15:42:125``, Physics Toolbox) is seconds of the day (a
    midnight passed adds a day); a date and time (``2024-05-01 10:15:42.125``, ISO) is
    seconds since 1970.

    Parameters
    ----------
    cells : pandas.Series
        The column's cells as text (stripped).

    Returns
    -------
    tuple or None
        The seconds (NaN for blank cells) and what they were read from.
    """
    import pandas as pd

    filled = cells.notna() & (cells != "")
    n = int(filled.sum())
    if n == 0:
        return None
    parts = cells.str.extract(_TIME_OF_DAY)
    hms = parts[0].notna()
    if int(hms.sum()) >= CLOCK_SHARE * n:
        h, m, sec = (parts[k].astype(float).to_numpy() for k in range(3))
        frac = parts[3].fillna("0")
        digits = frac.str.len().to_numpy(dtype=float)
        fraction = frac.astype(float).to_numpy() / 10.0**digits
        seconds = h * 3600 + m * 60 + sec + fraction
        back = np.flatnonzero(np.diff(seconds) < -43_200)
        for i in back:  # past midnight
            seconds[i + 1 :] += 86_400.0
        return seconds, "clock text (hh:mm:ss, seconds of the day)"
    with np.errstate(all="ignore"):
        try:
            stamps = pd.to_datetime(cells.where(filled), errors="coerce", format="mixed")
        except (ValueError, TypeError):
            return None
    ok = stamps.notna()
    if int(ok.sum()) < CLOCK_SHARE * n:
        return None
    if getattr(stamps.dt, "tz", None) is not None:
        stamps = stamps.dt.tz_convert("UTC").dt.tz_localize(None)
    seconds = (stamps - pd.Timestamp("1970-01-01")).dt.total_seconds().to_numpy(dtype=float)
    return seconds, "date-and-time text (seconds since 1970, UTC unless it says its zone)"


def _parser_error(sniffed: Sniffed, exc: BaseException, first_line: int) -> LogReadError:
    if isinstance(exc, FileTooLarge):
        return LogReadError(
            sniffed.path,
            f"more than {sniffed.limit} bytes read, more than this machine can read safely",
            hint="split the file into smaller files (e.g. one run per file) or raise max_bytes",
        )
    message = " ".join(str(exc).split()) or type(exc).__name__
    found = _LINE_IN_MESSAGE.search(message)
    # pandas counts "line N" from 1 and "row N" from 0 over the data it was given.
    line = None
    if found:
        line = first_line + int(found.group(2)) - (1 if found.group(1) == "line" else 0)
    if isinstance(exc, MemoryError):
        return LogReadError(
            sniffed.path,
            "not enough memory to read the file",
            line=line or first_line,
            hint="split the file into smaller files",
        )
    if isinstance(exc, UnicodeDecodeError):
        return LogReadError(
            sniffed.path,
            "contains bytes that are not text",
            line=line or first_line,
            hint="export the data as CSV text again",
        )
    return LogReadError(
        sniffed.path,
        f"cannot be parsed as CSV ({message[:160]})",
        line=line or first_line,
        hint="check that every row has the same delimiter as the header",
    )
