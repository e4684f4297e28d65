"""Property: what ``write_log`` writes, ``read_log`` reads back, in every layout and variant.

Recordings are synthetic (seeded ``numpy`` generators drawn by hypothesis); every layout
is tried with every delimiter/decimal pair, with and without BOM and CRLF. Values come
back within the written precision (9 significant digits; 10 for phyphox).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from balancer_id.read import Recording, read_log, write_log
from balancer_id.read.validate import find_gaps
from balancer_id.read.writers import WRITABLE

VARIANTS = [(",", "."), (";", ","), (";", "."), ("\t", "."), ("\t", ",")]
RTOL = 1e-8


def _make_run(rng: np.random.Generator, layout: str, name: str) -> Recording:
    n = int(rng.integers(3, 60))
    rate = float(rng.choice([20.0, 100.0, 200.0]))
    start = float(rng.choice([0.0, rng.uniform(0.0, 50.0)]))
    steps = np.full(n - 1, 1.0 / rate) * (1.0 + rng.uniform(-0.1, 0.1, n - 1))
    if n > 10 and rng.random() < 0.5:  # dropped wireless samples
        steps[rng.integers(0, n - 1)] *= float(rng.integers(3, 6))
    time = start + np.concatenate([[0.0], np.cumsum(steps)])
    kinds = ["both", "force", "accel"] if layout != "phyphox" else ["both", "accel"]
    kind = kinds[int(rng.integers(0, len(kinds)))]
    force = rng.normal(0.0, 10.0, n) if kind in ("both", "force") else None
    accel = None
    axes: tuple[str, ...] = ("x", "y", "z")
    with_g = True
    if kind in ("both", "accel"):
        shape = int(rng.choice([1, 3]))
        if shape == 3:
            with_g = bool(rng.random() < 0.7)
            base = np.array([0.3, -0.4, 9.8]) if with_g else np.zeros(3)
            accel = base + rng.normal(0.0, 0.1, (n, 3))
        else:
            axes, with_g = ("z",), False
            accel = rng.normal(0.0, 1.0, (n, 1))
    extra = {}
    if rng.random() < 0.5:
        key = "Gyroscope x (rad/s)" if layout in ("phyphox", "generic") else "Position (m)"
        values = rng.normal(0.0, 1.0, n)
        values[rng.random(n) < 0.1] = np.nan
        extra[key] = values
    return Recording(
        name=name,
        time=time,
        force=force,
        accel=accel,
        accel_includes_gravity=with_g,
        accel_axes=axes,
        extra=extra,
    )


def _names(layout: str, count: int) -> list[str]:
    if layout == "pasco-capstone":
        return [f"Run #{i + 1}" for i in range(count)]
    if layout == "pasco-sparkvue":
        return [f"Run {i + 1}" for i in range(count)]
    return ["Run 1"]


@settings(max_examples=120, deadline=None, derandomize=True)
@given(
    layout=st.sampled_from(WRITABLE),
    variant=st.sampled_from(VARIANTS),
    bom=st.booleans(),
    crlf=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_write_then_read_gives_the_same_samples(
    layout: str, variant: tuple[str, str], bom: bool, crlf: bool, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 4)) if layout.startswith("pasco") else 1
    runs = [_make_run(rng, layout, name) for name in _names(layout, count)]
    if layout == "generic":
        for run in runs:
            run.extra = {}  # a generic log keeps only time, force and acceleration
    delimiter, decimal = variant
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "log.csv"
        write_log(path, runs, layout, delimiter=delimiter, decimal=decimal, bom=bom, crlf=crlf)
        log = read_log(path, accel_unit="m/s^2")
    assert log.format == layout
    assert [r.name for r in log.recordings] == [r.name for r in runs]
    for wrote, read in zip(runs, log.recordings, strict=True):
        assert read.n_samples == wrote.n_samples
        np.testing.assert_allclose(read.time, wrote.time, rtol=RTOL, atol=1e-12)
        if wrote.force is None:
            assert read.force is None
        else:
            assert read.force is not None
            np.testing.assert_allclose(read.force, wrote.force, rtol=RTOL, atol=1e-12)
        if wrote.accel is None:
            assert read.accel is None
        else:
            assert read.accel is not None
            np.testing.assert_allclose(read.accel, wrote.accel, rtol=RTOL, atol=1e-12)
            assert read.accel_axes == wrote.accel_axes
            assert read.accel_includes_gravity == wrote.accel_includes_gravity
        assert set(read.extra) == set(wrote.extra)
        for key, values in wrote.extra.items():
            np.testing.assert_allclose(read.extra[key], values, rtol=RTOL, atol=1e-12)
        assert read.gaps == find_gaps(read.time)
        assert len(read.gaps) == len(find_gaps(wrote.time))
        assert read.sample_rate_hz == np.float64(1.0 / np.median(np.diff(read.time)))
