"""Bad input: each case raises one exact error whose one-line message names the file,
the line or column, and what to do."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from balancer_id.errors import BalancerIdError, LogReadError, UsageError
from balancer_id.read import read_log

GOLDEN = Path(__file__).resolve().parent / "golden"
_NOISE = b',;\t\n\r"0123456789.-E aNn\xef\xbb\xbf\x00\xff'


def _write(tmp_path: Path, name: str, content: bytes | str) -> Path:
    path = tmp_path / name
    path.write_bytes(content.encode("utf-8") if isinstance(content, str) else content)
    return path


def _check(
    exc: BaseException, path: Path, line: int | None = None, column: str | None = None
) -> str:
    message = str(exc)
    assert "\n" not in message and "\r" not in message
    assert str(path) in message
    if line is not None:
        assert f"line {line}" in message
        assert getattr(exc, "line", None) == line
    if column is not None:
        assert f"column '{column}'" in message
    assert line is not None or column is not None
    return message


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.csv"
    with pytest.raises(LogReadError) as info:
        read_log(path)
    message = str(info.value)
    assert str(path) in message and "not found" in message and "\n" not in message


def test_folder_instead_of_file(tmp_path: Path) -> None:
    with pytest.raises(LogReadError, match="folder"):
        read_log(tmp_path)


@pytest.mark.parametrize("content", [b"", b"\n\n  \r\n", b"\xef\xbb\xbf"])
def test_empty_file(tmp_path: Path, content: bytes) -> None:
    path = _write(tmp_path, "empty.csv", content)
    with pytest.raises(LogReadError) as info:
        read_log(path)
    assert "empty" in _check(info.value, path, line=1)


@pytest.mark.parametrize(
    "content",
    [
        "Time (s),Force (N)\n",
        "Time (s),Force (N)\r\n\r\n",
        '\ufeff"Time (s)";"Force (N) Run #1"',
    ],
)
def test_header_only(tmp_path: Path, content: str) -> None:
    path = _write(tmp_path, "header.csv", content)
    with pytest.raises(LogReadError) as info:
        read_log(path)
    assert "no data rows" in _check(info.value, path, line=2)


def test_binary_file(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    data = rng.integers(0, 256, 4096, dtype=np.uint8).tobytes()
    path = _write(tmp_path, "binary.csv", data)
    with pytest.raises(LogReadError) as info:
        read_log(path)
    message = str(info.value)
    assert "not a text CSV" in message and "\n" not in message
    assert str(path) in message and info.value.line is not None


def test_nul_bytes_name_their_line(tmp_path: Path) -> None:
    path = _write(tmp_path, "nul.csv", b"Time (s),Force (N)\n0,1\n0.1,2\n0.2,\x003\n")
    with pytest.raises(LogReadError) as info:
        read_log(path)
    assert "not a text CSV" in _check(info.value, path, line=4)


def test_undecodable_bytes(tmp_path: Path) -> None:
    path = _write(tmp_path, "bad.csv", b"Time (s),Force (N)\n0,1\n\x81\x02\x03,2\n")
    with pytest.raises(LogReadError) as info:
        read_log(path)
    _check(info.value, path, line=3)


def test_cp1252_export_is_read(tmp_path: Path) -> None:
    text = "Time (s) Run #1,Acceleration z (m/s²) Run #1\n0,9.8\n0.005,9.7\n0.01,9.8\n"
    path = _write(tmp_path, "cp1252.csv", text.encode("cp1252"))
    log = read_log(path)
    assert log.format == "pasco-capstone" and log.recordings[0].n_samples == 3


def test_non_numeric_cell_names_line_and_column(tmp_path: Path) -> None:
    path = _write(tmp_path, "text.csv", "Time (s),Force (N)\n0,1\n0.1,2\n0.2,abc\n0.3,4\n")
    with pytest.raises(LogReadError) as info:
        read_log(path)
    assert "'abc'" in _check(info.value, path, line=4, column="Force (N)")


def test_non_numeric_decimal_comma_file(tmp_path: Path) -> None:
    content = "Time (s) Auto;Force (N) Run #1\n0;1,5\n0,05;1,6\n0,1;1.6.7\n"
    path = _write(tmp_path, "comma.csv", content)
    with pytest.raises(LogReadError) as info:
        read_log(path)
    _check(info.value, path, line=4, column="Force (N) Run #1")


def test_non_numeric_time_cell(tmp_path: Path) -> None:
    content = "Time (s),Force (N)\n0,1\n0.1,2\nnoon,3\n0.3,4\n0.4,5\n"
    path = _write(tmp_path, "time.csv", content)
    with pytest.raises(LogReadError) as info:
        read_log(path)
    _check(info.value, path, line=4, column="Time (s)")


def test_non_numeric_extra_column_is_dropped_with_warning(tmp_path: Path) -> None:
    content = "Time (s) Run #1,Force (N) Run #1,Position (m) Run #1\n0,1,a\n0.1,2,0\n0.2,3,0\n"
    log = read_log(_write(tmp_path, "extra.csv", content))
    assert log.recordings[0].extra == {}
    assert any("Position (m) Run #1" in w and "line 2" in w for w in log.warnings)


def test_time_going_backwards(tmp_path: Path) -> None:
    path = _write(tmp_path, "back.csv", "Time (s),Force (N)\n0,1\n0.1,2\n0.2,3\n0.15,4\n")
    with pytest.raises(LogReadError) as info:
        read_log(path)
    assert "backwards" in _check(info.value, path, line=5, column="Time (s)")


def test_time_backwards_in_second_ragged_run(tmp_path: Path) -> None:
    content = (
        "Time (s) Run #1,Force (N) Run #1,Time (s) Run #2,Force (N) Run #2\n"
        "0,1,0,5\n0.1,2,0.1,6\n0.2,3,0.05,7\n0.3,4,,\n"
    )
    path = _write(tmp_path, "back2.csv", content)
    with pytest.raises(LogReadError) as info:
        read_log(path)
    _check(info.value, path, line=4, column="Time (s) Run #2")


def test_duplicate_timestamps(tmp_path: Path) -> None:
    content = "Time (s),Force (N)\n0,1\n0.005,2\n0.01,3\n0.01,4\n0.015,5\n"
    path = _write(tmp_path, "dup.csv", content)
    with pytest.raises(LogReadError) as info:
        read_log(path)
    assert "duplicate" in _check(info.value, path, line=5, column="Time (s)")


def test_no_force_and_no_acceleration(tmp_path: Path) -> None:
    content = "Time (s) Run #1,Position (m) Run #1\n0,1\n0.1,2\n"
    path = _write(tmp_path, "pos.csv", content)
    with pytest.raises(LogReadError) as info:
        read_log(path)
    message = _check(info.value, path, line=1)
    assert "no force or acceleration" in message
    assert "'Time (s) Run #1'" in message and "'Position (m) Run #1'" in message


def test_unknown_header_tells_to_pass_columns(tmp_path: Path) -> None:
    path = _write(tmp_path, "odd.csv", "u,v,w\n0,1,2\n1,2,3\n")
    with pytest.raises(LogReadError) as info:
        read_log(path)
    message = _check(info.value, path, line=1)
    assert "--columns time=" in message and "'u', 'v', 'w'" in message


def test_column_map_names_a_missing_column(tmp_path: Path) -> None:
    path = _write(tmp_path, "map.csv", "t,F,acc\n0,1,2\n1,2,3\n")
    with pytest.raises(LogReadError) as info:
        read_log(path, columns={"time": "t", "force": "Force"})
    message = _check(info.value, path, line=1, column="Force")
    assert "'t', 'F', 'acc'" in message


@pytest.mark.parametrize(
    "mapping",
    [
        {"time": "t", "speed": "F"},
        {"force": "F"},
        {"time": "t"},
        {"time": "t", "a": "F", "ax": "F"},
    ],
)
def test_bad_column_map_is_a_usage_error(tmp_path: Path, mapping: dict[str, str]) -> None:
    path = _write(tmp_path, "map.csv", "t,F\n0,1\n1,2\n")
    with pytest.raises(UsageError):
        read_log(path, columns=mapping)


def test_bad_accel_unit_is_a_usage_error(tmp_path: Path) -> None:
    path = _write(tmp_path, "ok.csv", "t,F\n0,1\n1,2\n")
    with pytest.raises(UsageError):
        read_log(path, accel_unit="furlong")


def test_file_too_large(tmp_path: Path) -> None:
    path = _write(tmp_path, "big.csv", "Time (s),Force (N)\n" + "0,1\n" * 100)
    with pytest.raises(LogReadError) as info:
        read_log(path, max_bytes=100)
    message = _check(info.value, path, line=1)
    assert "split the file" in message and "more than" in message


def test_unclosed_quote(tmp_path: Path) -> None:
    path = _write(tmp_path, "quote.csv", 'Time (s),Force (N)\n0,1\n0.1,2\n"0.2,1\n0.3,4\n')
    with pytest.raises(LogReadError) as info:
        read_log(path)
    _check(info.value, path, line=4)


def test_all_blank_data(tmp_path: Path) -> None:
    path = _write(tmp_path, "blank.csv", "Time (s) Run #1,Force (N) Run #1\n,\n,\n")
    with pytest.raises(LogReadError) as info:
        read_log(path)
    assert "no usable data" in _check(info.value, path, line=2)


def test_time_column_missing(tmp_path: Path) -> None:
    path = _write(tmp_path, "notime.csv", "Force (N),Acceleration z (m/s^2)\n1,2\n3,4\n")
    with pytest.raises(LogReadError) as info:
        read_log(path)
    assert "no time column" in _check(info.value, path, line=1)


@settings(max_examples=150, deadline=None, derandomize=True)
@given(
    golden=st.sampled_from(sorted(p.name for p in GOLDEN.glob("*.csv"))),
    edits=st.lists(
        st.tuples(st.integers(0, 2), st.integers(0, 10_000), st.integers(0, len(_NOISE) - 1)),
        min_size=1,
        max_size=8,
    ),
)
def test_damaged_files_never_give_a_traceback(
    golden: str, edits: list[tuple[int, int, int]]
) -> None:
    """Bytes deleted, inserted or replaced anywhere: a Log or a one-line BalancerIdError."""
    data = bytearray((GOLDEN / golden).read_bytes())
    for op, where, char in edits:
        pos = where % max(1, len(data))
        if op == 0 and data:
            del data[pos]
        elif op == 1:
            data.insert(pos, _NOISE[char])
        elif data:
            data[pos] = _NOISE[char]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / golden
        path.write_bytes(bytes(data))
        try:
            log = read_log(path)
        except BalancerIdError as exc:
            assert "\n" not in str(exc) and str(path) in str(exc)
        else:
            assert log.recordings and all(r.n_samples >= 2 for r in log.recordings)


def test_json_error_names_the_file(cli, tmp_path: Path) -> None:
    """The ``--json`` error object carries the log's path in ``file`` (CONTRACT, Errors)."""
    import json

    path = _write(tmp_path, "back.csv", "Time (s),Force (N)\n0,1\n0.1,2\n0.2,3\n0.15,4\n")
    code, out, err = cli("inspect", path, "--json")
    assert code == 3 and "time goes backwards" in err
    error = json.loads(out)["error"]
    assert error["file"] == str(path)
    assert (error["line"], error["column"]) == (5, "Time (s)")
