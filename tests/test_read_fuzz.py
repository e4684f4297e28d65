"""Fuzzing the readers (issue 13): every generated file reads or fails with LogReadError.

Files are built from the pieces real exports are made of (PASCO, phyphox and generic
headers, numbers in both decimal marks, blanks, NaN, absurd values, quotes, BOMs, CR/LF)
and then damaged (bytes flipped, cut anywhere, binary and undecodable bytes, ragged rows).
Whatever comes out, ``read_log`` returns a log or raises :class:`LogReadError` (exit 3)
with a one-line message naming the file; never another exception, never a warning (the
suite turns warnings into errors), and ``inspect`` exits 0, 3 or 4 with one line.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from balancer_id.errors import LogReadError
from balancer_id.read import read_log

HEADERS = [
    "Time (s)",
    "Time (s) Run #1",
    "Time (s) Auto",
    "Time (ms)",
    "time",
    "t",
    "Date and Time Run 1",
    "Force (N) Run #1",
    "Force (N)",
    "force",
    "Acceleration x (m/s²) Run #1",
    "Acceleration y (m/s²) Run #1",
    "Acceleration z (m/s²) Run #1",
    "Acceleration x (g)",
    "Linear Acceleration z (m/s^2)",
    "Absolute acceleration (m/s^2)",
    "ax",
    "ay",
    "az",
    "a",
    "Position (m) Run 1",
    "Gyroscope x (rad/s)",
    "comment",
    "",
]
CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-20, 20).map(lambda x: f"{x:.4f}"),
    st.floats(-20, 20).map(lambda x: f"{x:.3f}".replace(".", ",")),
    st.sampled_from(["", "NaN", "nan", "1e300", "-1e300", "inf", "1.2E", "--1", "#VALUE!"]),
    st.sampled_from(["abc", '"1,5"', '"', "0x1F", "1.2.3", " ", "\t", "01/02/2024 10:00:00 am"]),
    st.text(max_size=6),
)
DELIMITERS = st.sampled_from([",", ";", "\t", " "])
EOLS = st.sampled_from(["\n", "\r\n", "\r"])


@st.composite
def csv_bytes(draw: st.DrawFn) -> bytes:
    """A CSV-like file, plausible or damaged."""
    delim, eol = draw(DELIMITERS), draw(EOLS)
    header = draw(st.lists(st.sampled_from(HEADERS), min_size=1, max_size=7))
    quote = draw(st.booleans())
    head = delim.join(f'"{h}"' if quote else h for h in header)
    n_rows = draw(st.integers(0, 40))
    steady = draw(st.booleans())  # a clean numeric table, so that parsing goes deep
    rows = []
    for i in range(n_rows):
        if steady:
            cells = [f"{i * 0.01:.3f}"] + [f"{9.8 * (k == 3) + 0.01 * i:.3f}" for k in header[1:]]
        else:
            width = draw(st.integers(0, len(header) + 2))
            cells = [draw(CELLS) for _ in range(width)]
        rows.append(delim.join(cells))
    text = eol.join([head, *rows]) + draw(st.sampled_from(["", eol, eol + eol]))
    encoding = draw(st.sampled_from(["utf-8", "utf-8-sig", "utf-16", "cp1252", "latin-1"]))
    data = text.encode(encoding, errors="replace")
    damage = draw(st.sampled_from(["none", "cut", "flip", "nul", "binary"]))
    if damage == "cut" and data:
        data = data[: draw(st.integers(0, len(data)))]
    elif damage == "flip" and data:
        k = draw(st.integers(0, len(data) - 1))
        data = data[:k] + bytes([data[k] ^ draw(st.integers(1, 255))]) + data[k + 1 :]
    elif damage == "nul":
        k = draw(st.integers(0, len(data)))
        data = data[:k] + b"\x00" + data[k:]
    elif damage == "binary":
        data += draw(st.binary(min_size=1, max_size=64))
    return data


def _check(data: bytes, folder: Path) -> None:
    path = folder / "fuzz.csv"
    path.write_bytes(data)
    try:
        log = read_log(path)
    except LogReadError as exc:
        text = str(exc)
        assert exc.exit_code == 3
        assert "\n" not in text and "\r" not in text
        assert text.startswith(str(path))
        return
    assert log.recordings
    for rec in log.recordings:
        assert rec.n_samples >= 2 and np.all(np.diff(rec.time) > 0)
        for channel in (rec.force, rec.accel):
            assert channel is None or np.all(np.isfinite(channel))


@settings(
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(csv_bytes())
def test_every_generated_file_reads_or_is_one_clean_error(data):
    with tempfile.TemporaryDirectory() as folder:
        _check(data, Path(folder))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=400))
def test_random_bytes_read_or_are_one_clean_error(data):
    with tempfile.TemporaryDirectory() as folder:
        _check(data, Path(folder))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(csv_bytes())
def test_inspect_exits_with_a_contract_code_and_one_line(data):
    from typer.testing import CliRunner

    from balancer_id.cli import app

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.csv"
        path.write_bytes(data)
        res = CliRunner().invoke(app, ["inspect", str(path), "--json"])
    assert res.exit_code in (0, 3, 4), res.output
    if res.exit_code:
        lines = [line for line in res.stderr.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith("balancer-id: error:")
