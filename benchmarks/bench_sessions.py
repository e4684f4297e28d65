"""Logs as people record them (issue 8): sessions, payload changes, guided moves.

1. Session vs separate runs: the balancer of ``bench_fit.py`` (m_a 15.1, T_a 0.33, D0 6,
   A 0.4; noise 0.03 m/s^2, force noise 0.03 N, sensor tilted 5-25 degrees) recorded
   (a) as six separate step runs (±2.45, ±4.9, ±7.35 N from rest) and (b) as one 70 s
   session in which the thrust changes six times while the load moves (2 s rest, then
   +2.45, +4.9, -2.45, -4.9, +7.35, -7.35 N held 11.3 s each). Both are segmented from
   the raw signals and fitted with ``variable_viscosity``; per parameter: bias, spread
   and the share of seeds within the fit benchmark's tolerances (m_a 2 %, T_a 5 %,
   D0 8 %, A 15 %).
2. Payload change between runs: six runs (+2.45, +4.9, +7.35, -2.45, -4.9, -7.35 N),
   the payload changed after run 2, 3 or 4 (m_a +1, +2 or +4 kg), so that a thrust
   level occurs on both sides of the change (a change that coincides with a change of
   every thrust level cannot be told from a thrust dependence); detection =
   ``diagnose`` names a split of m_a at the right run. False alarms: the same logs
   without a change, and logs with a hidden effect (``karnopp`` f_s 0.5-1 N,
   ``dead_time`` 60 ms) fitted with the paper's model.
   Uses the pure split test on the per-trial fits, as ``diagnose`` does.
3. Guided moves: a person pushes and pulls the load smoothly (no step; peak 4-7 N over
   5-8 s); one excitation window, the measured force as input; accuracy per parameter.

Run: ``python benchmarks/bench_sessions.py [--seeds N]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from balancer_id.diagnostics.groups import detect_groups
from balancer_id.identify.data import from_trials
from balancer_id.identify.matching import match_trials
from balancer_id.identify.per_trial import fit_each_trial
from balancer_id.model import parse_model
from balancer_id.read.recording import Log
from balancer_id.segment import find_trials
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' simlib

from simlib.sessions import guided_move_thrust, record, session_thrust

TRUTH = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
TOLERANCE = {"m_a": 0.02, "T_a": 0.05, "D0": 0.08, "A": 0.15}
THRUSTS = (2.45, -2.45, 4.9, -4.9, 7.35, -7.35)
SESSION = (2.45, 4.9, -2.45, -4.9, 7.35, -7.35)
#: Payload runs: each thrust level on both sides of a change after run 2, 3 or 4.
PAYLOAD_ORDER = (2.45, 4.9, 7.35, -2.45, -4.9, -7.35)
START = {"m_a": 15.0, "T_a": 0.3}


def _fit(model, recs, name: str) -> dict[str, float]:
    trials = find_trials(Log(Path(name), "pasco-capstone", recs))
    res = match_trials(model, from_trials(trials), start=START)
    return {n: p.value for n, p in res.parameters.items()}


def _table(title: str, rows: list[dict[str, float]], truth: dict[str, float]) -> None:
    print(title)
    print(f"  {'param':6} {'bias %':>8} {'spread %':>9} {'in tol':>7}")
    for n, t in truth.items():
        x = np.array([r[n] for r in rows])
        inside = np.mean(np.abs(x / t - 1) <= TOLERANCE[n]) * 100
        print(
            f"  {n:6} {100 * (x.mean() / t - 1):+8.2f} {100 * x.std(ddof=1) / t:9.2f} "
            f"{inside:6.0f}%  (tol {100 * TOLERANCE[n]:.0f} %)"
        )


def sessions(model, seeds: int) -> None:
    """Session of six changes while moving vs six separate step runs."""
    sep, ses = [], []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        sensor = SensorSettings(tilt_deg=float(rng.uniform(5, 25)))
        sep.append(
            _fit(model, synthetic_recordings(model, TRUTH, THRUSTS, sensor=sensor, seed=seed), "s")
        )
        rec = record(
            model, TRUTH, session_thrust(SESSION, 68.0 / 6), 70.0, sensor=sensor, seed=seed
        )
        ses.append(_fit(model, [rec], "session"))
    _table(f"six separate step runs ({seeds} seeds)", sep, TRUTH)
    _table(f"one 70 s session, six changes while moving ({seeds} seeds)", ses, TRUTH)


def _split_found(model, recs) -> tuple[bool, int | None]:
    trials = from_trials(find_trials(Log(Path("p.csv"), "pasco-capstone", recs)))
    match = match_trials(model, trials, start=START)
    per = fit_each_trial(model, trials, match.values())
    src = {t.index: t.source for t in trials}
    split = detect_groups(
        model.param_names,
        [src[p.index] for p in per],
        [p.values for p in per],
        [p.stderr for p in per],
        [p.thrust_N for p in per],
    )
    if split is None:
        return False, None
    return split.parameter == "m_a", split.split_after


def payload(model, seeds: int) -> None:
    """Detection rate of a payload change and false alarms without one."""
    hits: dict[float, list[bool]] = {1.0: [], 2.0: [], 4.0: []}
    for dm in hits:
        for seed in range(seeds):
            k = 2 + seed % 3
            sensor = SensorSettings(tilt_deg=10.0 + seed)
            a = synthetic_recordings(model, TRUTH, PAYLOAD_ORDER[:k], sensor=sensor, seed=seed)
            heavier = {**TRUTH, "m_a": TRUTH["m_a"] + dm}
            b = synthetic_recordings(
                model, heavier, PAYLOAD_ORDER[k:], sensor=sensor, seed=seed + 500
            )
            for j, r in enumerate(b):
                r.name = f"Run #{k + j + 1}"
            is_m, where = _split_found(model, a + b)
            hits[dm].append(is_m and where == k)
    for dm, h in hits.items():
        print(
            f"payload +{dm:g} kg (m_a +{100 * dm / TRUTH['m_a']:.0f} %): "
            f"detected at the right run in {sum(h)}/{len(h)}"
        )
    alarms = {"nothing changed": 0, "karnopp hidden": 0, "dead_time hidden": 0}
    for seed in range(seeds):
        sensor = SensorSettings(tilt_deg=10.0 + seed)
        recs = synthetic_recordings(model, TRUTH, THRUSTS, sensor=sensor, seed=seed + 1000)
        alarms["nothing changed"] += _split_found(model, recs)[1] is not None
        kar = parse_model("variable_viscosity+karnopp")
        fs = 0.5 + 0.5 * (seed % 3) / 2
        recs = synthetic_recordings(
            kar, {**TRUTH, "f_s": fs}, THRUSTS, sensor=sensor, seed=seed + 2000
        )
        alarms["karnopp hidden"] += _split_found(model, recs)[1] is not None
        dt = parse_model("variable_viscosity+dead_time")
        recs = synthetic_recordings(
            dt, {**TRUTH, "tau_d": 0.06}, THRUSTS, sensor=sensor, seed=seed + 3000
        )
        alarms["dead_time hidden"] += _split_found(model, recs)[1] is not None
    for what, n in alarms.items():
        print(f"false alarms, {what}: {n}/{seeds}")


def guided(model, seeds: int) -> None:
    """Accuracy from one guided move."""
    rows = []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        peak = float(rng.uniform(4, 7)) * float(rng.choice([-1, 1]))
        move = float(rng.uniform(5, 8))
        sensor = SensorSettings(tilt_deg=float(rng.uniform(5, 25)))
        rec = record(
            model, TRUTH, guided_move_thrust(peak, move), move + 6.0, sensor=sensor, seed=seed
        )
        rows.append(_fit(model, [rec], "move"))
    _table(f"one guided move ({seeds} seeds)", rows, TRUTH)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--only", choices=("sessions", "payload", "guided"))
    args = parser.parse_args()
    model = parse_model("variable_viscosity")
    if args.only in (None, "sessions"):
        sessions(model, args.seeds)
    if args.only in (None, "payload"):
        payload(model, args.seeds)
    if args.only in (None, "guided"):
        guided(model, args.seeds)


if __name__ == "__main__":
    sys.exit(main())
