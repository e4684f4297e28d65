"""Evaluation of the diagnosis (issue: diagnose): does it name the effect a model misses?

For every built-in effect but ``servo``, simulated logs of the paper's balancer (m_a,
T_a, D0, A varied by up to 20 % per case) with that effect hidden at three strengths,
two noise levels (0.02 and 0.05 m/s^2; force noise 0.03 N) and ``--seeds`` seeds. Six
runs (±2.45, ±4.9, ±7.35 N; 2 s rest + 8 s motion) are recorded by a sensor tilted
5-25 degrees (accelerometer including gravity), written in a reader layout (rotating
over pasco-capstone, pasco-sparkvue, phyphox, generic), read back with ``read_log`` and
segmented with ``find_trials``. The paper's model (``variable_viscosity``; ``viscous``
when ``variable_viscosity`` itself is hidden) is fitted from the paper method's start
values, as ``balancer-id fit`` does, and diagnosed. Recorded per case: whether the
hidden effect is suggested first (top-1) or among the first two (top-2), the verdict,
and the error above the noise floor before and after adding the top suggestion (its
quick refit), and, to tell a refit that stops short from an error too small for the
estimated noise floor to see, the same ratio measured above a fit of the true model
("oracle"). False alarms: logs with nothing hidden, fitted with the paper's model,
every noise level, seed and layout; the share with the verdict "effect missing".

Targets: top-1 >= 90 %, top-2 >= 98 %, false alarms <= 5 %, error above the noise floor
at least halved by the top suggestion (median after/before <= 0.5).

Run: ``python benchmarks/bench_diagnose.py [--seeds N] [--jobs N] [--quick]``. The first
run compiles the kernels of every candidate model (numba, cached under
``~/.cache/balancer-id``).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from diagnose_cases import HIDDEN, NOT_HERE, Case, build_cases, make_setup

from balancer_id.diagnostics.diagnosis import BIC_THRESHOLD, MIN_EXCESS_DROP, diagnose
from balancer_id.identify.classic import paper_method
from balancer_id.identify.matching import match_trials
from balancer_id.identify.result import fit_match
from balancer_id.model import parse_model

TARGET_TOP1 = 0.90
TARGET_TOP2 = 0.98
TARGET_FALSE_ALARMS = 0.05
TARGET_RATIO = 0.5
#: Fit and reader notes shown under a failing case.
MAX_NOTES = 3
#: Trials each case should yield (one per thrust).
EXPECTED_TRIALS = 6


@dataclass
class Outcome:
    """What the diagnosis made of one case.

    Attributes
    ----------
    case : Case
        The case.
    n_trials : int
        Trials found by the segmenter.
    tilt_deg : float
        Sensor tilt.
    suggested : list of tuple
        ``(effect, delta_bic, excess_drop)`` of every suggestion, best first.
    verdict : str
        ``"adequate"``, ``"effect missing"`` or ``"error"``.
    noise_floor : float
        Estimated white noise (m/s^2).
    excess_before, excess_after : float
        Error above the noise floor of the fit and of the top suggestion's refit (m/s^2).
    rmse_before, rmse_after : float
        RMS error of the fit and of the top suggestion's refit (m/s^2).
    rmse_true : float
        RMS error of the true model fitted from the true values: what a perfect refit
        reaches (NaN for false-alarm cases).
    seconds : float
        Wall time of the case.
    error : str
        The exception, when the case could not be run.
    notes : list of str
        Segmentation and fit warnings worth showing with a failure.
    """

    case: Case
    n_trials: int = 0
    tilt_deg: float = math.nan
    suggested: list[tuple[str, float, float]] = field(default_factory=list)
    verdict: str = "error"
    noise_floor: float = math.nan
    excess_before: float = math.nan
    excess_after: float = math.nan
    rmse_before: float = math.nan
    rmse_after: float = math.nan
    rmse_true: float = math.nan
    seconds: float = 0.0
    error: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def top1(self) -> bool:
        """The hidden effect is suggested first."""
        return bool(self.suggested) and self.suggested[0][0] == self.case.effect

    @property
    def top2(self) -> bool:
        """The hidden effect is among the first two suggestions."""
        return self.case.effect in [s[0] for s in self.suggested[:2]]

    @property
    def missing(self) -> bool:
        """The verdict says an effect is missing."""
        return self.verdict == "effect missing"

    @property
    def ratio(self) -> float:
        """Error above the noise floor after / before adding the top suggestion."""
        if not self.excess_before > 0:
            return math.nan
        return self.excess_after / self.excess_before

    @property
    def oracle_ratio(self) -> float:
        """After / before of the error above the true model's fit (no noise-floor estimate).

        ``sqrt(rmse^2 - rmse_true^2)`` of the refit over that of the fit: separates a refit
        that stops short of the truth from an error too small for the noise floor to see.
        """
        if math.isnan(self.rmse_true):
            return math.nan
        floor = min(self.rmse_true, self.rmse_after, self.rmse_before)
        before = math.sqrt(max(self.rmse_before**2 - floor**2, 0.0))
        after = math.sqrt(max(self.rmse_after**2 - floor**2, 0.0))
        return after / before if before > 0 else math.nan

    @property
    def true_excess(self) -> float:
        """Model error of the fit above the true model's fit (m/s^2)."""
        if math.isnan(self.rmse_true):
            return math.nan
        floor = min(self.rmse_true, self.rmse_before)
        return math.sqrt(max(self.rmse_before**2 - floor**2, 0.0))

    @property
    def vetoed(self) -> bool:
        """The top suggestion passes the BIC test but not the excess-drop test."""
        return (
            bool(self.suggested)
            and self.suggested[0][1] > BIC_THRESHOLD
            and not self.suggested[0][2] > MIN_EXCESS_DROP
        )

    @property
    def halved(self) -> bool:
        """The top suggestion at least halves the error above the noise floor."""
        return bool(self.ratio <= TARGET_RATIO)

    def problems(self) -> list[str]:
        """Why a hidden-effect case fails (empty when it passes)."""
        if self.error:
            return ["error"]
        out = []
        if not self.top1:
            out.append("top-1 miss" if self.top2 else "top-2 miss")
        if not self.missing:
            out.append("verdict adequate" + (" (excess-drop gate)" if self.vetoed else ""))
        if not self.halved:
            out.append("not halved")
        if self.n_trials != EXPECTED_TRIALS:
            out.append(f"{self.n_trials} trials")
        return out


def run_case(case: Case) -> Outcome:
    """Simulate, write, read, segment, fit and diagnose one case.

    Parameters
    ----------
    case : Case
        The case.

    Returns
    -------
    Outcome
        Never raises: an exception is recorded in ``error``.
    """
    t0 = time.perf_counter()
    out = Outcome(case)
    try:
        setup = make_setup(case)
        out.n_trials, out.tilt_deg = len(setup.trials), setup.tilt_deg
        out.notes.extend(setup.warnings)
        model = parse_model(case.hidden.fit_spec)
        classic = paper_method(setup.trials)
        match = match_trials(model, setup.trials, start=classic.start_values(model))
        out.notes.extend(match.warnings)
        diagnosis = diagnose(fit_match(match, classic=classic))
        ctx = diagnosis.context
        out.verdict = diagnosis.verdict
        out.noise_floor = ctx.noise_floor
        out.rmse_before = match.metrics["rmse"]
        out.excess_before = ctx.excess_rmse(out.rmse_before)
        out.suggested = [(s.effect, s.delta_bic, s.excess_drop) for s in diagnosis.suggestions]
        out.notes.extend(diagnosis.failures)
        best = diagnosis.suggestions[0] if diagnosis.suggestions else None
        if best is not None and best.refit is not None:
            out.rmse_after = best.refit.metrics["rmse"]
        else:
            out.rmse_after = out.rmse_before
        out.excess_after = ctx.excess_rmse(out.rmse_after)
        if case.effect != "none":
            truth = match_trials(
                parse_model(case.hidden.truth_spec), setup.trials, start=setup.truth
            )
            out.rmse_true = truth.metrics["rmse"]
    except Exception as exc:  # a benchmark reports every failure and goes on
        out.error = f"{type(exc).__name__}: {exc}"
    out.seconds = time.perf_counter() - t0
    return out


def run_all(cases: Sequence[Case], jobs: int) -> list[Outcome]:
    """Run the cases (in ``jobs`` processes) and return the outcomes in case order."""
    done: list[Outcome | None] = [None] * len(cases)
    t0 = time.perf_counter()

    def progress() -> None:
        """Report every tenth finished case on stderr."""
        n = sum(o is not None for o in done)
        if n % 10 == 0 or n == len(cases):
            print(f"  {n}/{len(cases)} cases, {time.perf_counter() - t0:.0f} s", file=sys.stderr)

    if jobs <= 1:
        for k, case in enumerate(cases):
            done[k] = run_case(case)
            progress()
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(run_case, case): k for k, case in enumerate(cases)}
            for fut in as_completed(futures):
                k = futures[fut]
                done[k] = fut.result()
                progress()
    return [o for o in done if o is not None]


def _pct(flags: Iterable[bool]) -> float:
    """Share of true flags in percent (NaN for none)."""
    x = list(flags)
    return 100.0 * sum(x) / len(x) if x else math.nan


def _median(values: Iterable[float]) -> float:
    """Median of the finite values (NaN for none)."""
    x = [v for v in values if np.isfinite(v)]
    return float(np.median(x)) if x else math.nan


@dataclass
class Row:
    """One line of a summary table."""

    label: str
    cases: int
    top1: float
    top2: float
    missing: float
    ratio: float
    halved: float
    oracle: float

    @classmethod
    def of(cls, label: str, outcomes: Sequence[Outcome]) -> Row:
        """Summarize ``outcomes`` under ``label``."""
        return cls(
            label,
            len(outcomes),
            _pct(o.top1 for o in outcomes),
            _pct(o.top2 for o in outcomes),
            _pct(o.missing for o in outcomes),
            _median(o.ratio for o in outcomes),
            _pct(o.halved for o in outcomes),
            _median(o.oracle_ratio for o in outcomes),
        )

    def cells(self) -> list[str]:
        """The row's cells as text."""
        return [
            self.label,
            str(self.cases),
            f"{self.top1:.0f}",
            f"{self.top2:.0f}",
            f"{self.missing:.0f}",
            f"{self.ratio:.2f}",
            f"{self.halved:.0f}",
            f"{self.oracle:.2f}",
        ]


HEADER = [
    "effect",
    "cases",
    "top-1 %",
    "top-2 %",
    "'missing' %",
    "median after/before",
    "halved %",
    "oracle after/before",
]


def text_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """Columns padded to their widest cell; the first left-aligned, the rest right."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(
            c.ljust(w) if i == 0 else c.rjust(w)
            for i, (c, w) in enumerate(zip(cells, widths, strict=True))
        )

    return "\n".join([line(header), line(["-" * w for w in widths]), *map(line, rows)])


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A GitHub markdown table."""
    lines = ["| " + " | ".join(header) + " |"]
    lines.append("|" + "|".join("---" if i == 0 else "---:" for i in range(len(header))) + "|")
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _group(
    outcomes: Sequence[Outcome], key: Callable[[Outcome], object]
) -> dict[object, list[Outcome]]:
    """Outcomes grouped by ``key``, in first-seen order."""
    groups: dict[object, list[Outcome]] = {}
    for o in outcomes:
        groups.setdefault(key(o), []).append(o)
    return groups


def effect_rows(hidden: Sequence[Outcome]) -> list[Row]:
    """One row per hidden effect and one for all of them."""
    by_effect = _group(hidden, lambda o: o.case.effect)
    rows = [Row.of(h.effect, by_effect[h.effect]) for h in HIDDEN if h.effect in by_effect]
    rows.append(Row.of("all", hidden))
    return rows


def detail_rows(hidden: Sequence[Outcome]) -> list[Row]:
    """One row per (effect, strength, noise)."""
    groups = _group(hidden, lambda o: (o.case.effect, o.case.strength, o.case.noise))
    return [
        Row.of(f"{e} [{items[0].case.strength_label}] noise {n:g}", items)
        for (e, _s, n), items in groups.items()
    ]


def _suggested(o: Outcome, n: int = 3) -> str:
    """The first ``n`` suggestions with their delta BIC and excess drop."""
    if not o.suggested:
        return "nothing"
    return "; ".join(f"{e} (dBIC {d:.0f}, drop {x:.0%})" for e, d, x in o.suggested[:n])


def failure_lines(hidden: Sequence[Outcome], null: Sequence[Outcome]) -> list[str]:
    """Every failing case, with what was suggested and the verdict."""
    lines = []
    for o in hidden:
        why = o.problems()
        if not why:
            continue
        c = o.case
        lines.append(
            f"[{', '.join(why)}] {c.effect} [{c.strength_label}] noise {c.noise:g} seed {c.seed} "
            f"{c.layout} (tilt {o.tilt_deg:.0f} deg, {o.n_trials} trials): "
            + (
                o.error
                if o.error
                else f"suggested {_suggested(o)}; verdict {o.verdict}; excess "
                f"{o.excess_before:.4f} -> {o.excess_after:.4f} m/s^2 "
                f"(floor {o.noise_floor:.4f}); above the true model's fit "
                f"{o.true_excess:.4f} m/s^2, oracle after/before {o.oracle_ratio:.2f}"
            )
        )
        lines += [f"      note: {n}" for n in o.notes[:MAX_NOTES]]
    for o in null:
        if not (o.missing or o.error or o.n_trials != EXPECTED_TRIALS):
            continue
        c = o.case
        why = "error" if o.error else "false alarm" if o.missing else f"{o.n_trials} trials"
        lines.append(
            f"[{why}] none noise {c.noise:g} seed {c.seed} {c.layout} "
            f"(tilt {o.tilt_deg:.0f} deg, {o.n_trials} trials): "
            + (
                o.error
                if o.error
                else f"suggested {_suggested(o)}; verdict {o.verdict}; excess "
                f"{o.excess_before:.4f} m/s^2 (floor {o.noise_floor:.4f})"
            )
        )
        lines += [f"      note: {n}" for n in o.notes[:MAX_NOTES]]
    return lines


def calibration_lines(hidden: Sequence[Outcome], null: Sequence[Outcome]) -> list[str]:
    """How close the verdict's two tests come to their thresholds."""
    vetoed = [o for o in hidden if o.vetoed and not o.missing]
    tops = [o.suggested[0] for o in null if o.suggested]
    lines = [
        f"hidden effects called 'adequate' although the top suggestion lowers BIC by more "
        f"than {BIC_THRESHOLD:g} (its excess drop <= {MIN_EXCESS_DROP:.0%}): "
        f"{len(vetoed)} of {sum(not o.missing for o in hidden)} 'adequate' verdicts",
    ]
    if tops:
        d_bic = np.array([t[1] for t in tops])
        drop = np.array([t[2] for t in tops])
        both = np.mean((d_bic > BIC_THRESHOLD) & (drop > MIN_EXCESS_DROP))
        lines.append(
            f"nothing hidden: top suggestion's delta BIC max {d_bic.max():.1f} (threshold "
            f"{BIC_THRESHOLD:g}), excess drop max {drop.max():.0%} (threshold "
            f"{MIN_EXCESS_DROP:.0%}); both passed in {both:.0%}"
        )
    lines.append(
        "columns: 'missing' % = verdict 'effect missing'; after/before = error above the "
        "estimated noise floor after/before adding the top suggestion (its quick refit); "
        "oracle after/before = the same above the true model's fit instead of the noise floor"
    )
    return lines


def _mark(ok: bool) -> str:
    """PASS or FAIL."""
    return "PASS" if ok else "FAIL"


def target_lines(hidden: Sequence[Outcome], null: Sequence[Outcome]) -> list[tuple[str, str]]:
    """(measure, value against its target) for the four targets."""
    top1 = _pct(o.top1 for o in hidden) / 100
    top2 = _pct(o.top2 for o in hidden) / 100
    fa = _pct(o.missing for o in null) / 100
    ratio = _median(o.ratio for o in hidden)
    halved = _pct(o.halved for o in hidden)
    return [
        ("top-1", f"{top1:.1%} (target >= {TARGET_TOP1:.0%}) {_mark(top1 >= TARGET_TOP1)}"),
        ("top-2", f"{top2:.1%} (target >= {TARGET_TOP2:.0%}) {_mark(top2 >= TARGET_TOP2)}"),
        (
            "false alarms",
            f"{fa:.1%} of {len(null)} (target <= {TARGET_FALSE_ALARMS:.0%}) "
            f"{_mark(fa <= TARGET_FALSE_ALARMS)}",
        ),
        (
            "error above noise floor",
            f"median after/before {ratio:.2f}, halved in {halved:.0f} % of cases "
            f"(target: at least halved, median <= {TARGET_RATIO}) {_mark(ratio <= TARGET_RATIO)}",
        ),
    ]


def report(hidden: Sequence[Outcome], null: Sequence[Outcome], args: argparse.Namespace) -> None:
    """Print the tables, the targets, the failing cases and the markdown summary."""
    for name, why in NOT_HERE.items():
        print(f"{name}: {why}")
    print()
    rows = effect_rows(hidden)
    print(text_table(HEADER, [r.cells() for r in rows]))
    print()
    print("by strength and noise:")
    print(text_table(HEADER, [r.cells() for r in detail_rows(hidden)]))
    print()
    floors = [o.noise_floor / o.case.noise for o in [*hidden, *null] if np.isfinite(o.noise_floor)]
    print(
        f"estimated noise floor / true noise: median {_median(floors):.3f}, "
        f"range {min(floors, default=math.nan):.3f}-{max(floors, default=math.nan):.3f}"
    )
    seconds = [o.seconds for o in [*hidden, *null]]
    print(f"time per case: median {_median(seconds):.1f} s, max {max(seconds):.1f} s")
    for line in calibration_lines(hidden, null):
        print(line)
    print()
    targets = target_lines(hidden, null)
    for name, text in targets:
        print(f"{name:>24}: {text}")
    print()
    failures = failure_lines(hidden, null)
    n_failing = sum(not line.startswith(" ") for line in failures)
    print(f"failing cases ({n_failing}; notes are the first fit's warnings):")
    for line in failures:
        print("  " + line)
    if not failures:
        print("  none")
    print()
    mode = "quick: one strength, one noise" if args.quick else "three strengths, two noise levels"
    print(f"markdown ({args.seeds} seeds, {mode}):")
    print()
    print(markdown_table(HEADER, [r.cells() for r in rows]))
    print()
    print(markdown_table(["target", "result"], [list(t) for t in targets]))


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the options, run every case and print the report.

    Parameters
    ----------
    argv : sequence of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 when every target is met, 1 otherwise.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3, help="seeds per effect/strength/noise")
    parser.add_argument(
        "--jobs", type=int, default=os.cpu_count() or 1, help="worker processes (default: all)"
    )
    parser.add_argument("--quick", action="store_true", help="one strength, one noise level")
    args = parser.parse_args(argv)
    hidden_cases, null_cases = build_cases(args.seeds, quick=args.quick)
    print(
        f"{len(hidden_cases)} hidden-effect cases, {len(null_cases)} false-alarm cases, "
        f"{args.jobs} job(s)",
        file=sys.stderr,
    )
    t0 = time.perf_counter()
    outcomes = run_all([*hidden_cases, *null_cases], args.jobs)
    hidden, null = outcomes[: len(hidden_cases)], outcomes[len(hidden_cases) :]
    print(f"ran in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    report(hidden, null, args)
    ok = (
        _pct(o.top1 for o in hidden) / 100 >= TARGET_TOP1
        and _pct(o.top2 for o in hidden) / 100 >= TARGET_TOP2
        and _pct(o.missing for o in null) / 100 <= TARGET_FALSE_ALARMS
        and _median(o.ratio for o in hidden) <= TARGET_RATIO
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
