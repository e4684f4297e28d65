"""The inspect figure: a valid PNG, written whole, for logs with and without trials."""

from __future__ import annotations

import numpy as np
from test_segment_synth import make_log, make_recording, synth_run

from balancer_id.report.inspect_plot import plot_inspection
from balancer_id.segment import find_trials

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_plot_shows_runs_trials_and_gaps(tmp_path):
    first, _ = synth_run(51, [[4.9], [-2.45]], n_gaps=2)
    second, _ = synth_run(52, [[7.35]], rate=100.0, name="Run 2", has_force=False)
    log = make_log(first, second)
    trials = find_trials(make_log(first))
    path = tmp_path / "inspect.png"
    assert plot_inspection(log, trials, path) == path
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > 20_000
    assert not list(tmp_path.glob(".*part"))  # no temporary file left behind


def test_plot_without_trials_or_accel_replaces_the_old_file(tmp_path):
    rec, _ = synth_run(53, [], has_accel=False)
    single, _ = synth_run(54, [], tilt_deg=0.0)
    one_axis = make_recording(single.time, None, single.accel[:, 2:3], 200.0, name="Run 2")
    path = tmp_path / "rest.png"
    path.write_bytes(b"old")
    plot_inspection(make_log(rec, one_axis), [], path)
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > 5_000
    assert np.isfinite(single.accel).all()
