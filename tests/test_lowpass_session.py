"""A sensor's 1st-order low-pass on a session's acceleration is named as the sensor's,
not a late channel or a dead time (issue 31)."""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from balancer_id.diagnostics.api import diagnose
from balancer_id.diagnostics.explanations.sensor_lowpass import lowpass, lowpass_at
from balancer_id.identify.api import fit
from balancer_id.model.spec import resolve_model
from balancer_id.read.recording import Recording
from balancer_id.read.writers import write_log
from balancer_id.simulation.engine import TrialInput, simulate_many
from balancer_id.simulation.inputs import Thrust
from balancer_id.simulation.synth import keep_mask

#: after bench_universe world 4104009: a session of pushes and releases, the
#: accelerometer's own 1st-order filter at 8 Hz (its lag 20 ms), a few samples lost
TRUTH = {"m_a": 40.0, "T_a": 0.5, "D0": 160.0, "A": 0.004}
CUTOFF_HZ = 8.0


def _session_log(tmp_path) -> str:
    rate, rest, hold = 100.0, 1.5, 2.5
    levels = [120.0, 0.0, -90.0, 0.0, 150.0, 0.0]
    times = rest + hold * np.arange(len(levels))
    t = np.arange(round((times[-1] + hold) * rate) + 1) / rate
    model = resolve_model("variable_viscosity")
    drive = Thrust(times, np.array(levels))
    sim = simulate_many(model, TRUTH, [TrialInput(t, drive)], substeps=8)[0]
    alpha = math.exp(-2 * math.pi * CUTOFF_HZ / rate)
    seen = lfilter([1 - alpha], [1, -alpha], sim.accel)
    rng = np.random.default_rng(11)
    accel = np.zeros((t.size, 3))
    accel[:, 2] = seen + 9.80665
    accel += rng.normal(0.0, 0.01, accel.shape)
    force = np.asarray(sim.operating_force, dtype=float) + rng.normal(0.0, 0.3, t.size)
    keep = keep_mask(t.size, 0.01, rng)
    rec = Recording(
        name="Run #1",
        time=t[keep],
        force=force[keep],
        accel=accel[keep],
        accel_includes_gravity=True,
        accel_axes=("x", "y", "z"),
        sample_rate_hz=rate,
    )
    path = tmp_path / "lowpass_session.csv"
    write_log(path, [rec], "pasco-capstone")
    return str(path)


def test_the_filter_runs_on_the_sensor_clock_across_a_lost_sample():
    t = np.arange(200) / 100.0
    y = (t > 0.5).astype(float)
    whole = lowpass(y, 8.0, 100.0, order=1)
    keep = np.ones(t.size, bool)
    keep[[60, 61, 90]] = False
    assert np.allclose(lowpass_at(t[keep], y[keep], 8.0, 100.0, order=1), whole[keep])


def test_a_first_order_filter_on_a_session_is_named_as_the_sensor_low_pass(tmp_path):
    # a release while moving steps the viscous force at once (D follows |u|); the
    # filter smooths that jump over the first samples of the trial that continues
    # the session. Filtered trial by trial from its own first value, and as a
    # 2nd-order filter only, the low-pass lost to "acceleration channel late" and its
    # twin, the balancer's dead time.
    d = diagnose(fit(_session_log(tmp_path))).to_dict()
    assert d["verdict"] in ("sensor effect", "ambiguous")
    best = next(e for e in d["explanations"] if e["label"] == (d.get("ambiguity") or {}).get(
        "best", d["explanations"][0]["label"]))
    assert best["detail"].get("sensor") == "low-pass", best["label"]
    assert best["detail"]["order"] == 1
    assert abs(best["detail"]["cutoff_hz"] - CUTOFF_HZ) < 0.35 * CUTOFF_HZ
