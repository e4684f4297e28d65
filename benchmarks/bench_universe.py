"""Is "trusted" right on worlds nobody has seen? (issue 31)

Each world is drawn afresh from a seed printed at the start (a new seed each run unless
``--seed`` is given):

- a balancer: ``m_a`` log-uniform 0.2-2000 kg, ``T_a`` 0-1.5 s, a viscous time constant
  such that the top speed is 0.2-2 m/s, ``A |u|`` 0-1.2 at the median thrust, thrusts
  giving 0.3-3 m/s^2 at first;
- a recording: separate step runs, one session with rests between levels, up-then-down
  without rest, or a person's guided move; 1-3 thrust levels, both signs, orders mixed;
- a layout: PASCO Capstone, SPARKvue, phyphox or a generic CSV (the writable layouts;
  one-run layouts get the session forms), with a comma or a semicolon;
- a sensor: 50-500 Hz, white or coloured (AR(1)) noise of 0.005-0.1 m/s^2, force noise
  0.2-5 % of the thrust, a tilt of 0-25 degrees, and sometimes (each about 1 in 6) an
  accelerometer gain of +-5 %, clipping at the 99th percentile of the magnitude, a force
  channel 5-60 ms late, a first-order low-pass at 4-20 Hz, drop-outs;
- sometimes (1 in 4) an effect the fitted model lacks: Karnopp friction, a speed limit
  that clips, a dead time, an asymmetric lag.

Each log is fitted as a user would (``balancer_id.identify.fit``, default model and
starts). Scored against the truth, over the trusted parameters (``m_a, T_a, D0, A``
fitted; a parameter's own ``trusted`` where the fit gives one, so an untrusted fit's
parameters that keep their trust count too): the share outside their 99 % interval
(target <= 2 %), each parameter's 95 % coverage (target >= 90 %); the share of worlds
trusted per class (clean, sensor, effect); refusals, tracebacks and hangs (a world over
``--timeout`` s).

Works on any version of the code (it reads only ``fit``'s result), so "before" comes from
an older checkout with ``PYTHONPATH`` pointing there.

With ``--verdicts`` each fitted world is also diagnosed (``balancer_id.diagnostics.api.
diagnose``) and its verdict scored (target >= 90 %): a drawn effect named first by
``effect missing`` (a dead time also as its twin, a late acceleration channel); a drawn
sensor fault (gain, channel delay, low-pass, clipping) named by its explanation or, for
clipping, by the reader's note on the trials; nothing drawn, ``adequate``; ``adequate``
also where every trusted value still holds the truth (a fault below detection).

Run: ``python benchmarks/bench_universe.py [--worlds N] [--seed S] [--timeout S] [-v]
[--verdicts]``.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' simlib

from balancer_id.model.spec import resolve_model
from balancer_id.read.recording import Recording
from balancer_id.read.writers import write_log
from balancer_id.simulation.engine import TrialInput, simulate_many
from balancer_id.simulation.inputs import Thrust
from balancer_id.simulation.synth import ar1_noise, keep_mask, up_vector

G = 9.80665
FITTED = ("m_a", "T_a", "D0", "A")
Z99, Z95 = 2.5758, 1.95996


@dataclass
class World:
    """One drawn world: what was simulated and how it was recorded."""

    seed: int
    truth: dict[str, float]
    effect: str | None
    effect_values: dict[str, float]
    recording: str
    layout: str
    levels: list[float]
    rate: float
    faults: list[str] = field(default_factory=list)
    #: The sensor's draw: accelerometer noise (m/s^2), its AR(1) coefficient, force noise
    #: as a share of the median thrust, tilt (degrees).
    sensor: dict[str, float] = field(default_factory=dict)

    @property
    def kind(self) -> str:
        """``clean``, ``sensor`` (a sensor fault) or ``effect`` (the model lacks one)."""
        if self.effect:
            return "effect"
        return "sensor" if self.faults else "clean"

    def describe(self) -> str:
        t = self.truth
        return (
            f"m_a={t['m_a']:.3g} T_a={t['T_a']:.3g} D0={t['D0']:.3g} A={t['A']:.3g} "
            f"{self.recording}/{self.layout} {self.rate:g}Hz levels={len(self.levels)} "
            f"effect={self.effect}{self.effect_values or ''} faults={','.join(self.faults)} "
            + " ".join(f"{k}={v:.3g}" for k, v in self.sensor.items())
        )


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def draw_world(seed: int) -> tuple[World, list[Recording]]:
    """Draw a world and record it."""
    rng = np.random.default_rng(seed)
    m_a = _loguniform(rng, 0.2, 2000.0)
    T_a = max(float(rng.uniform(0.0, 1.5)), 0.002)
    a0 = _loguniform(rng, 0.3, 3.0)
    v_top = _loguniform(rng, 0.2, 2.0)
    u_med = m_a * a0
    n_levels = int(rng.integers(1, 4))
    mags = u_med * np.sort(rng.uniform(0.5, 1.5, n_levels))
    A = float(rng.uniform(0.0, 1.2)) / u_med
    D_eff = u_med / v_top  # the viscosity at the median thrust: top speed v_top
    D0 = D_eff * math.exp(A * u_med)
    truth = {"m_a": m_a, "T_a": T_a, "D0": D0, "A": A}
    effect, effect_values = None, {}
    if rng.uniform() < 0.25:
        effect = str(rng.choice(["karnopp", "speed_limit", "dead_time", "asymmetric_lag"]))
        if effect == "karnopp":
            effect_values = {"f_s": float(rng.uniform(0.05, 0.3)) * u_med}
        elif effect == "speed_limit":
            effect_values = {"v_max": float(rng.uniform(0.5, 0.8)) * v_top}
        elif effect == "dead_time":
            effect_values = {"tau_d": float(rng.uniform(0.03, 0.15))}
        else:
            effect_values = {"T_up": T_a, "T_down": T_a * float(rng.choice([0.4, 2.5]))}
    spec = "variable_viscosity" + (f"+{effect}" if effect else "")
    model = resolve_model(spec)
    values = {k: v for k, v in {**truth, **effect_values}.items() if k in model.param_names}
    recording = str(rng.choice(["steps", "session", "updown", "guided"], p=[0.4, 0.3, 0.2, 0.1]))
    layout = str(
        rng.choice(["pasco-capstone", "pasco-sparkvue", "phyphox", "generic"])
        if recording != "steps"
        else rng.choice(["pasco-capstone", "pasco-sparkvue"])
    )
    rate = float(rng.choice([50.0, 100.0, 200.0, 500.0], p=[0.15, 0.3, 0.4, 0.15]))
    levels = [float(m * s) for m in mags for s in (1, -1)]
    if rng.uniform() < 0.5:
        levels = sorted(levels, key=lambda x: x < 0)  # all ups, then all downs
    tau_v = m_a / D_eff
    hold = float(np.clip(3 * T_a + 2 * tau_v, 2.0, 6.0))
    rest = float(rng.uniform(1.0, 2.0))
    dt = 1.0 / rate
    thrusts: list[Thrust] = []
    durations: list[float] = []
    if recording == "steps":
        for u in levels:
            thrusts.append(Thrust.step(rest, u))
            durations.append(rest + hold)
    elif recording in ("session", "updown"):
        times, values_u = [rest], []
        for u in levels if recording == "session" else list(mags):
            pattern = (
                [(u, hold), (0.0, hold)]
                if recording == "session"
                else [(u, hold / 2), (-u, hold / 2), (0.0, hold)]
            )
            for level, span in pattern:
                values_u.append(level)
                times.append(times[-1] + span)
        thrusts.append(Thrust(np.array(times[:-1]), np.array(values_u)))
        durations.append(times[-1])
    else:
        from simlib.sessions import guided_move_thrust

        move = float(np.clip(6 * T_a + 4, 4.0, 10.0))
        thrusts.append(guided_move_thrust(1.5 * u_med, move, rest, rate))
        durations.append(rest + move + 2.0)
    faults: list[str] = []
    tilt = float(rng.uniform(0, 25))
    sigma = _loguniform(rng, 0.005, 0.1)
    rho = float(rng.uniform(0.5, 0.9)) if rng.uniform() < 0.3 else 0.0
    force_noise = _loguniform(rng, 0.002, 0.05) * u_med
    hot = float(rng.choice([-1, 1]) * rng.uniform(0.02, 0.05))
    gain = 1.0 + hot if rng.uniform() < 1 / 6 else 1.0
    clip = rng.uniform() < 1 / 6
    delay = float(rng.uniform(0.005, 0.06)) if rng.uniform() < 1 / 6 else 0.0
    lowpass = float(rng.uniform(4, 20)) if rng.uniform() < 1 / 6 else 0.0
    drop = float(rng.uniform(0.005, 0.03)) if rng.uniform() < 1 / 6 else 0.0
    if gain != 1.0:
        faults.append(f"gain{gain:.3f}")
    if delay:
        faults.append(f"delay{delay * 1e3:.0f}ms")
    if lowpass:
        faults.append(f"lowpass{lowpass:.0f}Hz")
    if rho:
        faults.append(f"coloured{rho:.2f}")  # not a fault: the tool widens for it
    # simulate finely enough for the fastest rate, then record
    fastest = max(1.0 / T_a, D0 / m_a)
    substeps = int(np.clip(np.ceil(dt * fastest / 0.25), 1, 4096))
    inputs = []
    for th, dur in zip(thrusts, durations, strict=True):
        t = np.arange(round(dur / dt) + 1) * dt
        inputs.append(TrialInput(t, th))
    sims = simulate_many(model, values, inputs, substeps=substeps)
    recs = []
    up = up_vector(tilt, float(rng.uniform(0, 360)))
    for k, (sim, inp) in enumerate(zip(sims, inputs, strict=True)):
        t = inp.time
        accel = sim.accel.copy()
        if lowpass:
            alpha = math.exp(-2 * math.pi * lowpass * dt)
            from scipy.signal import lfilter

            accel = lfilter([1 - alpha], [1, -alpha], accel - accel[0]) + accel[0]
        specific = (accel + G)[:, None] * up[None, :] * gain
        specific = specific + ar1_noise(rng, sigma, rho, specific.shape)
        force = np.asarray(sim.operating_force, dtype=float)
        if delay:
            force = np.interp(t - delay, t, force, left=force[0])
        force = force + rng.normal(0.0, force_noise, force.shape)
        if clip:
            mag = np.abs(specific)
            level = float(np.quantile(mag, 0.99))
            specific = np.clip(specific, -level, level)
            if k == 0:
                faults.append("clipped")
        keep = keep_mask(t.size, drop, rng)
        recs.append(
            Recording(
                name=f"Run #{k + 1}",
                time=t[keep],
                force=force[keep],
                accel=specific[keep],
                accel_includes_gravity=True,
                accel_axes=("x", "y", "z"),
                sample_rate_hz=rate,
            )
        )
    if drop:
        faults.append("dropouts")
    world = World(seed, truth, effect, effect_values, recording, layout, levels, rate, faults)
    world.sensor = {
        "sigma": sigma,
        "rho": rho,
        "force_noise": force_noise / u_med,
        "tilt": tilt,
    }
    return world, recs


@dataclass
class Outcome:
    world: World
    status: str  # trusted, untrusted, refused, traceback, hang
    seconds: float
    message: str = ""
    params: dict[str, dict] = field(default_factory=dict)
    #: ``diagnose``'s verdict and what it names (``--verdicts``), and whether it is right.
    verdict: str = ""
    named: list[str] = field(default_factory=list)
    verdict_right: bool | None = None


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout


#: The sensor faults the draw makes, by the name ``diagnose`` gives their explanation.
SENSOR_NAMES = {
    "gain": "gain",
    "delay": "channel timing",
    "lowpass": "low-pass",
    "clipped": "clipping",
}


def drawn_sensor_faults(world: World) -> set[str]:
    """The sensor faults drawn (by their explanations' names); coloured noise and
    drop-outs are no fault to name (the tool widens for one, bridges the other)."""
    return {
        name for key, name in SENSOR_NAMES.items() if any(f.startswith(key) for f in world.faults)
    }


def named_by(d: dict) -> list[str]:
    """What a diagnosis names: the effects and sensors of its best explanation, of both
    when it is ambiguous, and the clipping the reader found in the trials' motion."""
    exps = d.get("explanations") or []
    amb = d.get("ambiguity") or {}
    labels = [amb.get("best"), amb.get("runner_up")] if d.get("verdict") == "ambiguous" else []
    # the explanation the verdict is about: both of an ambiguity, else the best whose own
    # verdict is the diagnosis's (a gain and a zero offset fit alike; the verdict says which)
    same = [e for e in exps if e.get("verdict") == d.get("verdict")][:1]
    top = [e for lab in labels for e in exps if e.get("label") == lab][:2] or same or exps[:1]
    out: list[str] = []
    for e in top:
        out.extend(e.get("effects") or [])
        sensor = (e.get("detail") or {}).get("sensor")
        if sensor:
            out.append(str(sensor))
        out.extend(e.get("parameters") or [])
    if not exps:
        for sug in (d.get("suggestions") or [])[:1]:
            out.append(str(sug.get("effect")))
    fit_notes = (d.get("fit") or {}).get("notes") or d.get("notes") or []
    if any(
        n.get("code") == "read.sensor_limit" and n.get("severity") == "error" for n in fit_notes
    ):
        out.append("clipping")
    return out


def judge_verdict(world: World, verdict: str, named: list[str], covered: bool) -> bool:
    """Whether the verdict is right for the world.

    A drawn effect: ``effect missing`` (or ``ambiguous``) naming it first; a dead time
    also as its twin, the acceleration channel late (one log cannot tell them). A drawn
    sensor fault: ``sensor effect`` (or ``ambiguous``) naming one of the faults drawn.
    With both, either is right. Nothing drawn: ``adequate``. ``adequate`` is also right
    where the fault or effect left no trace, i.e. every trusted value's 95 % interval
    holds the truth (``covered``: below detection, and harmless).
    """
    sensors = drawn_sensor_faults(world)
    if not sensors and not world.effect:
        return verdict == "adequate"
    if verdict == "adequate":
        return covered
    right = False
    if world.effect and verdict in ("effect missing", "ambiguous") and named:
        right = named[0] == world.effect or (verdict == "ambiguous" and world.effect in named)
        if world.effect == "dead_time" and "channel timing" in named:
            right = True
    if sensors and verdict in ("sensor effect", "ambiguous", "effect missing"):
        right = right or bool(sensors & set(named))
    return right


def run_world(seed: int, folder: Path, timeout: float, verdicts: bool = False) -> Outcome:
    """Draw, write, fit one world; classify the outcome."""
    from balancer_id.errors import BalancerIdError
    from balancer_id.identify.api import fit

    world, recs = draw_world(seed)
    path = folder / f"world_{seed}.csv"
    delimiter = ";" if seed % 5 == 0 and world.layout != "phyphox" else ","
    decimal = "," if delimiter == ";" and world.layout == "generic" else "."
    if world.layout in ("phyphox", "generic") and len(recs) > 1:
        world.layout = "pasco-capstone"
    try:
        write_log(path, recs, world.layout, delimiter=delimiter, decimal=decimal)
    except TypeError:  # an older writer without those options
        write_log(path, recs, world.layout)
    start = time.perf_counter()
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(int(timeout))
    try:
        result = fit(str(path))
        doc = result.to_dict()
        status = "trusted" if doc.get("trusted", True) else "untrusted"
        why = "; ".join(doc.get("untrusted_because") or [])
        out = Outcome(world, status, time.perf_counter() - start, why, doc["parameters"])
        if verdicts:
            from balancer_id.diagnostics.api import diagnose

            d = diagnose(result).to_dict()
            d.setdefault("fit", {})["notes"] = doc.get("notes", [])
            out.verdict = str(d.get("verdict"))
            out.named = named_by(d)
            out.verdict_right = judge_verdict(world, out.verdict, out.named, covered(out))
            out.seconds = time.perf_counter() - start
        return out
    except _Timeout:
        return Outcome(world, "hang", time.perf_counter() - start)
    except BalancerIdError as exc:
        return Outcome(world, "refused", time.perf_counter() - start, str(exc)[:200])
    except Exception:
        return Outcome(world, "traceback", time.perf_counter() - start, traceback.format_exc())
    finally:
        signal.alarm(0)
        path.unlink(missing_ok=True)


def verdict_class(world: World) -> str:
    """``effect``, ``sensor`` (a sensor fault to name) or ``clean`` (neither)."""
    if world.effect:
        return "effect"
    return "sensor" if drawn_sensor_faults(world) else "clean"


def covered(o: Outcome) -> bool:
    """Whether every trusted fitted value's 95 % interval holds the truth."""
    for name in FITTED:
        p = o.params.get(name)
        if p is None or not p.get("vary") or not p.get("trusted", o.status == "trusted"):
            continue
        iv = interval(p, Z95)
        if iv is None or not iv[0] <= o.world.truth[name] <= iv[1]:
            return False
    return True


def interval(p: dict, z: float) -> tuple[float, float] | None:
    """The parameter's interval at normal quantile ``z`` (its 95 % one scaled)."""
    ci = p.get("ci95")
    value = p["value"]
    if p.get("not_reached") and ci:
        return (ci[0], math.inf) if p["not_reached"] == "above" else (-math.inf, ci[1])
    if ci is None:
        return None
    lo, hi = ci
    return value - (value - lo) * z / Z95, value + (hi - value) * z / Z95


def main() -> None:
    """Run the worlds and print the scores."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", type=int, default=100)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("-v", "--verbose", action="store_true")
    ap.add_argument(
        "--verdicts", action="store_true", help="also diagnose each world and score the verdict"
    )
    args = ap.parse_args()
    seed = args.seed if args.seed is not None else int.from_bytes(os.urandom(3), "little")
    print(f"seed {seed} ({args.worlds} worlds); repeat with --seed {seed}", flush=True)
    outcomes: list[Outcome] = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.worlds):
            o = run_world(seed * 1000 + k, Path(tmp), args.timeout, args.verdicts)
            outcomes.append(o)
            if args.verbose or o.status in ("traceback", "hang"):
                said = (
                    f" verdict {o.verdict} {o.named} right={o.verdict_right}" if o.verdict else ""
                )
                print(f"[{k}] {o.status} {o.seconds:.1f}s {o.world.describe()}{said}", flush=True)
                if o.message and (args.verbose or o.status == "traceback"):
                    print("    " + o.message.strip().replace("\n", "\n    ")[:1500], flush=True)
    report(outcomes)


def report(outcomes: list[Outcome]) -> None:
    """Print the scores."""
    n = len(outcomes)
    status = Counter(o.status for o in outcomes)
    print(f"\nworlds {n}: " + ", ".join(f"{k} {v}" for k, v in sorted(status.items())))
    secs = [o.seconds for o in outcomes]
    print(f"time per world: median {np.median(secs):.1f} s, max {max(secs):.1f} s")
    outside99 = total = 0
    cover: dict[str, list[bool]] = defaultdict(list)
    wrong_worlds = []
    by_kind: dict[str, Counter] = defaultdict(Counter)
    for o in outcomes:
        by_kind[o.world.kind][o.status] += 1
        if o.status not in ("trusted", "untrusted"):
            continue
        missed = []
        for name in FITTED:
            p = o.params.get(name)
            if p is None or not p.get("vary"):
                continue
            if not p.get("trusted", o.status == "trusted"):  # a per-parameter flag, or the fit's
                continue
            truth = o.world.truth[name]
            iv99 = interval(p, Z99)
            iv95 = interval(p, Z95)
            total += 1
            inside99 = iv99 is not None and iv99[0] <= truth <= iv99[1]
            outside99 += not inside99
            cover[name].append(iv95 is not None and iv95[0] <= truth <= iv95[1])
            if not inside99:
                missed.append(f"{name} {p['value']:.3g} vs {truth:.3g}")
        if missed:
            wrong_worlds.append((o, missed))
    print(
        f"trusted parameters outside their 99 % interval: {outside99}/{total} "
        f"({100 * outside99 / max(total, 1):.1f} %; target <= 2 %)"
    )
    for name in FITTED:
        c = cover[name]
        if c:
            share = 100 * np.mean(c)
            print(f"  95 % coverage of {name}: {share:.0f} % of {len(c)} (target >= 90 %)")
    print("outcome by world class (clean / sensor fault or coloured noise / effect missing):")
    for kind in ("clean", "sensor", "effect"):
        c = by_kind.get(kind, Counter())
        tot = sum(c.values())
        if tot:
            print(f"  {kind:7s} {tot:4d}: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))
    if wrong_worlds:
        print("trusted and wrong (world, parameters outside 99 %):")
        for o, missed in wrong_worlds[:25]:
            w = o.world
            print(f"  seed {w.seed}: {w.kind}: {w.describe()}: {'; '.join(missed)}")
    judged = [o for o in outcomes if o.verdict_right is not None]
    if judged:
        right = sum(bool(o.verdict_right) for o in judged)
        print(
            f"right verdict (diagnose): {right}/{len(judged)} "
            f"({100 * right / len(judged):.0f} %; target >= 90 %)"
        )
        for kind in ("clean", "sensor", "effect"):
            part = [o for o in judged if verdict_class(o.world) == kind]
            if part:
                ok = sum(bool(o.verdict_right) for o in part)
                print(f"  {kind:7s} {ok}/{len(part)}")
        wrong = [o for o in judged if not o.verdict_right]
        if wrong:
            print("wrong verdicts (first 15):")
            for o in wrong[:15]:
                print(f"  seed {o.world.seed}: {o.world.describe()}: {o.verdict} {o.named}")
    refused = [o for o in outcomes if o.status == "refused"]
    if refused:
        print("refusals (first 8):")
        for o in refused[:8]:
            print(f"  seed {o.world.seed}: {o.message[:160]}")


if __name__ == "__main__":
    main()
