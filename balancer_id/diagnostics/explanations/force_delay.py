"""The force channel's timing against the acceleration's: two clocks that disagree."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np

from balancer_id.diagnostics import arena
from balancer_id.diagnostics.explanations.base import (
    Explanation,
    ExplanationKind,
    Verdict,
    head,
)
from balancer_id.diagnostics.explanations.measured_output import corrected, fit_mapped
from balancer_id.notes import has_code

if TYPE_CHECKING:
    from balancer_id.diagnostics.arena import ArenaInput
    from balancer_id.identify.result import FitResult

#: Offsets searched (s): a wireless sensor's time stamp is late by tens of milliseconds.
MAX_DELAY_S = 0.25
#: Trials whose input has more breakpoints than this are driven by a measured force.
MEASURED_BREAKPOINTS = 3


class ForceDelay(ExplanationKind):
    """The force channel time-stamped ``d`` later than the acceleration (``d < 0``: the
    acceleration is the late one).

    A balancer is time-invariant: driven by the force ``d`` late, its response comes ``d``
    late as a whole, so the model's output shifted by ``d`` is the fit with the true
    timing (one parameter; the start from a scan of the shift at the current values).
    Proposed only where a measured force drives the trials. A force step must precede
    its response: with ``d > 0`` the acceleration moves before the force says it steps,
    which no balancer does. With ``d < 0`` a balancer's dead time fits alike: the
    recording cannot tell them apart (the ``dead_time`` effect is then its rival).
    Correction: ``--force-delay d`` and the refit.
    """

    key = "force_delay"
    kind = "sensor"
    verdict = Verdict.SENSOR_EFFECT
    stands_alone = True
    measurement = True
    tried = "the force channel's timing"
    mimics: ClassVar[str] = "a dead time of the balancer (when the acceleration is the late one)"
    separating_trial: ClassVar[str] = (
        "tap the load once with both sensors recording (or record both channels on one "
        "device's clock): the force and the acceleration must jump at the same instant; "
        "a later jump of the acceleration is then the balancer's dead time"
    )

    def propose(self, inp: ArenaInput) -> list[Explanation]:
        """The shift of the model's output between the channels, fitted."""
        driven = [len(td.input.thrust.times) > MEASURED_BREAKPOINTS for td in inp.trials]
        if not inp.trials or sum(driven) < max(1, len(driven) // 2):
            return []
        times = [np.asarray(td.time, dtype=float) for td in inp.trials]
        dt = float(np.median([np.median(np.diff(t)) for t in times if t.size > 1]))
        # a session's trials shifted as one record: the step that starts a continuing
        # trial is seen with what came just before it
        chains = arena.session_chains(inp.trials)
        joined = {c[0]: np.concatenate([times[j] for j in c]) for c in chains}

        def shifted(i: int, y: np.ndarray, d: float) -> np.ndarray:
            t = joined[i]
            return np.interp(t + d, t, y) if t.size == y.size else y

        d0 = _scan(inp, shifted, dt, chains)
        fit = fit_mapped(inp, shifted, d0, -MAX_DELAY_S, MAX_DELAY_S, chains=chains)
        d, se = fit.param, fit.stderr
        late = "force" if d > 0 else "acceleration"
        lead = inp.match.metrics.get("timing_lead_s")
        lead_se = inp.match.metrics.get("timing_lead_stderr_s")
        shift = self.make(
            f"{late} channel {abs(d) * 1e3:.0f} ms late",
            fit.delta_bic,
            fit.rmse,
            detail={
                "sensor": "channel timing",
                "force_delay_s": d,
                "force_delay_stderr_s": se,
                "late_channel": late,
                "sample_interval_s": dt,
                "values": fit.values,
                "fit_timing_clear": _timing_called(inp),
                "fit_lead_s": lead,
                "fit_lead_stderr_s": lead_se,
            },
            null=abs(d) < 0.5 * dt,
        )
        return [shift, *_dead_time_twin(inp, shift)]

    def valid(self, e: Explanation, tests_failed: bool, threshold: float, min_drop: float) -> bool:
        """By BIC as any explanation, or, for a late force channel that the fit's own
        timing test found (``fit.timing``, the same lateness within 3 standard errors),
        by :data:`~balancer_id.diagnostics.arena.CLOSE_BIC`.

        The arena's threshold guards against the best of many explanations tried rising
        by chance; the timing test is one test fixed in advance, called at 3 standard
        errors (a false alarm in 0.3 % of on-time logs), and an acceleration that moves
        before its force has no twin in the balancer (no balancer answers before it is
        pushed). Its refit need then only be positive evidence, and remove some of the
        error above the noise floor, not a tenth (a noisy force drive leaves error no
        timing removes): a 25 ms late force at 50 Hz gained 24 BIC and 9 % of the
        excess, and the verdict was "effect missing", naming a bias.
        """
        if super().valid(e, tests_failed, threshold, min_drop):
            return True
        d = float(e.detail.get("force_delay_s", 0.0))  # type: ignore[arg-type]
        lead = e.detail.get("fit_lead_s")
        lead_se = e.detail.get("fit_lead_stderr_s")
        se = e.detail.get("force_delay_stderr_s")
        if e.null or d <= 0 or not e.detail.get("fit_timing_clear"):
            return False
        if not (isinstance(lead, float) and isinstance(lead_se, float) and lead > 0):
            return False
        spread = float(np.hypot(lead_se, se if isinstance(se, float) else 0.0))
        dt = float(e.detail.get("sample_interval_s", 0.0))  # type: ignore[arg-type]
        agree = abs(d - lead) <= 3.0 * spread + dt
        return agree and e.delta_bic > arena.CLOSE_BIC and e.excess_drop > 0

    def twin(self, e: Explanation, other: Explanation) -> bool:
        """A late acceleration and the balancer's ``dead_time`` of about the same length."""
        d = float(e.detail.get("force_delay_s", 0.0))  # type: ignore[arg-type]
        values: dict[str, float] = other.detail.get("values") or {}  # type: ignore[assignment]
        tau = values.get("tau_d")
        if d >= 0 or other.effects != ["dead_time"] or tau is None:
            return False
        dt = float(e.detail.get("sample_interval_s", 0.0))  # type: ignore[arg-type]
        se = e.detail.get("force_delay_stderr_s")
        tol = max(2.0 * dt, 3.0 * se if isinstance(se, float) else 0.0, 0.25 * abs(d))
        return abs(float(tau) + d) <= tol

    def sentence(self, e: Explanation, fit: FitResult) -> str:
        """The offset, its interval, which channel is late, the correction and the refit."""
        d = float(e.detail["force_delay_s"])  # type: ignore[arg-type]
        se = e.detail.get("force_delay_stderr_s")
        ms = f"{abs(d) * 1e3:.0f} ms" + (
            f" (95 % interval {(abs(d) - 1.96 * se) * 1e3:.0f}-{(abs(d) + 1.96 * se) * 1e3:.0f} ms)"
            if isinstance(se, float)
            else ""
        )
        why = (
            "the acceleration moves before the force says it steps, and a force step must "
            "precede its response: the force channel's time stamps are late (a wireless "
            "sensor, two devices' clocks), not the balancer"
            if d > 0
            else "the acceleration answers late: the acceleration channel's time stamps are "
            "late, or the balancer acts with a dead time (both delay the response alike)"
        )
        return (
            f"the {e.detail['late_channel']} channel runs {ms} behind the other: {why}; "
            f"{head(e)}; {corrected(e, fit)}. Correct the timing and refit: "
            f"{fit.command()} --force-delay {d:.3f}"
        )


def _dead_time_twin(inp: ArenaInput, shift: Explanation) -> list[Explanation]:
    """The balancer's dead time read from a late acceleration's fit, where the library's
    own ``+dead_time`` refit did not reach it.

    A balancer is time-invariant: its response to a drive ``tau`` late is its response
    moved ``tau`` later, so the late acceleration's fit is also the fit of a dead time
    ``tau = -d`` (the same residual, one parameter more than the model, as the shift).
    The library's refit starts from the current values and can stop in another basin
    (an up-then-down log with a 72 ms dead time: its refit 2,100 BIC worse than the model
    without it, while the shift gained 83): the verdict then named the sensor alone,
    though no log of this kind tells the two apart. Offered only where that refit falls
    more than :data:`~balancer_id.diagnostics.arena.CLOSE_BIC` short of the shift.
    """
    d = float(shift.detail.get("force_delay_s", 0.0))  # type: ignore[arg-type]
    model = inp.match.model
    if d >= 0 or shift.null or "dead_time" in {e.name for e in model.effects}:
        return []
    if not any(e.name == "dead_time" for e in model.registry):
        return []
    for name, own in inp.effect_fits:
        if name == "dead_time":
            r = own.residual
            d_own, _ = arena.score(inp, [r[sl] for sl in own.data.slices()], 1)
            if d_own >= shift.delta_bic - arena.CLOSE_BIC:
                return []  # the library's refit reached it: it speaks for itself
    from balancer_id.diagnostics.explanations.effect import LibraryEffect

    values = dict(shift.detail.get("values") or {})  # type: ignore[call-overload]
    values["tau_d"] = -d
    return [
        LibraryEffect().make(
            f"+dead_time {-d * 1e3:.0f} ms",
            shift.delta_bic,
            shift.rmse,
            effects=["dead_time"],
            detail={"values": values, "twin_of": shift.label},
        )
    ]


def _timing_called(inp: ArenaInput) -> bool:
    """Whether the fit's own timing test called a lead or lag (its ``fit.timing`` note)."""
    notes = [*inp.match.warnings, *(inp.fit.warnings if inp.fit is not None else ())]
    return has_code(notes, "fit.timing")


def _scan(inp: ArenaInput, shifted: object, dt: float, chains: list[list[int]]) -> float:
    """The shift that best matches the current fit's output to the data (a start); the
    outputs joined by session chain, as ``shifted`` takes them."""
    sims = arena.Trials(inp.trials)
    values = inp.match.values()
    pvec = np.array([values[n] for n in inp.match.model.param_names])
    each = sims.outputs(inp.match.model, [pvec] * len(inp.trials))
    outs = [np.concatenate([each[j] for j in c]) for c in chains]
    ys = [np.concatenate([np.asarray(sims.data[j].y, dtype=float) for j in c]) for c in chains]
    heads = [c[0] for c in chains]
    grid = np.arange(-MAX_DELAY_S, MAX_DELAY_S + 1e-12, max(dt / 2, 0.001))
    pairs = list(zip(ys, outs, strict=True))
    cost = []
    for g in grid:
        total = 0.0
        for i, (y, o) in zip(heads, pairs, strict=True):
            total += float(np.sum((y - shifted(i, o, float(g))) ** 2))  # type: ignore[operator]
        cost.append(total)
    return float(grid[int(np.nanargmin(cost))])
