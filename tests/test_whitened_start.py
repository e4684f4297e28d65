"""Every sample counts in the arena's criterion, a trial's first two too (issue 31): a
trial that continues a session starts on its thrust step, where a late channel shows."""

from __future__ import annotations

import numpy as np
from scipy.linalg import toeplitz

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.api import diagnose
from balancer_id.identify.api import fit
from balancer_id.model.spec import resolve_model
from balancer_id.read.recording import Recording
from balancer_id.read.writers import write_log
from balancer_id.simulation.engine import TrialInput, simulate_many
from balancer_id.simulation.inputs import Thrust

#: bench_universe world 4101010: up-then-down at 100 Hz, the force channel 14 ms late
TRUTH = {"m_a": 5.266, "T_a": 0.8028, "D0": 9.207, "A": 0.2752}


def _ar2_acf(p1: float, p2: float, n: int) -> np.ndarray:
    """Autocovariance of a unit-innovation AR(2), lags 0..n-1."""
    g0 = (1 - p2) / ((1 + p2) * ((1 - p2) ** 2 - p1**2))
    g = [g0, p1 * g0 / (1 - p2)]
    while len(g) < n:
        g.append(p1 * g[-1] + p2 * g[-2])
    return np.array(g[:n])


def test_the_whitened_sum_is_the_exact_quadratic_form_of_ar2_noise():
    rng = np.random.default_rng(3)
    parts = [rng.normal(size=40), rng.normal(size=25)]
    # white noise: every sample, as it is
    rss, n = arena.whitened_rss(parts, (0.0, 0.0))
    assert n == 65 and np.isclose(rss, sum(float(p @ p) for p in parts))
    # AR(2): r' C^-1 r over each trial, the first two samples included
    p1, p2 = 0.9, -0.3
    rss, n = arena.whitened_rss(parts, (p1, p2))
    exact = sum(
        float(p @ np.linalg.solve(toeplitz(_ar2_acf(p1, p2, p.size)), p)) for p in parts
    )
    assert n == 65 and np.isclose(rss, exact, rtol=1e-9)


def _updown_log(tmp_path, delay: float) -> str:
    rate, rest, hold, u = 100.0, 1.18, 5.48, 5.01
    times = [rest, rest + hold / 2, rest + hold]
    t = np.arange(round((rest + 2 * hold) * rate) + 1) / rate
    drive = Thrust(np.array(times), np.array([u, -u, 0.0]))
    model = resolve_model("variable_viscosity")
    sim = simulate_many(model, TRUTH, [TrialInput(t, drive)], substeps=8)[0]
    rng = np.random.default_rng(7)
    accel = np.zeros((t.size, 3))
    accel[:, 2] = sim.accel + 9.80665
    accel += rng.normal(0.0, 0.0136, accel.shape)
    force = np.asarray(sim.operating_force, dtype=float)
    force = np.interp(t - delay, t, force, left=force[0]) + rng.normal(0.0, 0.016, t.size)
    rec = Recording(
        name="Run #1",
        time=t,
        force=force,
        accel=accel,
        accel_includes_gravity=True,
        accel_axes=("x", "y", "z"),
        sample_rate_hz=rate,
    )
    path = tmp_path / f"updown_{delay * 1e3:.0f}ms.csv"
    write_log(path, [rec], "pasco-capstone")
    return str(path)


def test_a_late_force_on_an_up_then_down_move_is_named_from_the_samples_at_its_steps(tmp_path):
    # the down step starts a trial that continues the session: the force's samples
    # half-way through its step (14 ms late) drive the model there, and only a trial's
    # first samples show it. Those were left out of every BIC: the verdict was "effect
    # missing" naming nothing, the late force 9 BIC worse than no change.
    d = diagnose(fit(_updown_log(tmp_path, 0.014))).to_dict()
    assert d["verdict"] == "sensor effect"
    best = d["explanations"][0]
    assert best["detail"]["sensor"] == "channel timing"
    assert best["detail"]["late_channel"] == "force"
    # within two samples of the truth
    assert abs(best["detail"]["force_delay_s"] - 0.014) <= 0.02
