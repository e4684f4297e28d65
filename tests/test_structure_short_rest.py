"""The structure test's false alarms on a short rest stay at their nominal rate (issue 31).

The test compares the residual's power in motion with the noise's at rest. A rest of a
few tens of samples reads the noise's power with a skewed error (a chi-square of few
degrees of freedom: more often low than high), and the normal approximation of the
ratio's spread that decided it raised "the model misses something" on clean fits several
times as often as its 3-sigma level says (``bench_universe`` clean world 8209: motion 1.9
times the rest's power, values right, untrusted). The ratio is now held to its F
distribution.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from balancer_id.identify import structure


def test_pure_noise_with_a_short_rest_is_rarely_called_a_misfit(monkeypatch):
    rng = np.random.default_rng(31)
    trial = SimpleNamespace(level_se_N=None, thrust_N=1.0, index=0)
    draws, called = 1000, 0
    for _ in range(draws):
        parts = [(trial, rng.normal(0.0, 0.02, 60), rng.normal(0.0, 0.02, 2000))]
        monkeypatch.setattr(structure, "residual_around_steps", lambda match, p=parts: p)
        monkeypatch.setattr(structure, "residual_continuing", lambda match: [])
        called += structure.structured_residual(None) is not None  # type: ignore[arg-type]
    # nominal: the 3-sigma one-sided level, 0.135 % (with the whiteness test about 0.3 %,
    # 3 of 1000); the normal approximation called 1.25 % (12 of 1000)
    assert called <= 7, called


def test_a_real_excess_over_a_short_rest_is_still_called(monkeypatch):
    rng = np.random.default_rng(32)
    trial = SimpleNamespace(level_se_N=None, thrust_N=1.0, index=0)
    called = 0
    for _ in range(100):
        # the motion's residual at twice the noise's power (a misfit of the noise's RMS)
        parts = [(trial, rng.normal(0.0, 0.02, 100), rng.normal(0.0, 0.02 * np.sqrt(2), 2000))]
        monkeypatch.setattr(structure, "residual_around_steps", lambda match, p=parts: p)
        monkeypatch.setattr(structure, "residual_continuing", lambda match: [])
        called += structure.structured_residual(None) is not None  # type: ignore[arg-type]
    # the F test's power there is about 94 % (the normal approximation's 99 %)
    assert called >= 85, called


def _called(monkeypatch, rng, rest_n: int, motion_scale: float, draws: int) -> int:
    trial = SimpleNamespace(level_se_N=None, thrust_N=1.0, index=0)
    called = 0
    for _ in range(draws):
        parts = [(trial, rng.normal(0.0, 0.02, rest_n), rng.normal(0.0, 0.02 * motion_scale, 50))]
        cont = [rng.normal(0.0, 0.02 * motion_scale, 170) for _ in range(3)]
        monkeypatch.setattr(structure, "residual_around_steps", lambda match, p=parts: p)
        monkeypatch.setattr(structure, "residual_continuing", lambda match, c=cont: c)
        called += structure.structured_residual(None) is not None  # type: ignore[arg-type]
    return called


def test_a_50_hz_sessions_half_second_of_rest_is_enough(monkeypatch):
    # issue 31 (bench_universe world 14420044004): a 50 Hz session whose trial window
    # holds 0.5 s of rest (25 samples) before its first step; the residual in motion at
    # 2.2 times the noise's RMS (a speed limit the model lacks, A 9 standard errors off),
    # trusted: the test needed 50 resting samples and never ran. The F test knows how
    # little a short rest says; it now runs from 20.
    rng = np.random.default_rng(33)
    assert _called(monkeypatch, rng, 25, 2.2, 50) >= 48
    # and noise alone over the same short rest is rarely called a misfit
    assert _called(monkeypatch, rng, 25, 1.0, 1000) <= 7
