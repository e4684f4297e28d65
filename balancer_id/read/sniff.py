"""Open a log and find how it is written: size, encoding, BOM, delimiter, decimal mark, header.

Nothing here knows about PASCO or phyphox; the result, :class:`Sniffed`, holds the
head of the file (re-encoded as UTF-8 without BOM) and the header cells, ready for
:mod:`balancer_id.read.table` to parse the numbers.

Safety: only regular files are opened (a FIFO, a device, a socket or a folder is refused
from ``os.stat`` before any ``open``, and the file is opened with ``O_NONBLOCK`` and
checked again with ``fstat``); every read counts the bytes actually read against the
size limit (a file whose size reads as 0 is not trusted); UTF-8 and cp1252 files are
streamed to the parser from disk, never held whole in memory; a header of more than
:data:`MAX_COLUMNS` columns is refused at once.
"""

from __future__ import annotations

import csv
import io
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path

from balancer_id.errors import LogReadError

#: Fallback size limit (bytes) when the available memory cannot be read.
DEFAULT_MAX_BYTES = 2 * 1024**3

_DELIMITERS = (",", ";", "\t")
_CONTROL = re.compile(rb"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")
_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+(?:[eE][+-]?\d+)?$")
_DECIMAL_POINT = re.compile(r"^[+-]?(?:\d+\.\d*|\.\d+)(?:[eE][+-]?\d+)?$")
_SAMPLE_LINES = 50
#: Bytes read first to sniff the layout; more (up to HEAD_MAX_BYTES) when the lines are long.
HEAD_BYTES = 1 << 20
HEAD_MAX_BYTES = 16 << 20
#: A header with more columns than this is refused (no export has as many).
MAX_COLUMNS = 10_000
_TAIL_BYTES = 1 << 16
_CHUNK = 1 << 20
_BOMS = (
    (b"\xef\xbb\xbf", "utf-8-sig"),
    (b"\xff\xfe", "utf-16-le"),
    (b"\xfe\xff", "utf-16-be"),
)


@dataclass(frozen=True)
class Sniffed:
    """How a log file is written.

    Attributes
    ----------
    path : pathlib.Path
        The file.
    data : bytes
        The file as UTF-8, without BOM: the whole file, or (``stream`` True) its head,
        cut after its last complete line.
    encoding : str
        The encoding the file was written in (``"utf-8"``, ``"utf-8-sig"``, ``"cp1252"``, ...).
    delimiter : str
        ``","``, ``";"``, ``"\\t"`` or ``" "`` (runs of blanks).
    decimal : str
        ``"."`` or ``","``.
    header : list of str
        The cells of the first line.
    data_start : int
        Offset in ``data`` of the first data line (after the header line).
    header_line : int
        Line number (1-based) of the header in the file; data row ``i`` is on line
        ``header_line + 1 + i``.
    stream : bool
        True when the parser reads the rows from the file itself (from ``raw_offset``,
        decoding with ``read_encoding``) rather than from ``data``.
    raw_offset : int
        Byte offset in the file of the first data line (used when ``stream``).
    read_encoding : str
        The encoding the parser decodes the streamed rows with.
    limit : int
        Most bytes that may be read from the file.
    cut_last : str
        The last line of the file when it has no line end and looks cut (fewer cells
        than the line before, or a shorter last number); the parser drops it.
    notes : tuple of str
        What was done to the text before parsing (quotes around whole rows removed).
    """

    path: Path
    data: bytes
    encoding: str
    delimiter: str
    decimal: str
    header: list[str]
    data_start: int
    header_line: int = 1
    stream: bool = False
    raw_offset: int = 0
    read_encoding: str = "utf-8"
    limit: int = DEFAULT_MAX_BYTES
    cut_last: str = ""
    notes: tuple[str, ...] = ()

    @property
    def has_bom(self) -> bool:
        """True when the file began with a byte-order mark."""
        return self.encoding in ("utf-8-sig", "utf-16-le", "utf-16-be")


def default_max_bytes() -> int:
    """Return the default size limit: a quarter of the available memory, at most 2 GiB.

    Returns
    -------
    int
        The limit in bytes.
    """
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    available = int(line.split()[1]) * 1024
                    return max(1, min(DEFAULT_MAX_BYTES, available // 4))
    except (OSError, ValueError, IndexError):
        pass
    return DEFAULT_MAX_BYTES


def _human(n_bytes: int) -> str:
    size = float(n_bytes)
    for unit in ("bytes", "kB", "MB", "GB"):
        if size < 1000 or unit == "GB":
            return f"{size:.0f} {unit}" if unit == "bytes" else f"{size:.1f} {unit}"
        size /= 1000
    return f"{size:.1f} TB"  # pragma: no cover


def _line_of(data: bytes, offset: int) -> int:
    return data.count(b"\n", 0, offset) + 1


_KINDS = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


class FileTooLarge(Exception):
    """More bytes were read from a file than its limit allows."""


def _kind_error(path: Path, mode: int) -> LogReadError | None:
    if stat.S_ISDIR(mode):
        return LogReadError(path, "is a folder, not a log file", hint="give the path of a CSV file")
    if stat.S_ISREG(mode):
        return None
    kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    return LogReadError(
        path,
        f"is {kind}, not a regular file; only regular files are read",
        hint="save the data to a CSV file and give its path",
    )


def _os_error(path: Path, exc: OSError) -> LogReadError:
    if isinstance(exc, FileNotFoundError):
        return LogReadError(path, "file not found", hint="check the path and the file name")
    if isinstance(exc, PermissionError):
        return LogReadError(
            path, "permission denied", hint="make the file readable (chmod u+r) or copy it"
        )
    return LogReadError(path, f"cannot be opened: {exc.strerror or exc}")


def open_regular(path: str | os.PathLike[str], limit: int | None = None) -> int:
    """Open a regular file for reading without ever blocking, and return its descriptor.

    ``os.stat`` decides first (a FIFO, a device, a socket or a folder is refused before
    any ``open``); the file is then opened with ``O_NONBLOCK`` and checked again with
    ``fstat`` (the path may have been replaced in between).

    Parameters
    ----------
    path : str or path-like
        The file.
    limit : int, optional
        Refuse a file whose size (as ``stat`` says) is above this many bytes.

    Returns
    -------
    int
        An open file descriptor (the caller closes it).

    Raises
    ------
    LogReadError
        Missing, not a regular file, unreadable (permission), or too large.
    """
    path = Path(path)
    try:
        info = os.stat(path)
    except OSError as exc:
        raise _os_error(path, exc) from None
    error = _kind_error(path, info.st_mode)
    if error is not None:
        raise error
    if limit is not None and info.st_size > limit:
        raise _too_large(path, info.st_size, limit)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise _os_error(path, exc) from None
    error = _kind_error(path, os.fstat(fd).st_mode)
    if error is not None:
        os.close(fd)
        raise error
    return fd


def _too_large(path: Path, size: int, limit: int) -> LogReadError:
    return LogReadError(
        path,
        f"file is {_human(size)}, more than the {_human(limit)} this machine can read safely",
        line=1,
        hint="split the file into smaller files (e.g. one run per file) or raise max_bytes",
    )


class BoundedReader(io.RawIOBase):
    """A read-only raw stream over a descriptor that stops at ``limit`` bytes read.

    Parameters
    ----------
    fd : int
        An open descriptor (closed with the reader).
    limit : int
        Most bytes that may be read; reading more raises :class:`FileTooLarge`.
    offset : int
        Where to start reading.
    """

    def __init__(self, fd: int, limit: int, offset: int = 0) -> None:
        super().__init__()
        self._fd = fd
        self._left = limit - offset
        os.lseek(fd, offset, os.SEEK_SET)

    def readable(self) -> bool:
        """Return True (the stream reads).

        Returns
        -------
        bool
        """
        return True

    def readinto(self, buffer: bytearray | memoryview) -> int:  # type: ignore[override]
        """Read into ``buffer``; raise :class:`FileTooLarge` past the limit.

        Parameters
        ----------
        buffer : bytearray or memoryview
            Where the bytes go.

        Returns
        -------
        int
            Bytes read (0 at the end of the file).
        """
        view = memoryview(buffer).cast("B")
        want = min(len(view), self._left + 1)
        if want <= 0:
            raise FileTooLarge
        got = os.readv(self._fd, [view[:want]])
        self._left -= got
        if self._left < 0:
            raise FileTooLarge
        return got

    def close(self) -> None:
        """Close the descriptor."""
        if not self.closed:
            os.close(self._fd)
        super().close()


def _read_up_to(path: Path, fd: int, n: int, limit: int) -> tuple[bytes, bool]:
    """Read at most ``n`` bytes from ``fd``; True when the end of the file was reached."""
    parts: list[bytes] = []
    total = 0
    while total < n:
        chunk = os.read(fd, min(_CHUNK, n - total))
        if not chunk:
            return b"".join(parts), True
        parts.append(chunk)
        total += len(chunk)
        if total > limit:
            raise _too_large(path, total, limit)
    return b"".join(parts), False


def _tail(fd: int, end: int) -> bytes:
    """The last bytes of the file before offset ``end`` (at most ``_TAIL_BYTES``)."""
    start = max(0, end - _TAIL_BYTES)
    return os.pread(fd, end - start, start)


def _load(path: Path, max_bytes: int | None) -> tuple[bytes, bool, int, bytes]:
    """Read the head of a regular file within the size limit.

    Returns the head (the whole file when ``complete``), whether it is complete, the
    limit, and the file's last bytes.
    """
    limit = default_max_bytes() if max_bytes is None else int(max_bytes)
    fd = open_regular(path, limit)
    try:
        data, complete = _read_up_to(path, fd, HEAD_BYTES, limit)
        while not complete and data.count(b"\n") <= _SAMPLE_LINES and len(data) < HEAD_MAX_BYTES:
            more, complete = _read_up_to(path, fd, len(data), limit - len(data))
            data += more
        tail = data[-_TAIL_BYTES:] if complete else _tail(fd, os.fstat(fd).st_size)
    except OSError as exc:
        raise _os_error(path, exc) from None
    finally:
        os.close(fd)
    if complete and not data.strip(b" \t\r\n\x00\xef\xbb\xbf\xff\xfe"):
        raise LogReadError(
            path, "file is empty", line=1, hint="export the data again from the logging app"
        )
    return data, complete, limit, tail


def _decode(path: Path, data: bytes) -> tuple[bytes, str]:
    """Return the file as UTF-8 bytes without BOM, and the encoding it was in."""
    for bom, encoding in _BOMS:
        if data.startswith(bom):
            if encoding == "utf-8-sig":
                data = data[len(bom) :]
                break
            try:
                text = data[len(bom) :].decode(encoding)
            except UnicodeDecodeError as exc:
                raise _not_text(path, data, exc.start) from None
            return text.encode("utf-8"), encoding
    else:
        encoding = "utf-8"
    if b"\n" not in data and b"\r" in data:  # classic Mac line ends (CR only)
        data = data.replace(b"\r", b"\n")
    nul = data.find(b"\x00")
    if nul >= 0:
        raise _not_text(path, data, nul)
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        control = _CONTROL.search(data)
        if control is not None:
            raise _not_text(path, data, control.start()) from None
        try:  # a Windows export without UTF-8 (e.g. "m/s²" written as one cp1252 byte)
            return data.decode("cp1252").encode("utf-8"), "cp1252"
        except UnicodeDecodeError:
            raise _not_text(path, data, exc.start) from None
    return data, encoding


def _not_text(path: Path, data: bytes, offset: int) -> LogReadError:
    return LogReadError(
        path,
        f"is not a text CSV file (binary or undecodable bytes at byte {offset})",
        line=_line_of(data, offset),
        hint="export the data as CSV text from Capstone, SPARKvue or phyphox",
    )


def _fields(line: str, delimiter: str) -> list[str]:
    if delimiter == " ":
        return line.split()
    try:
        return next(csv.reader([line.replace("\r", " ")], delimiter=delimiter), [])
    except csv.Error:
        return line.split(delimiter)


def _choose_delimiter(header: str, sample: list[str]) -> str:
    best, best_count = ",", 1
    for delimiter in _DELIMITERS:
        count = len(_fields(header, delimiter))
        if count > best_count:
            best, best_count = delimiter, count
        elif count == best_count and count == 1 and sample:
            # A single-column header: let the data decide.
            data_count = len(_fields(sample[0], delimiter))
            if data_count > len(_fields(sample[0], best)):
                best = delimiter
    if best_count == 1 and len(header.split()) > 1 and all(c not in header for c in ",;\t"):
        lengths = {len(line.split()) for line in sample}
        if lengths == {len(header.split())}:
            return " "
    return best


def _choose_decimal(delimiter: str, sample: list[str]) -> str:
    # Cells are split as csv does, so with a "," delimiter only quoted "0,05" counts.
    comma = point = 0
    for line in sample:
        for cell in _fields(line, delimiter):
            cell = cell.strip()
            if _DECIMAL_COMMA.match(cell):
                comma += 1
            elif _DECIMAL_POINT.match(cell):
                point += 1
    return "," if comma > point else "."


def sniff(path: str | os.PathLike[str], max_bytes: int | None = None) -> Sniffed:
    """Read the head of a log file and find its encoding, delimiter, decimal mark and header.

    Parameters
    ----------
    path : str or path-like
        The file.
    max_bytes : int, optional
        Refuse files larger than this (bytes, counted as they are read); default
        :func:`default_max_bytes`.

    Returns
    -------
    Sniffed
        The file's head (or whole content) and layout facts.

    Raises
    ------
    LogReadError
        Missing, not a regular file, unreadable, empty, too large, binary or undecodable
        file, a header of more than :data:`MAX_COLUMNS` columns, or a header with no data.
    """
    path = Path(path)
    head, complete, limit, tail = _load(path, max_bytes)
    if not complete and (
        head.startswith(tuple(bom for bom, enc in _BOMS if enc.startswith("utf-16")))
        or (b"\n" not in head and b"\r" in head)
    ):  # UTF-16 or CR-only line ends: decoded whole, in memory (bounded by the limit)
        head, complete = _read_whole(path, limit)
    if not complete:  # decode whole lines only: a character may be cut at the end
        cut = head.rfind(b"\n")
        head = head[: cut + 1] if cut >= 0 else head
    _refuse_zip(path, head)
    data, encoding = _decode(path, head)
    notes: tuple[str, ...] = ()
    if _rows_quoted_whole(data):
        if not complete:
            head, complete = _read_whole(path, limit)
            data, encoding = _decode(path, head)
        data = _unquote_rows(data)
        tail = data[-_TAIL_BYTES:]
        notes = (
            "every line of the file is one quoted field (re-saved by a spreadsheet); "
            "the quotes around each line were removed",
        )
    # The header is the first line that is not blank (after metadata lines, if any).
    start, skipped = _after_preamble(data)
    header_line, start, end = _header_line(path, data, start, complete)
    data_start = len(data) if end < 0 else end + 1
    if not header_line.strip():
        raise LogReadError(path, "file is empty", line=1, hint="export the data again")
    header_lineno = _line_of(data, start)
    _refuse_wide(path, header_line, header_lineno)
    sample = _sample_lines(data, data_start)
    if not sample:
        raise LogReadError(
            path,
            "has a header but no data rows",
            line=header_lineno + 1,
            hint="export the data again with the measurements included",
        )
    delimiter = _choose_delimiter(header_line, sample)
    decimal = _choose_decimal(delimiter, sample)
    header = [cell.replace("\ufeff", "").strip() for cell in _fields(header_line, delimiter)]
    named = _names_above_units(skipped, header, delimiter)
    if named is not None:  # the names' row, then a row of units: "time,force" / "s,N"
        notes = (
            *notes,
            f"the header's units were read from the row under it ({', '.join(header[:5])})",
        )
        header, skipped = named, skipped[:-1]
    if skipped:
        notes = (
            *notes,
            f"{len(skipped)} line(s) before the header skipped as metadata "
            f"({'; '.join(repr(x[:40]) for x in skipped[:3])})",
        )
    stream = not complete
    raw_offset = 0
    if stream:
        newlines = data.count(b"\n", 0, data_start)
        raw_offset = _after_newlines(head, newlines)
    cut_last = "" if encoding.startswith("utf-16") else _cut_last_line(tail, delimiter)
    return Sniffed(
        path,
        data,
        encoding,
        delimiter,
        decimal,
        header,
        data_start,
        header_lineno,
        stream=stream,
        raw_offset=raw_offset,
        read_encoding="cp1252" if encoding == "cp1252" else "utf-8",
        limit=limit,
        cut_last=cut_last,
        notes=notes,
    )


def _refuse_zip(path: Path, head: bytes) -> None:
    """A zip archive (phyphox's zip export, an .xlsx) is not a CSV file."""
    if head.startswith(b"PK\x03\x04"):
        raise LogReadError(
            path,
            "is a zip archive, not a CSV file (phyphox's export as a zip, or an Excel .xlsx)",
            line=1,
            hint="unzip it and give the CSV inside (phyphox: 'Raw Data.csv'), "
            "or save the sheet as CSV",
        )


def _refuse_wide(path: Path, header_line: str, header_lineno: int) -> None:
    """A header of more than :data:`MAX_COLUMNS` columns is no log's."""
    widest = max(header_line.count(d) for d in (*_DELIMITERS, " ")) + 1
    if widest > MAX_COLUMNS:
        raise LogReadError(
            path,
            f"the header has {widest} columns, more than the {MAX_COLUMNS} a log may have",
            line=header_lineno,
            hint="export only the time, force and acceleration columns",
        )


def _read_whole(path: Path, limit: int) -> tuple[bytes, bool]:
    """The whole file, up to ``limit`` bytes (and whether it was all read)."""
    fd = open_regular(path, limit)
    try:
        return _read_up_to(path, fd, limit + 1, limit)
    except OSError as exc:
        raise _os_error(path, exc) from None
    finally:
        os.close(fd)


def _header_line(path: Path, data: bytes, start: int, complete: bool) -> tuple[str, int, int]:
    """The first line from ``start`` that is not blank: its text, its start and its end
    (-1: the data end on it)."""
    while True:
        end = data.find(b"\n", start)
        line_end = len(data) if end < 0 else end
        if line_end - start > HEAD_MAX_BYTES // 2 or (end < 0 and not complete):
            raise LogReadError(
                path,
                "the first line is longer than any log header",
                line=_line_of(data, start),
                hint="check that this is a CSV export with one header line",
            )
        header_line = data[start:line_end].decode("utf-8").strip("\r\n")
        if header_line.strip() or end < 0:
            return header_line, start, end
        start = end + 1


def _sample_lines(data: bytes, data_start: int) -> list[str]:
    """The first :data:`_SAMPLE_LINES` data lines that are not blank."""
    sample: list[str] = []
    pos = data_start
    while len(sample) < _SAMPLE_LINES and pos < len(data):
        nxt = data.find(b"\n", pos)
        nxt = len(data) if nxt < 0 else nxt
        text = data[pos:nxt].decode("utf-8").strip("\r")
        if text.strip():
            sample.append(text)
        pos = nxt + 1
    return sample


_CELL_NUMBER = re.compile(r"^[+-]?(?:\d+[.,]?\d*|[.,]\d+)(?:[eE][+-]?\d+)?$")
#: Lines looked at for metadata above the header.
_PREAMBLE_LINES = 40


_MISSING = frozenset({"nan", "-nan", "na", "n/a", "null", "none", "-", "inf", "-inf"})


def _numeric_row(cells: list[str]) -> bool:
    filled = [c.strip().strip('"') for c in cells if c.strip().strip('"')]
    filled = [c for c in filled if c.lower() not in _MISSING]
    return len(cells) >= 2 and (
        sum(bool(_CELL_NUMBER.match(c)) for c in filled) > 0.5 * len(filled) or not filled
    )


#: Units a row under the header may hold (lower case, brackets removed).
_UNIT_CELLS = frozenset(
    {
        "s", "sec", "ms", "us", "µs", "μs", "ns", "min", "n", "kn", "mn", "lbf", "kgf",
        "g", "mg", "m/s^2", "m/s²", "m/s2", "m s^-2", "m/s", "m", "mm", "cm", "deg", "°",
        "rad", "rad/s", "deg/s", "°/s", "%", "v", "mv", "hz", "-", "1", "°c", "k",
    }
)  # fmt: skip


def _unit_text(cell: str) -> str:
    """A units row's cell without quotes or brackets: ``"[m/s^2]"`` -> ``m/s^2``."""
    return cell.strip().strip('"').strip().strip("[]()").strip()


def _unit_cell(cell: str) -> bool:
    """Whether a cell is a unit as a units row writes it (``s``, ``[N]``, ``(m/s^2)``)."""
    return _unit_text(cell).lower() in _UNIT_CELLS


def _names_above_units(skipped: list[str], units: list[str], delimiter: str) -> list[str] | None:
    """The header ``name (unit)`` when the line taken as the header is a row of units and
    the last line skipped above it holds the names, cell for cell; else None."""
    if not skipped or len(units) < 2 or not all(_unit_cell(u) for u in units if u.strip()):
        return None
    if sum(bool(u.strip()) for u in units) < 2:
        return None
    names = [c.replace("\ufeff", "").strip().strip('"') for c in _fields(skipped[-1], delimiter)]
    if len(names) != len(units) or not all(names) or _numeric_row(names):
        return None
    return [
        f"{n} ({_unit_text(u)})" if u.strip() else n
        for n, u in zip(names, units, strict=True)
    ]


def _after_preamble(data: bytes) -> tuple[int, list[str]]:
    """Offset of the header line, past metadata lines above it, and the lines skipped.

    The header is the first line that is not a numeric row and has as many cells as the
    numeric rows that follow it (an app's "Device: ...", "Rate: 100 Hz" lines above the
    table are skipped). When no line fits, the first non-blank line is the header.
    """
    text = data[: 1 << 16].decode("utf-8", "replace")
    lines = text.split("\n")[:_PREAMBLE_LINES]
    offsets, pos = [], 0
    for line in lines:
        offsets.append(pos)
        pos += len(line.encode("utf-8")) + 1
    kept = [(k, ln.strip("\r")) for k, ln in enumerate(lines) if ln.strip()]
    for j in range(len(kept) - 2):
        k, line = kept[j]
        if any(_numeric_row(_fields(line, d)) for d in _DELIMITERS):
            return 0, []  # the data begin: no header after them
        for delimiter in _DELIMITERS:
            cells = _fields(line, delimiter)
            if len(cells) < 2:
                continue
            rows = [_fields(kept[j + m][1], delimiter) for m in (1, 2)]
            if all(len(r) == len(cells) and _numeric_row(r) for r in rows):
                if j == 0:
                    return 0, []
                return offsets[k], [ln for _, ln in kept[:j]]
    return 0, []


def _rows_quoted_whole(data: bytes) -> bool:
    """True when the first lines are each one quoted field holding delimiters.

    A spreadsheet that took each line of a CSV as one text cell writes it back quoted
    whole: ``"Time (s),""Linear Acceleration x (m/s^2)"",..."`` then ``"0.097,0.017,..."``.
    """
    lines = [ln for ln in data[:65536].decode("utf-8", "replace").splitlines() if ln.strip()]
    lines = lines[:6] if len(lines) > 6 else lines[:-1] or lines
    if len(lines) < 2:
        return False
    for line in lines:
        cells = _fields(line.strip(), ",")
        text = line.strip()
        if not (text.startswith('"') and text.endswith('"')) or len(cells) != 1:
            return False
        if not any(d in cells[0] for d in _DELIMITERS):
            return False
    return True


def _unquote_rows(data: bytes) -> bytes:
    """Each line's single quoted field, unquoted (``""`` back to ``"``)."""
    out = []
    for line in data.decode("utf-8").splitlines():
        cells = _fields(line.strip(), ",") if line.strip() else [""]
        out.append(cells[0] if len(cells) == 1 else line)
    return ("\n".join(out) + "\n").encode("utf-8")


def _after_newlines(raw: bytes, n: int) -> int:
    """Offset just after the ``n``-th newline of ``raw`` (0 for ``n`` = 0)."""
    pos = 0
    for _ in range(n):
        pos = raw.index(b"\n", pos) + 1
    return pos


_NUMBER = re.compile(r"^[+-]?(\d+)?(?:[.,](\d*))?(?:[eE][+-]?\d+)?$")


def _cut_last_line(tail: bytes, delimiter: str) -> str:
    """The file's last line when it has no line end and looks cut, else ``""``.

    Cut: fewer cells than the line before, or a last cell that is not a whole number
    where the line before has one, has no exponent where the line before has one, or has
    fewer decimals.
    """
    if not tail.strip() or tail.endswith((b"\n", b"\r")):
        return ""
    lines = tail.decode("utf-8", errors="replace").replace("\r", "\n").split("\n")
    last = lines[-1]
    prev = next((line for line in reversed(lines[:-1]) if line.strip()), None)
    if prev is None or not last.strip():
        return ""
    cells, before = _fields(last, delimiter), _fields(prev, delimiter)
    if len(cells) < len(before):
        return last
    a, b = cells[-1].strip().strip('"'), before[-1].strip().strip('"')
    m_a, m_b = _NUMBER.match(a), _NUMBER.match(b)
    if m_b is None or not b:
        return ""
    if m_a is None or not a:
        return last
    if ("e" in b.lower()) != ("e" in a.lower()):
        return last
    if len(m_a.group(2) or "") < len(m_b.group(2) or ""):
        return last
    return ""
