"""Open a log and find how it is written: size, encoding, BOM, delimiter, decimal mark, header.

Nothing here knows about PASCO or phyphox; the result, :class:`Sniffed`, holds the
file's bytes (re-encoded as UTF-8 without BOM) and the header cells, ready for
:mod:`balancer_id.read.table` to parse the numbers.
"""

from __future__ import annotations

import csv
import os
import re
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
        The whole file as UTF-8, without BOM.
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
    """

    path: Path
    data: bytes
    encoding: str
    delimiter: str
    decimal: str
    header: list[str]
    data_start: int
    header_line: int = 1

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


def _load(path: Path, max_bytes: int | None) -> bytes:
    """Check the file exists, is not empty and not too large, and return its bytes."""
    if not path.exists():
        raise LogReadError(path, "file not found", hint="check the path and the file name")
    if path.is_dir():
        raise LogReadError(path, "is a folder, not a log file", hint="give the path of a CSV file")
    size = path.stat().st_size
    limit = default_max_bytes() if max_bytes is None else int(max_bytes)
    if size > limit:
        raise LogReadError(
            path,
            f"file is {_human(size)}, more than the {_human(limit)} this machine can read safely",
            line=1,
            hint="split the file into smaller files (e.g. one run per file) or raise max_bytes",
        )
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise LogReadError(path, f"cannot be opened: {exc.strerror or exc}", line=1) from None
    if not data.strip(b" \t\r\n\x00\xef\xbb\xbf\xff\xfe"):
        raise LogReadError(
            path, "file is empty", line=1, hint="export the data again from the logging app"
        )
    return data


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
    """Read a log file and find its encoding, delimiter, decimal mark and header.

    Parameters
    ----------
    path : str or path-like
        The file.
    max_bytes : int, optional
        Refuse files larger than this (bytes); default :func:`default_max_bytes`.

    Returns
    -------
    Sniffed
        The file's bytes and layout facts.

    Raises
    ------
    LogReadError
        Missing, empty, too large, binary or undecodable file, or a header with no data.
    """
    path = Path(path)
    data, encoding = _decode(path, _load(path, max_bytes))
    # The header is the first line that is not blank.
    start = 0
    while True:
        end = data.find(b"\n", start)
        line_end = len(data) if end < 0 else end
        header_line = data[start:line_end].decode("utf-8").strip("\r\n")
        if header_line.strip() or end < 0:
            break
        start = end + 1
    data_start = len(data) if end < 0 else end + 1
    if not header_line.strip():
        raise LogReadError(path, "file is empty", line=1, hint="export the data again")
    header_lineno = _line_of(data, start)
    sample: list[str] = []
    pos = data_start
    while len(sample) < _SAMPLE_LINES and pos < len(data):
        nxt = data.find(b"\n", pos)
        nxt = len(data) if nxt < 0 else nxt
        text = data[pos:nxt].decode("utf-8").strip("\r")
        if text.strip():
            sample.append(text)
        pos = nxt + 1
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
    return Sniffed(path, data, encoding, delimiter, decimal, header, data_start, header_lineno)
