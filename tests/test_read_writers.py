"""Writers: the layouts look like the real exports; files are written atomically."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from balancer_id.errors import OutputExistsError, UsageError
from balancer_id.read import Recording, read_log, write_log


def _recording(name: str = "Run 1", n: int = 4, offset: float = 0.0) -> Recording:
    t = offset + np.arange(n) * 0.005
    force = np.linspace(-7.1e-15, 2.45, n)
    accel = np.column_stack([np.full(n, 0.01005775), np.zeros(n), np.full(n, 9.8)])
    return Recording(name=name, time=t, force=force, accel=accel)


def test_capstone_layout_header_and_padding(tmp_path: Path) -> None:
    path = write_log(
        tmp_path / "c.csv",
        [_recording(n=3), _recording(n=2)],
        "pasco-capstone",
        delimiter=";",
        decimal=",",
        bom=True,
        crlf=True,
    )
    data = path.read_bytes()
    assert data.startswith(
        b"\xef\xbb\xbfTime (s) Run #1;Force (N) Run #1;Acceleration x (m/s\xc2\xb2)"
    )
    lines = data.decode("utf-8-sig").split("\r\n")
    assert lines[0].split(";")[5:7] == ["Time (s) Run #2", "Force (N) Run #2"]
    assert lines[1].split(";")[:2] == ["0", "-7,1E-15"]
    assert lines[3].endswith(";;;;;")  # the shorter run is padded with empty cells
    assert lines[-1] == ""


def test_sparkvue_layout(tmp_path: Path) -> None:
    path = write_log(tmp_path / "s.csv", [_recording()], "pasco-sparkvue")
    header, first = path.read_text(encoding="utf-8").splitlines()[:2]
    assert header.startswith('"Date and Time Run 1","Time (s) Run 1","Force (N) Run 1"')
    assert '"Acceleration - x (m/s²) Run 1"' in header
    assert first.startswith("01/01/2024 12:00:00 pm,0,")


def test_phyphox_number_style(tmp_path: Path) -> None:
    rec = _recording()
    rec.accel_includes_gravity = False
    path = write_log(tmp_path / "p.csv", [rec], "phyphox", delimiter="\t")
    header, first = path.read_text(encoding="utf-8").splitlines()[:2]
    assert header.split("\t")[:3] == [
        '"Time (s)"',
        '"Force (N)"',
        '"Linear Acceleration x (m/s^2)"',
    ]
    assert first.split("\t")[0] == "0.000000000E0"
    assert first.split("\t")[2] == "1.005775000E-2"
    assert first.split("\t")[4] == "9.800000000E0"


def test_generic_layout(tmp_path: Path) -> None:
    path = write_log(tmp_path / "g.csv", [_recording()], "generic")
    assert path.read_text(encoding="utf-8").splitlines()[0] == "time,force,ax,ay,az"


def test_refuses_to_overwrite(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    path.write_text("keep me", encoding="utf-8")
    with pytest.raises(OutputExistsError) as info:
        write_log(path, [_recording()], "generic")
    assert str(path) in str(info.value) and "overwrite" in str(info.value)
    assert path.read_text(encoding="utf-8") == "keep me"
    write_log(path, [_recording()], "generic", overwrite=True)
    assert read_log(path).recordings[0].n_samples == 4
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]  # no temp file left


@pytest.mark.parametrize(
    ("layout", "kwargs", "count"),
    [
        ("excel", {}, 1),
        ("generic", {"delimiter": "|"}, 1),
        ("generic", {"delimiter": ",", "decimal": ","}, 1),
        ("phyphox", {}, 2),
        ("generic", {}, 0),
    ],
)
def test_bad_options(tmp_path: Path, layout: str, kwargs: dict[str, str], count: int) -> None:
    with pytest.raises(UsageError):
        write_log(tmp_path / "x.csv", [_recording()] * count, layout, **kwargs)
    assert not (tmp_path / "x.csv").exists()


def test_mismatched_lengths(tmp_path: Path) -> None:
    rec = _recording()
    rec.force = rec.force[:2]
    with pytest.raises(UsageError):
        write_log(tmp_path / "x.csv", [rec], "pasco-capstone")


def test_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(UsageError):
        write_log(tmp_path / "no" / "x.csv", [_recording()], "generic")
