"""Hostile and broken files (issue 13): refused at once with exit 3 and one line, or read
with a note; never a hang, an unbounded read, a traceback or a numpy warning.

Every file is generated small in ``tmp_path``. The tests run with warnings as errors, so
a numpy ``RuntimeWarning`` anywhere in reading or segmenting fails them.
"""

from __future__ import annotations

import os
import stat
import threading
from pathlib import Path

import numpy as np
import pytest

from balancer_id.errors import LogReadError
from balancer_id.read import read_log
from balancer_id.read import sniff as sniff_module
from balancer_id.segment import find_trials


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def _steps_csv(n: int = 4000, rate: float = 200.0) -> str:
    """A force + with-g acceleration log with two thrust steps (a valid, segmentable log)."""
    rng = np.random.default_rng(0)
    t = np.arange(n) / rate
    force = np.where((t > 4) & (t < 9), 4.9, 0.0) + np.where(t > 13, -4.9, 0.0)
    a_up = np.where((t > 4) & (t < 9), 0.3 * -np.expm1(-np.clip(t - 4, 0, None) / 0.3), 0.0)
    a_up += np.where(t > 13, -0.3 * -np.expm1(-np.clip(t - 13, 0, None) / 0.3), 0.0)
    rows = [
        f"{ti:.4f},{fi + rng.normal(0, 0.02):.4f},{0.05:.4f},{-0.03:.4f},{9.8 + ai:.4f}"
        for ti, fi, ai in zip(t, force, a_up, strict=True)
    ]
    return "time,force,ax,ay,az\n" + "\n".join(rows) + "\n"


def _one_line_exit_3(exc: pytest.ExceptionInfo[LogReadError]) -> str:
    text = str(exc.value)
    assert exc.value.exit_code == 3 and "\n" not in text
    return text


def _in_thread(fn, timeout: float = 20.0):
    """Run ``fn`` in a thread; fail (instead of hanging the suite) if it does not return."""
    out: dict[str, object] = {}

    def run() -> None:
        try:
            out["value"] = fn()
        except BaseException as exc:  # handed to the test
            out["error"] = exc

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(timeout)
    assert not worker.is_alive(), "reading blocked"
    return out


# --- special files --------------------------------------------------------------------


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)  # nobody writes to it: opening it for reading would block forever
    out = _in_thread(lambda: read_log(fifo))
    assert isinstance(out.get("error"), LogReadError)
    text = str(out["error"])
    assert "FIFO" in text and "regular file" in text and "\n" not in text


@pytest.mark.parametrize("device", ["/dev/null", "/dev/zero"])
def test_device_is_refused(device):
    if not os.path.exists(device):
        pytest.skip(f"{device} missing")
    out = _in_thread(lambda: read_log(device))
    assert isinstance(out.get("error"), LogReadError)
    assert "character device" in str(out["error"])


def test_folder_is_refused(tmp_path):
    with pytest.raises(LogReadError, match="is a folder") as exc:
        read_log(tmp_path)
    _one_line_exit_3(exc)


def test_unreadable_file_is_exit_3(tmp_path, monkeypatch):
    path = _write(tmp_path, "locked.csv", "t,F\n0,1\n0.1,2\n")

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(sniff_module.os, "open", denied)
    with pytest.raises(LogReadError, match="permission denied") as exc:
        read_log(path)
    assert "locked.csv" in _one_line_exit_3(exc)


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads any file")
def test_unreadable_file_for_real_is_exit_3(tmp_path):
    path = _write(tmp_path, "locked.csv", "t,F\n0,1\n0.1,2\n")
    path.chmod(0)
    with pytest.raises(LogReadError, match="permission denied") as exc:
        read_log(path)
    _one_line_exit_3(exc)


# --- size bounds ----------------------------------------------------------------------


def test_size_is_counted_on_bytes_read_not_on_stat(tmp_path, monkeypatch):
    """A file whose size reads as 0 (as /proc files do) is still bounded."""
    path = _write(tmp_path, "big.csv", _steps_csv(400))
    real_stat = os.stat

    def zero_size(p, *args, **kwargs):
        st = real_stat(p, *args, **kwargs)
        if Path(p) == path:
            values = list(st)
            values[stat.ST_SIZE] = 0
            return os.stat_result(values)
        return st

    monkeypatch.setattr(sniff_module.os, "stat", zero_size)
    with pytest.raises(LogReadError, match="more than") as exc:
        read_log(path, max_bytes=2000)
    _one_line_exit_3(exc)
    assert read_log(path).n_samples == 400  # within the default limit it reads


def test_streamed_file_is_bounded_while_parsing(tmp_path, monkeypatch):
    """Past the head, the parser reads from disk through the byte counter."""
    monkeypatch.setattr(sniff_module, "HEAD_BYTES", 4096)
    path = _write(tmp_path, "big.csv", _steps_csv(2000))
    sniffed = sniff_module.sniff(path)
    assert sniffed.stream
    limited = sniff_module.BoundedReader(sniff_module.open_regular(path), 10_000)
    with pytest.raises(sniff_module.FileTooLarge):
        while limited.read(4096):
            pass
    limited.close()


def test_streamed_read_equals_the_in_memory_read(tmp_path, monkeypatch):
    lines = _steps_csv(3000).splitlines()
    lines = [lines[0] + ",comment"] + [line + "," for line in lines[1:]]
    lines[-1] += "30 \xb0C"  # a cp1252 byte after the head: the stream switches encoding
    path = tmp_path / "cp1252.csv"
    path.write_bytes("\n".join(lines).encode("cp1252") + b"\n")
    whole = read_log(path)
    monkeypatch.setattr(sniff_module, "HEAD_BYTES", 2048)
    streamed = read_log(path)
    assert sniff_module.sniff(path).stream
    a, b = whole.recordings[0], streamed.recordings[0]
    assert a.n_samples == 3000
    np.testing.assert_array_equal(a.time, b.time)
    np.testing.assert_array_equal(a.force, b.force)
    np.testing.assert_array_equal(a.accel, b.accel)
    assert whole.warnings == streamed.warnings


def test_million_column_header_is_refused(tmp_path):
    header = ",".join(f"c{i}" for i in range(1_000_000))
    path = _write(tmp_path, "wide.csv", header + "\n" + ",".join("1" for _ in range(10)) + "\n")
    assert path.stat().st_size > 6_000_000
    with pytest.raises(LogReadError, match="1000000 columns, more than the 10000") as exc:
        read_log(path)
    _one_line_exit_3(exc)


def test_endless_first_line_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(sniff_module, "HEAD_MAX_BYTES", 1 << 16)
    monkeypatch.setattr(sniff_module, "HEAD_BYTES", 1 << 12)
    path = _write(tmp_path, "oneline.csv", "x" * 200_000)
    with pytest.raises(LogReadError, match="first line is longer") as exc:
        read_log(path)
    _one_line_exit_3(exc)


# --- damaged content ------------------------------------------------------------------


@pytest.mark.parametrize(
    "cut", ["0.0400,1.5,0.05,-0.03,9.", "0.0400,1.5,0.05", "0.0400,1.5,0.05,-0.03,"]
)
def test_row_cut_at_the_end_is_dropped_with_a_note(tmp_path, cut):
    rows = [f"{i * 0.005:.4f},1.5000,0.0500,-0.0300,9.8000" for i in range(8)]
    path = _write(tmp_path, "cut.csv", "time,force,ax,ay,az\n" + "\n".join(rows) + "\n" + cut)
    log = read_log(path)
    assert log.recordings[0].n_samples == 8
    assert any("no line end and looks cut" in w and "line 10" in w for w in log.warnings)


def test_whole_last_row_without_line_end_is_kept(tmp_path):
    rows = [f"{i * 0.005:.4f},1.5000,0.0500,-0.0300,9.8000" for i in range(9)]
    log = read_log(_write(tmp_path, "whole.csv", "time,force,ax,ay,az\n" + "\n".join(rows)))
    assert log.recordings[0].n_samples == 9
    assert not any("cut" in w for w in log.warnings)


@pytest.mark.parametrize("bad", ["1e300", "inf", "-inf", "-1e300"])
def test_absurd_values_are_missing_samples_with_a_note(tmp_path, bad):
    lines = _steps_csv().splitlines()
    for k in (500, 501, 2500):  # one run keeps every other sample: nothing is dropped
        cells = lines[k].split(",")
        cells[4 if k != 2500 else 1] = bad
        lines[k] = ",".join(cells)
    log = read_log(_write(tmp_path, "absurd.csv", "\n".join(lines) + "\n"))
    (rec,) = log.recordings
    assert rec.n_samples == 4000 - 3
    assert np.all(np.isfinite(rec.accel)) and np.all(np.isfinite(rec.force))
    notes = [w for w in log.warnings if "treated as missing samples" in w]
    assert len(notes) == 2 and any("column 'az': 2 value(s)" in w for w in notes)
    trials = find_trials(log)  # warnings are errors here: no RuntimeWarning on the way
    assert len(trials) == 3  # up at 4 s, back to 0 at 9 s, down at 13 s


def test_absurd_time_gives_no_absurd_gap_count(tmp_path):
    lines = _steps_csv(600).splitlines()
    lines[300] = "1e300" + lines[300][lines[300].index(",") :]
    lines[301] = "inf" + lines[301][lines[301].index(",") :]
    log = read_log(_write(tmp_path, "time.csv", "\n".join(lines) + "\n"))
    assert log.recordings[0].n_samples == 598
    text = " ".join(log.warnings)
    assert "column 'time': 2 value(s)" in text
    assert "1 gap(s) in the time column, 2 sample(s) missing" in text


def test_clock_jump_is_not_counted_as_missing_samples(tmp_path):
    rows = [f"{i * 0.005 + (5e9 if i >= 50 else 0):.4f},1.5" for i in range(100)]
    log = read_log(_write(tmp_path, "jump.csv", "time,force\n" + "\n".join(rows) + "\n"))
    (note,) = [w for w in log.warnings if "time jumps" in w]
    assert "the time jumps by up to 5e+09 s" in note and "sample(s) missing" not in note


# --- units and g ----------------------------------------------------------------------


def _rest_csv(level: float, unit: str = "m/s^2", n: int = 300) -> str:
    rng = np.random.default_rng(1)
    rows = [
        f"{i * 0.005:.3f},{0.02 * level:.5f},{-0.01 * level:.5f},{level + rng.normal(0, 0.001):.5f}"
        for i in range(n)
    ]
    return f"time,ax ({unit}),ay ({unit}),az ({unit})\n" + "\n".join(rows) + "\n"


def test_mps2_values_taken_as_g_are_refused(tmp_path):
    path = _write(tmp_path, "mps2.csv", _rest_csv(9.8))
    with pytest.raises(LogReadError, match="values are in m/s\\^2, not g") as exc:
        read_log(path, accel_unit="g")
    assert "--accel-unit m/s^2 or auto" in _one_line_exit_3(exc)


def test_mps2_values_under_a_g_header_are_kept_with_a_warning(tmp_path):
    log = read_log(_write(tmp_path, "hdr.csv", _rest_csv(9.8, unit="g")))
    rec = log.recordings[0]
    assert rec.accel is not None and np.median(rec.accel[:, 2]) == pytest.approx(9.8, abs=0.01)
    assert any("header says g but the acceleration rests at 9.80" in w for w in log.warnings)


def test_g_values_forced_to_mps2_are_refused(tmp_path):
    path = _write(tmp_path, "g.csv", _rest_csv(1.0))
    with pytest.raises(LogReadError, match="values look like g") as exc:
        read_log(path, accel_unit="m/s^2")
    _one_line_exit_3(exc)
    auto = read_log(path)  # auto converts, with a warning
    assert any("looks like g" in w for w in auto.warnings)


@pytest.mark.parametrize("g", [1.0, 0.5, 30.0])
def test_g_setting_that_contradicts_the_rest_is_refused(tmp_path, g):
    path = _write(tmp_path, "rest.csv", _rest_csv(9.8))
    with pytest.raises(LogReadError, match=f"contradicts g = {g:g}") as exc:
        read_log(path, g=g)
    _one_line_exit_3(exc)
    assert read_log(path, g=9.81).recordings[0].accel is not None


def test_cli_refuses_special_and_unreadable_files_with_exit_3(tmp_path, monkeypatch, cli):
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "pipe.csv")
        code, _, err = cli("inspect", tmp_path / "pipe.csv")
        assert code == 3 and "FIFO" in err and len(err.strip().splitlines()) == 1
    locked = _write(tmp_path, "locked.csv", _steps_csv(400))

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(sniff_module.os, "open", denied)
    code, _, err = cli("inspect", locked)
    assert code == 3 and "permission denied" in err and len(err.strip().splitlines()) == 1
