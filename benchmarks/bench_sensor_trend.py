"""Sensor faults and drifts in time (issues 31.4, 33.2): does ``diagnose`` name them?

Each case draws a balancer (m_a log-uniform 1.5-150 kg, T_a 0.15-0.5 s, D0 and the
thrusts scaled with m_a, A |h| spanning 0.5-4), a tilted sensor (5-25 degrees, noise
0.01-0.04 m/s^2 scaled with the response), records it through the PASCO Capstone
layout, reads it back, fits ``variable_viscosity`` as a user would (``bid.fit``) and
diagnoses. The truth classes:

- ``null``: six step runs, nothing wrong (control for the sensor kinds).
- ``force-late``: the force channel time-stamped 20-60 ms after the acceleration.
- ``accel-late``: the acceleration 20-60 ms behind the force (a dead time fits alike).
- ``gain``: the accelerometer 3-6 % hot or cold.
- ``clipped``: each accelerometer axis clipped at a range the step's peak exceeds.
- ``session-null``: one continuous session (the thrust changes every 6-10 s, 5-10 min),
  nothing drifting (control for the trend).
- ``trend-P``: the same session with P (D0 or m_a) changing linearly in time by 30-50 %.

A case is *right* when: ``null`` and ``session-null`` are not called a sensor effect nor
a drift (no false naming: any verdict naming neither counts as right);
``force-late``, ``gain``, ``clipped``: ``sensor effect`` from the right sensor
explanation (its ``detail.sensor``); ``accel-late``: the channel timing named, as the
verdict or as the ambiguity with ``dead_time`` (the log cannot tell them apart);
``trend-P``: ``parameter drift`` naming P from the trend within the run (or an
ambiguity naming it).

Run: ``python benchmarks/bench_sensor_trend.py [--seeds N] [--seed S] [--classes a,b]``.
A fresh seed is drawn each run and printed; ``--seed`` repeats a run.
"""

from __future__ import annotations

import argparse
import dataclasses
import secrets
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from balancer_id.diagnostics.diagnosis import diagnose
from balancer_id.identify.api import fit as fit_logs
from balancer_id.model import parse_model
from balancer_id.read import write_log
from balancer_id.read.recording import Recording
from balancer_id.simulation.engine import simulate
from balancer_id.simulation.inputs import Thrust
from balancer_id.simulation.synth import SensorSettings, synthetic_recordings, up_vector

CLASSES = (
    "null",
    "force-late",
    "accel-late",
    "gain",
    "clipped",
    "session-null",
    "trend-D0",
    "trend-m_a",
)
PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
LEVELS = (2.45, 4.9, 7.35)
G = 9.8
FS = 200.0


@dataclass
class Outcome:
    """What ``diagnose`` said about one case."""

    klass: str
    seed: int
    verdict: str = "error"
    said: str = ""
    right: bool = False
    seconds: float = 0.0
    error: str = ""


def _balancer(rng: np.random.Generator) -> tuple[dict[str, float], float]:
    """True values and the thrust scale of a balancer of random size."""
    scale = float(np.exp(rng.uniform(np.log(0.1), np.log(10.0))))
    truth = {
        "m_a": PAPER["m_a"] * scale * float(rng.uniform(0.8, 1.2)),
        "T_a": float(rng.uniform(0.15, 0.5)),
        "D0": PAPER["D0"] * scale * float(rng.uniform(0.7, 1.3)),
        "A": PAPER["A"] / scale * float(rng.uniform(0.7, 1.3)),
    }
    return truth, scale


def _sensor(rng: np.random.Generator, scale: float, truth: dict[str, float]) -> SensorSettings:
    peak = 7.35 * scale / truth["m_a"]  # the largest step's acceleration, about
    return SensorSettings(
        tilt_deg=float(rng.uniform(5, 25)),
        tilt_azimuth_deg=float(rng.uniform(0, 360)),
        accel_noise=float(rng.uniform(0.02, 0.06)) * peak,
        force_noise=0.005 * 7.35 * scale,
        g=G,
    )


def _steps(klass: str, rng: np.random.Generator, model, truth, scale, sensor) -> list[Recording]:
    """Six step runs with the class's sensor fault applied to the recorded channels."""
    levels = [s * h * scale for h in LEVELS for s in (1.0, -1.0)]
    rng.shuffle(levels)
    recs = synthetic_recordings(model, truth, levels, sensor=sensor, seed=int(rng.integers(2**31)))
    out = []
    delay = float(rng.uniform(0.02, 0.06))
    gain = float(rng.choice([-1.0, 1.0])) * float(rng.uniform(0.03, 0.06))
    for rec in recs:
        t = rec.time
        if klass == "force-late":
            rec = dataclasses.replace(rec, force=np.interp(t - delay, t, rec.force))
        elif klass == "accel-late":
            acc = np.column_stack([np.interp(t - delay, t, c) for c in rec.accel.T])
            rec = dataclasses.replace(rec, accel=acc)
        elif klass == "gain":
            rec = dataclasses.replace(rec, accel=rec.accel * (1.0 + gain))
        out.append(rec)
    if klass == "clipped":
        # the range just under the largest step's peak on the axis nearest the vertical:
        # the top of the largest peaks is cut
        stacked = np.vstack([r.accel for r in out])
        axis = int(np.argmax(np.abs(np.median(stacked, axis=0))))
        col = np.abs(stacked[:, axis])
        rest = float(np.median(col))
        limit = rest + 0.6 * (float(np.max(col)) - rest)
        out = [dataclasses.replace(r, accel=np.clip(r.accel, -limit, limit)) for r in out]
    return out


def _session(klass: str, rng: np.random.Generator, model, truth, scale, sensor) -> list[Recording]:
    """One continuous session; the drifting parameter (if any) changes linearly in time."""
    hold = float(rng.uniform(6.0, 10.0))
    minutes = float(rng.uniform(5.0, 10.0))
    n_steps = int(minutes * 60 / hold)
    # the load goes up and down around its start: each level held, then its opposite
    levels = []
    for _ in range(n_steps // 2):
        h = float(rng.choice(LEVELS)) * scale
        levels += [h, -h]
    rest = 2.0
    duration = rest + hold * len(levels)
    drift = klass.split("-", 1)[1] if klass.startswith("trend-") else None
    change = float(rng.uniform(0.3, 0.5)) * float(rng.choice([-1.0, 1.0]))
    starts = rest + hold * np.arange(len(levels))
    thrust = Thrust(starts, np.asarray(levels, dtype=float))
    dt = 1.0 / FS
    time_all = np.arange(round(duration / dt) + 1) * dt
    # piecewise: each hold simulated with the parameter's value at its middle, from the
    # state the previous hold ended in
    pieces = np.r_[0.0, starts[1:], duration + dt]
    accel, force = [], []
    x0, t_prev = None, None
    for k in range(len(pieces) - 1):
        sel = (time_all >= pieces[k] - 1e-9) & (time_all < pieces[k + 1] - 1e-9)
        t = time_all[sel]
        values = dict(truth)
        if drift is not None:
            frac = 0.5 * (pieces[k] + pieces[k + 1]) / duration
            values[drift] = truth[drift] * (1.0 + change * (frac - 0.5))
        # from the state the previous hold ended in, at its last sample
        grid = t if t_prev is None else np.r_[t_prev, t]
        sim = simulate(model, values, grid, thrust, x0=x0)
        keep = slice(0 if t_prev is None else 1, None)
        accel.append(sim.accel[keep])
        force.append(sim.operating_force[keep])
        x0 = (float(sim.drive_force[-1]), float(sim.velocity[-1]), float(sim.position[-1]))
        t_prev = float(t[-1])
    a = np.concatenate(accel)
    f = np.concatenate(force)
    up = up_vector(sensor.tilt_deg, float(sensor.tilt_azimuth_deg or 0.0))
    noise = rng.normal(0.0, sensor.accel_noise, (a.size, 3))
    specific = (a + sensor.g)[:, None] * up[None, :] + noise
    f = f + rng.normal(0.0, sensor.force_noise, f.shape)
    return [
        Recording(
            name="Run #1",
            time=time_all,
            force=f,
            accel=specific,
            accel_includes_gravity=True,
            accel_axes=("x", "y", "z"),
            sample_rate_hz=FS,
        )
    ]


def _top(d: dict) -> list[dict]:
    """The explanations the verdict rests on: the ambiguity's two, else the best one of
    the verdict (the list is by BIC; one the verdict set aside may come first)."""
    exps = d.get("explanations") or []
    if d["verdict"] == "ambiguous":
        amb = d.get("ambiguity") or {}
        labels = {amb.get("best"), amb.get("runner_up")}
        return [e for e in exps if e.get("label") in labels]
    return [e for e in exps if e.get("verdict") == d["verdict"]][:1]


def _sensor_named(d: dict, which: str) -> bool:
    return any((e.get("detail") or {}).get("sensor") == which for e in _top(d))


def judge(klass: str, d: dict) -> bool:
    """Whether the diagnosis is the class's (see the module's docstring)."""
    verdict = d["verdict"]
    top = _top(d)
    if klass in ("null", "session-null"):
        named_sensor = any(e.get("kind") == "sensor" for e in top)
        trend = any(e.get("kind") == "trend" for e in top)
        return not (named_sensor or trend)
    if klass == "force-late":
        return verdict == "sensor effect" and _sensor_named(d, "channel timing")
    if klass == "accel-late":
        return verdict in ("sensor effect", "ambiguous") and _sensor_named(d, "channel timing")
    if klass == "gain":
        return verdict == "sensor effect" and _sensor_named(d, "gain")
    if klass == "clipped":
        return verdict == "sensor effect" and _sensor_named(d, "clipping")
    if klass.startswith("trend-"):
        name = klass.split("-", 1)[1]
        return verdict in ("parameter drift", "ambiguous") and any(
            e.get("kind") == "trend" and name in e.get("parameters", []) for e in top
        )
    raise ValueError(klass)


def run_case(klass: str, seed: int) -> Outcome:
    """Simulate, write, read, fit and diagnose one case; never raises."""
    t0 = time.perf_counter()
    out = Outcome(klass, seed)
    try:
        rng = np.random.default_rng(seed)
        model = parse_model("variable_viscosity")
        truth, scale = _balancer(rng)
        sensor = _sensor(rng, scale, truth)
        make = _session if klass.startswith(("session", "trend")) else _steps
        recs = make(klass, rng, model, truth, scale, sensor)
        with tempfile.TemporaryDirectory(prefix="bench_sensor_trend_") as tmp:
            path = Path(tmp) / "log.csv"
            write_log(path, recs, "pasco-capstone")
            fitted = fit_logs(str(path), model="variable_viscosity", profile=False)
            d = diagnose(fitted).to_dict()
        out.verdict = str(d["verdict"])
        out.said = str(d["summary"])[:160]
        out.right = judge(klass, d)
    except Exception as exc:  # a benchmark reports every failure and goes on
        out.error = f"{type(exc).__name__}: {exc}"
    out.seconds = time.perf_counter() - t0
    return out


def table(outcomes: list[Outcome]) -> str:
    """Truth class x verdict, with the share right."""
    verdicts = sorted({o.verdict for o in outcomes})
    header = ["class", "n", *verdicts, "right %"]
    rows = []
    for klass in CLASSES:
        group = [o for o in outcomes if o.klass == klass]
        if not group:
            continue
        c = Counter(o.verdict for o in group)
        right = 100.0 * sum(o.right for o in group) / len(group)
        rows.append([klass, str(len(group)), *(str(c.get(v, 0)) for v in verdicts), f"{right:.0f}"])
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    return "\n".join(
        "  ".join(
            c.ljust(w) if i == 0 else c.rjust(w)
            for i, (c, w) in enumerate(zip(r, widths, strict=False))
        )
        for r in [header, ["-" * w for w in widths], *rows]
    )


def main(argv: list[str] | None = None) -> int:
    """Run the cases and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=3, help="cases per class")
    ap.add_argument("--seed", type=int, default=None, help="repeat a run (default: fresh)")
    ap.add_argument("--classes", default="", help="comma-separated classes (default all)")
    ap.add_argument("--jobs", type=int, default=1, help="processes")
    args = ap.parse_args(argv)
    seed = args.seed if args.seed is not None else secrets.randbelow(2**31)
    print(f"seed {seed} (repeat with --seed {seed})", flush=True)
    classes = [c for c in args.classes.split(",") if c] or list(CLASSES)
    master = np.random.default_rng(seed)
    cases = [(k, int(master.integers(2**31))) for _ in range(args.seeds) for k in classes]
    outcomes = []
    if args.jobs <= 1:
        for klass, s in cases:
            o = run_case(klass, s)
            outcomes.append(o)
            print(
                f"  {klass} {s}: {o.verdict} {'ok' if o.right else 'WRONG'} "
                f"({o.seconds:.0f} s) {o.error or o.said}",
                flush=True,
            )
    else:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(args.jobs) as pool:
            for o in pool.map(run_case, *zip(*cases, strict=False)):
                outcomes.append(o)
                print(
                    f"  {o.klass} {o.seed}: {o.verdict} {'ok' if o.right else 'WRONG'} "
                    f"({o.seconds:.0f} s) {o.error or o.said}",
                    flush=True,
                )
    print()
    print(table(outcomes))
    total = 100.0 * sum(o.right for o in outcomes) / max(len(outcomes), 1)
    print(
        f"\nright: {total:.0f} % of {len(outcomes)} cases; median "
        f"{np.median([o.seconds for o in outcomes]):.0f} s a case"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
