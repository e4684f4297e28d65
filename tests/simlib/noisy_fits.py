"""Seeded logs of the paper balancer with (coloured) noise, segmented and fitted: what the
standard-error test and ``benchmarks/bench_uncertainty.py`` judge the errors on."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from balancer_id.identify.data import TrialData
from balancer_id.identify.matching import MatchResult, match_trials
from balancer_id.model import parse_model
from balancer_id.read.recording import Log
from balancer_id.segment import find_trials
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings


def fit_noisy_logs(
    truth: Mapping[str, float], thrusts: Sequence[float], rho: float, seeds: int
) -> list[MatchResult]:
    """The ``variable_viscosity`` fit of one simulated 6-trial log per seed.

    Each log: ``truth`` stepped through ``thrusts``, a sensor tilted 5-25 degrees (drawn
    from the seed), noise 0.03 on acceleration and force with AR(1) lag-one correlation
    ``rho``; read back through gravity removal and step detection.

    Parameters
    ----------
    truth : mapping
        The model's parameters.
    thrusts : sequence of float
        The trials' thrusts (N).
    rho : float
        Lag-one correlation of the noise (0: white).
    seeds : int
        Seeds 0 .. seeds - 1.

    Returns
    -------
    list of MatchResult
    """
    model = parse_model("variable_viscosity")
    fits = []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        sensor = SensorSettings(
            tilt_deg=float(rng.uniform(5, 25)),
            accel_noise=0.03,
            force_noise=0.03,
            noise_correlation=rho,
        )
        recs = synthetic_recordings(model, truth, thrusts, sensor=sensor, seed=seed)
        log = Log(Path(f"seed{seed}.csv"), "pasco-capstone", recs)
        trials = [TrialData.from_trial(t) for t in find_trials(log)]
        fits.append(match_trials(model, trials, start={"m_a": 14.0, "T_a": 0.3}))
    return fits
