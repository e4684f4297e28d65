"""Case definitions of the diagnosis benchmark (``bench_diagnose.py``).

A case is one simulated balancer with one effect hidden at one strength, recorded at one
noise level by a tilted sensor, written in one of the reader's layouts, read back and
segmented: the trials a user would get. The null cases hide nothing (they measure false
alarms). Every random choice of a case comes from ``np.random.default_rng(case.seed)``.
"""

from __future__ import annotations

import tempfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from balancer_id.identify.data import TrialData
from balancer_id.model import parse_model
from balancer_id.read import read_log, write_log
from balancer_id.read.recording import Recording
from balancer_id.segment import find_trials
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings

#: The paper's balancer (MODEL.md reference values).
PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
#: Relative spread of the truth around :data:`PAPER`, drawn per case.
TRUTH_SPREAD = 0.2
#: Thrusts of the six runs (N, up positive): the paper's weights.
THRUSTS = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)
#: Rest before the step and recording after it (s).
REST_S, MOTION_S = 2.0, 8.0
#: White acceleration noise levels (m/s^2) and the force noise (N).
NOISES = (0.02, 0.05)
FORCE_NOISE = 0.03
#: Tilt of the sensor's z axis from the vertical (degrees), drawn per case.
TILT_RANGE = (5.0, 25.0)
#: Layouts the logs are written in, rotated over the cases of an effect.
LAYOUTS = ("pasco-capstone", "pasco-sparkvue", "phyphox", "generic")
#: Layouts that hold one run per file (one file per thrust is written).
ONE_RUN_LAYOUTS = ("phyphox", "generic")
#: The model fitted when nothing but the hidden effect differs from the paper's.
PAPER_MODEL = "variable_viscosity"
#: Built-in effects this benchmark does not cover, and why.
NOT_HERE = {
    "servo": "needs a robot reference move, not step trials; evaluated separately "
    "(robot-coupling benchmark), not here",
}


@dataclass(frozen=True)
class Hidden:
    """One effect to hide: the true model, the fitted model and the strengths.

    Attributes
    ----------
    effect : str
        Name of the hidden effect (what the diagnosis should suggest first).
    truth_spec : str
        Spec of the simulated balancer.
    fit_spec : str
        Spec of the model that is fitted and diagnosed.
    strengths : tuple of dict
        The hidden effect's true parameters, one dict per strength.
    """

    effect: str
    truth_spec: str
    fit_spec: str
    strengths: tuple[dict[str, float], ...]

    def label(self, k: int) -> str:
        """The strength ``k`` as ``name=value`` pairs."""
        return ", ".join(f"{n}={v:g}" for n, v in self.strengths[k].items())


#: Every built-in effect but ``servo``, at three realistic strengths.
HIDDEN: tuple[Hidden, ...] = (
    Hidden(
        "karnopp",
        "variable_viscosity+karnopp",
        PAPER_MODEL,
        ({"f_s": 0.5}, {"f_s": 1.0}, {"f_s": 1.5}),
    ),
    Hidden(
        "speed_limit",
        "variable_viscosity+speed_limit",
        PAPER_MODEL,
        ({"v_max": 0.35}, {"v_max": 0.5}, {"v_max": 0.7}),
    ),
    Hidden(
        "dead_time",
        "variable_viscosity+dead_time",
        PAPER_MODEL,
        ({"tau_d": 0.03}, {"tau_d": 0.06}, {"tau_d": 0.1}),
    ),
    Hidden(
        "bias",
        "variable_viscosity+bias",
        PAPER_MODEL,
        ({"b": 0.03}, {"b": 0.06}, {"b": 0.1}),
    ),
    Hidden(
        "asymmetric_lag",
        "variable_viscosity+asymmetric_lag",
        PAPER_MODEL,
        (
            {"T_up": 0.28, "T_down": 0.38},
            {"T_up": 0.25, "T_down": 0.42},
            {"T_up": 0.3, "T_down": 0.36},
        ),
    ),
    Hidden(
        "variable_viscosity",
        "variable_viscosity",
        "viscous",
        ({"A": 0.2}, {"A": 0.4}, {"A": 0.6}),
    ),
)

#: Nothing hidden: the paper's balancer fitted with the paper's model.
NULL = Hidden("none", PAPER_MODEL, PAPER_MODEL, ({},))


@dataclass(frozen=True)
class Case:
    """One simulated log set to diagnose.

    Attributes
    ----------
    hidden : Hidden
        What is hidden (:data:`NULL` for a false-alarm case).
    strength : int
        Index into ``hidden.strengths``.
    noise : float
        Acceleration noise (m/s^2).
    seed : int
        The user-facing seed number (0 .. ``--seeds`` - 1).
    layout : str
        File layout the logs are written in.
    """

    hidden: Hidden
    strength: int
    noise: float
    seed: int
    layout: str

    @property
    def effect(self) -> str:
        """The hidden effect (``"none"`` for a false-alarm case)."""
        return self.hidden.effect

    @property
    def strength_label(self) -> str:
        """The hidden parameters, or ``-`` when nothing is hidden."""
        return self.hidden.label(self.strength) or "-"

    @property
    def rng_seed(self) -> int:
        """The case's own seed, stable across runs and independent of the other cases."""
        key = f"{self.effect}|{self.strength}|{self.noise:g}|{self.seed}|{self.layout}"
        return zlib.crc32(key.encode())


@dataclass
class Setup:
    """What a case simulated and what the reader and segmenter made of it.

    Attributes
    ----------
    truth : dict
        True parameter values of the simulated balancer.
    tilt_deg : float
        Tilt of the sensor.
    trials : list of TrialData
        The trials found in the logs, renumbered over all files.
    paths : list of str
        The log files (already deleted when the case returns).
    warnings : list of str
        The reader's warnings.
    """

    truth: dict[str, float]
    tilt_deg: float
    trials: list[TrialData]
    paths: list[str]
    warnings: list[str] = field(default_factory=list)


def build_cases(seeds: int, *, quick: bool = False) -> tuple[list[Case], list[Case]]:
    """The hidden-effect cases and the false-alarm cases.

    Parameters
    ----------
    seeds : int
        Seeds per (effect, strength, noise).
    quick : bool
        One strength (the middle one) and one noise level (the larger).

    Returns
    -------
    hidden : list of Case
        Layouts rotate over the cases of each effect.
    null : list of Case
        Nothing hidden: every noise level, seed and layout.
    """
    noises = NOISES[-1:] if quick else NOISES
    hidden: list[Case] = []
    for h in HIDDEN:
        strengths = [len(h.strengths) // 2] if quick else list(range(len(h.strengths)))
        k = 0
        for s in strengths:
            for noise in noises:
                for seed in range(seeds):
                    hidden.append(Case(h, s, noise, seed, LAYOUTS[k % len(LAYOUTS)]))
                    k += 1
    null = [
        Case(NULL, 0, noise, seed, layout)
        for noise in noises
        for seed in range(seeds)
        for layout in LAYOUTS
    ]
    return hidden, null


def true_parameters(case: Case, rng: np.random.Generator) -> dict[str, float]:
    """The paper's balancer varied by up to :data:`TRUTH_SPREAD`, plus the hidden effect.

    The hidden effect's own parameters are used exactly (they name the strength).
    """
    model = parse_model(case.hidden.truth_spec)
    base = {k: v * float(rng.uniform(1 - TRUTH_SPREAD, 1 + TRUTH_SPREAD)) for k, v in PAPER.items()}
    truth = {**base, **case.hidden.strengths[case.strength]}
    return {k: v for k, v in truth.items() if k in model.param_names}


def _write_and_read(
    folder: Path, recordings: Sequence[Recording], layout: str
) -> tuple[list[TrialData], list[str], list[str]]:
    """Write the runs in ``layout`` (one file per run for one-run layouts), read, segment."""
    if layout in ONE_RUN_LAYOUTS:
        groups = [[rec] for rec in recordings]
    else:
        groups = [list(recordings)]
    trials: list[TrialData] = []
    paths: list[str] = []
    warnings: list[str] = []
    for k, group in enumerate(groups):
        path = folder / f"{layout}_{k + 1}.csv"
        write_log(path, group, layout)
        log = read_log(path)
        warnings.extend(log.warnings)
        trials.extend(TrialData.from_trial(t) for t in find_trials(log))
        paths.append(str(path))
    for k, td in enumerate(trials):
        td.index = k
    return trials, paths, warnings


def make_setup(case: Case) -> Setup:
    """Simulate the case, write its logs to a temporary folder, read and segment them.

    Parameters
    ----------
    case : Case
        The case.

    Returns
    -------
    Setup
        The truth, the tilt and the trials found.
    """
    rng = np.random.default_rng(case.rng_seed)
    truth = true_parameters(case, rng)
    tilt = float(rng.uniform(*TILT_RANGE))
    sensor = SensorSettings(tilt_deg=tilt, accel_noise=case.noise, force_noise=FORCE_NOISE)
    recordings = synthetic_recordings(
        parse_model(case.hidden.truth_spec),
        truth,
        THRUSTS,
        sensor=sensor,
        rest_s=REST_S,
        duration_s=MOTION_S,
        seed=int(rng.integers(2**31)),
    )
    with tempfile.TemporaryDirectory(prefix="bench_diagnose_") as tmp:
        trials, paths, warnings = _write_and_read(Path(tmp), recordings, case.layout)
    return Setup(truth, tilt, trials, paths, warnings)
