"""The result of an identification: it owns its data; rendering lives in ``report``.

A :class:`FitResult` records what it was computed from (the :class:`~balancer_id.trials.
TrialSet`, the values held fixed, the user effect files), so what comes after it (the
diagnosis, improve, the reports) reuses its paper's method and per-trial fits instead of
computing them again, and a command that reproduces it is derived from it.
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping, Sequence
from dataclasses import FrozenInstanceError, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from balancer_id.identify.advice import viscosity_factor
from balancer_id.identify.classic import ClassicResult, paper_method
from balancer_id.identify.coupling import Coupling, coupling_of
from balancer_id.identify.display import Displayable
from balancer_id.identify.matching import MatchResult
from balancer_id.identify.per_trial import PerTrialFit, fit_each_trial
from balancer_id.jsonsafe import json_ready
from balancer_id.model.spec import Model
from balancer_id.notes import Note, as_note, notes_json, texts
from balancer_id.records import FitRecord, FrozenDict, ReadsBack
from balancer_id.simulation.engine import TrialInput
from balancer_id.trials import TrialSet

#: ``error`` notes about some parameters only: each names those it moves in their own
#: ``distrust``, and the others keep their trust (the drive's timing, a rival model).
PARAMETER_NOTES = ("fit.timing", "fit.rival")

if TYPE_CHECKING:
    from balancer_id.identify.advice import Advice
    from balancer_id.identify.posterior import Posterior
    from balancer_id.identify.servo_delay import ServoDelay

__all__ = ["FitResult", "PerTrialFit", "fit_match", "robot_coupling"]


@dataclass(repr=False)
class FitResult(Displayable, ReadsBack):
    """Everything ``balancer-id fit`` reports, and what it was computed from.

    Attributes
    ----------
    match : MatchResult
        The simulation-matching fit over all trials.
    classic : ClassicResult
        The paper's method (it depends on the trials only, so every model of the same
        trials shares it).
    trial_set : TrialSet
        The trials fitted, the logs they came from, the reading options and the
        reference move.
    fixed : Mapping of str to float
        Parameters held at known values (``--fix``).
    effects_files : tuple of str
        User effect files the model was resolved with (``--effects-file``).
    coupling : Coupling or None
        Robot-balancer loop figures when the model needs a reference move (``servo``).
    per_trial : tuple of PerTrialFit
        Per-trial refits, once computed (:meth:`per_trial_fits`).
    include_per_trial : bool
        Whether :meth:`to_dict` shows :attr:`per_trial` (``--per-trial``).
    tracking : Tracking or None
        Parameters tracked in time within the session (``fit --track``, issue 33).
    warnings : tuple of Note
        What the user should know from the identification around the fit (the start,
        the move start, the profile intervals); strings given become ``fit.other`` notes.
        The fit's own notes are in ``match.warnings``; :attr:`all_notes` holds both.
    posterior : Posterior or None
        Posterior samples of the free parameters (``fit(..., posterior=True)``,
        ``fit --posterior``); the band is then drawn from them.

    Notes
    -----
    A result is complete when returned (:func:`~balancer_id.identify.api.fit` and
    :func:`fit_match` compute the notes and the per-trial fits before returning it) and
    immutable afterwards: setting any field raises :class:`dataclasses.FrozenInstanceError`,
    its tables and lists are read-only (:class:`~balancer_id.records.FrozenDict`,
    tuples) and its match is sealed (:meth:`~balancer_id.identify.matching.MatchResult.seal`).
    What follows from it alone is derived on first use and cached: the per-trial fits of
    a result made without them (:meth:`per_trial_fits`) and a robot pair's settings
    advice (:attr:`advice`).
    """

    match: MatchResult
    classic: ClassicResult
    trial_set: TrialSet = field(default_factory=TrialSet)
    fixed: Mapping[str, float] = field(default_factory=dict)
    effects_files: Sequence[str] = ()
    coupling: Coupling | None = None
    per_trial: Sequence[PerTrialFit] = ()
    include_per_trial: bool = False
    warnings: Sequence[Note | str] = ()
    tracking: Any = None
    posterior: Posterior | None = None
    _per_trial_done: bool = field(default=False, init=False, repr=False)
    _advice: Any = field(default=None, init=False, repr=False, compare=False)
    _servo_delay: Any = field(default=None, init=False, repr=False, compare=False)
    _frozen: bool = field(default=False, init=False, repr=False, compare=False)
    #: What the JSON reads back as (:meth:`from_dict`).
    record: ClassVar[type[FitRecord]] = FitRecord

    def __post_init__(self) -> None:
        # complete when made: the tables and lists read-only, the match sealed
        self.fixed = FrozenDict(self.fixed)
        self.effects_files = tuple(self.effects_files)
        self.per_trial = tuple(self.per_trial)
        self.warnings = tuple(as_note(w) for w in self.warnings)
        self.match.seal()
        self._frozen = True

    def __setattr__(self, name: str, value: Any) -> None:
        if getattr(self, "_frozen", False):
            raise FrozenInstanceError(f"a FitResult is complete when returned; cannot set {name}")
        object.__setattr__(self, name, value)

    def _shown_match(self) -> MatchResult:
        return self.match

    def _headline(self) -> str:
        values = ", ".join(f"{k}={v:.4g}" for k, v in list(self.values.items())[:4])
        more = ", ..." if len(self.values) > 4 else ""
        n = len(self.match.data.trials)
        fit = self.metrics.get("nrmse_fit_percent", float("nan"))
        return f"{self.model}: {values}{more}; fit {fit:.1f} % over {n} trials"

    def _summary_warnings(self) -> list[str]:
        return texts(self.all_notes)

    def _band_samples(self) -> dict[str, Any]:
        if self.posterior is None:
            return {}
        return {"samples": self.posterior.samples, "sample_names": self.posterior.names}

    def _summary_extra(self) -> list[str]:
        lines = self.tracking.lines() if self.tracking is not None else []
        if self.posterior is not None:
            lines += self.posterior.lines()
        return lines

    @property
    def all_notes(self) -> list[Note | str]:
        """The fit's notes, those that make it untrusted first (then in order)."""
        # the trials' warnings (a given thrust sign the motion disagrees with) come along
        notes = [*self.warnings, *self.match.warnings, *self.trial_set.trial_notes()]
        first = [n for n in notes if isinstance(n, Note) and n.severity == "error"]
        return [*first, *(n for n in notes if n not in first)]

    @property
    def trusted(self) -> bool:
        """False when a note says the fit cannot be trusted (a bound the data did not
        choose, starts that disagree, a parameter the data cannot determine, a fit below
        0 %): the values are then no identification."""
        return not self.untrusted_because

    @property
    def untrusted_because(self) -> list[str]:
        """Why the fit is not trusted: the texts of its ``error`` notes, then a late robot
        servo that moves fitted values (empty: trusted)."""
        why = [n.text for n in self.all_notes if isinstance(n, Note) and n.severity == "error"]
        late = self.servo_delay_distrust()
        if late:
            why.append(next(iter(late.values())))
        return why

    def servo_delay_distrust(self) -> dict[str, str]:
        """The fitted values a late robot servo moves beyond their standard error, each
        with why it is not trusted (issue 31: a servo 30 ms late read as a 36 % stiffer
        one, k_r 204 +- 0.5 N/m against 150, trusted, while the delay was named beside it).

        Empty without a robot, or where the servo's delay is ruled out.
        """
        late = self.servo_delay if self.coupling is not None else None
        delayed = late.delayed_values if late is not None and late.use_delay else None
        if late is None or not delayed:
            return {}
        moved = []
        for name, est in self.match.parameters.items():
            if not est.vary or name not in delayed or not est.stderr:
                continue
            if abs(float(delayed[name]) - est.value) > est.stderr:
                moved.append(name)
        if not moved:
            return {}
        ms = f"{1e3 * late.tau_r:.0f} ms " if late.tau_r else ""
        said = "acts late" if late.named else "may act late (not ruled out)"
        text = (
            f"the robot's servo {said} ({ms}servo delay): with the delay, "
            + ", ".join(f"{n} = {float(delayed[n]):.4g}" for n in moved)
            + " (a servo acting at once reads "
            + ", ".join(f"{n} = {self.match.parameters[n].value:.4g}" for n in moved)
            + "), so those values are not trusted; see 'servo delay' below"
        )
        return dict.fromkeys(moved, text)

    def parameter_distrust(self) -> dict[str, list[str]]:
        """Why each fitted parameter is not trusted (empty list: trusted).

        A parameter loses its trust by an ``error`` note (a bound the data did not
        choose, starts that disagree, a structured residual, a parameter the data cannot
        determine: the others trade with it, so none is trusted), or by a check that
        moves it beyond its standard error (its own ``distrust``, e.g. the drive's
        timing, ``fit.timing``). So a fit can
        be trusted for ``m_a`` and not for ``A``; the fit is trusted when every fitted
        parameter is and no note says otherwise.
        """
        errors = [n for n in self.all_notes if isinstance(n, Note) and n.severity == "error"]
        whole = [n.text for n in errors if n.code not in PARAMETER_NOTES]
        late = self.servo_delay_distrust()
        out: dict[str, list[str]] = {}
        for name, est in self.match.parameters.items():
            if not est.vary:
                continue
            out[name] = [*whole, *est.distrust, *([late[name]] if name in late else [])]
        return out

    @property
    def stuck(self) -> bool:
        """Whether a parameter ended on a bound the data did not choose, or the starts
        ended at different optima: the fit's point itself is no optimum to build on."""
        return any(
            isinstance(n, Note)
            and n.severity == "error"
            and n.code in ("fit.at_bound", "fit.starts_disagree")
            for n in self.all_notes
        )

    @property
    def model(self) -> str:
        """The model's spec."""
        return self.match.model.spec

    @property
    def spec_model(self) -> Model:
        """The fitted :class:`~balancer_id.model.spec.Model`."""
        return self.match.model

    @property
    def sources(self) -> list[str]:
        """The logs fitted."""
        return self.trial_set.paths

    @property
    def values(self) -> dict[str, float]:
        """Fitted parameter values by name."""
        return self.match.values()

    @property
    def metrics(self) -> dict[str, float]:
        """CONTRACT.md error figures."""
        return self.match.metrics

    def held(self, model: Model | None = None) -> dict[str, float]:
        """The fixed values that apply to ``model`` (default: this fit's model).

        Parameters
        ----------
        model : Model, optional
            A model of the same trials (a candidate one effect away).

        Returns
        -------
        dict of str to float
            The entries of :attr:`fixed` that name a parameter of ``model``.
        """
        names = (model or self.match.model).param_names
        return {k: v for k, v in self.fixed.items() if k in names}

    @property
    def params(self) -> Any:
        """The fit as ``lmfit.Parameters``: value, stderr, bounds, vary and correlations.

        "Parameters in, Parameters out": :func:`~balancer_id.identify.api.fit` takes
        them back (``params=``) as starts, held values and bounds.

        Returns
        -------
        lmfit.Parameters
        """
        import lmfit

        out = lmfit.Parameters()
        model = self.match.model
        for name, est in self.match.parameters.items():
            spec = model.param(name)
            out.add(name, value=est.value, min=spec.min, max=spec.max, vary=est.vary)
            out[name].stderr = est.stderr
        for name, row in (self.match.correlations or {}).items():
            if name in out:
                out[name].correl = {k: v for k, v in row.items() if k != name}
        return out

    @property
    def advice(self) -> Advice | None:
        """Settings that damp the robot-balancer mode (paper section IV), checked by
        simulation; None for a model without a robot (no ``servo``).

        Derived from the fit alone, once, on first use (it simulates the moves).
        """
        if self.coupling is None:
            return None
        if self._advice is None:
            from balancer_id.identify.advice import advise_fit

            moves = [t.input for t in self.match.data.trials]
            late = self.servo_delay
            if late is not None and late.use_delay and late.delayed_values is not None:
                # checked on the loop of the late servo, over the delay's interval
                tau = float(late.tau_r or 0.0)
                lo, hi = late.interval or (tau, tau)
                values = {k: late.delayed_values.get(k, v) for k, v in self.values.items()}
                delays = (tau, float(lo), float(hi))
                rival = late.rival_values  # ambiguous: the advice must hold on it too
                also = [{k: rival.get(k, v) for k, v in self.values.items()}] if rival else []
                advice = advise_fit(self.match.model, values, moves, delays=delays, also=also)
            else:
                share = self.coupling.viscosity_factor  # simulated once, for the coupling
                # no delay named, but one up to the interval's end is not ruled out: the
                # promise must hold over it too
                hi = late.interval[1] if late is not None and late.interval else 0.0
                advice = advise_fit(
                    self.match.model, self.values, moves, today=share,
                    delays=(0.0, 0.0, float(hi)) if hi > 0 else (),
                )  # fmt: skip
            object.__setattr__(self, "_advice", advice)  # a cache, not a change
        return self._advice

    @property
    def servo_delay(self) -> ServoDelay | None:
        """Whether the robot's servo acts late (issue 31): the delay as an explanation
        of the log beside a stiffer servo and a sensor's lag; None without a robot.

        Derived from the fit alone, once, on first use.
        """
        if self.coupling is None:
            return None
        if self._servo_delay is None:
            from balancer_id.identify.servo_delay import ServoDelay as ServoDelayResult
            from balancer_id.identify.servo_delay import (
                examine_servo_delay,
                move_forces,
                move_references,
            )

            free = [n for n, e in self.match.parameters.items() if e.vary]
            trials = self.match.data.trials
            sources = [*self.trial_set.trials, *self.trial_set.loose]
            try:
                found = examine_servo_delay(
                    self.match.model, self.values, free, trials, move_forces(trials, sources),
                    references=move_references(trials, sources),
                )  # fmt: skip
            except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
                # a numerical failure of the delayed fits leaves the fit itself standing
                found = ServoDelayResult(
                    False, "not_examined", why=f"the delayed fits failed ({exc})"
                )
            object.__setattr__(self, "_servo_delay", found)  # a cache, not a change
        return self._servo_delay

    def per_trial_fits(self) -> Sequence[PerTrialFit]:
        """Each trial fitted alone from the joint fit; computed once, then reused.

        Returns
        -------
        tuple of PerTrialFit
            One per trial whose fit succeeded.
        """
        if not self._per_trial_done:
            fits = fit_each_trial(
                self.match.model, self.match.data.trials, self.values, self.fixed or None
            )
            object.__setattr__(self, "per_trial", tuple(fits))  # a cache, not a change
            object.__setattr__(self, "_per_trial_done", True)
        return self.per_trial

    def command(self, model: str | Model | None = None, subcommand: str = "fit") -> str:
        """The shell command that reproduces this fit, or a fit of another model.

        Parameters
        ----------
        model : str or Model, optional
            The model to fit instead of this fit's (a suggestion's model); with a
            :class:`~balancer_id.model.spec.Model` only the fixed values it has are kept.
        subcommand : str
            ``fit``, ``diagnose``, ``improve`` or ``report``.

        Returns
        -------
        str
            ``balancer-id SUBCOMMAND LOGS... --model SPEC`` with every ``--fix``,
            ``--effects-file``, reading option and ``--trajectory`` the fit was made with,
            quoted for a POSIX shell.
        """
        if isinstance(model, Model):
            spec, fixed = model.spec, self.held(model)
        else:
            spec, fixed = model or self.model, dict(self.fixed)
        args = ["balancer-id", subcommand, *self.sources]
        args += ["--start" if subcommand == "improve" else "--model", spec]
        for name, value in fixed.items():
            args += ["--fix", f"{name}={value!r}"]
        for path in self.effects_files:
            args += ["--effects-file", path]
        args += self.trial_set.option_args()
        return shlex.join(args)

    def sampling_notes(self) -> list[str]:
        """At which rate the trials were fitted, when any was decimated (one line per rate).

        Returns
        -------
        list of str
            E.g. ``"3 trials fitted at 250 Hz, decimated from 1000 Hz (factor 4)"``; empty
            when every trial was fitted at its log's own rate.
        """
        groups: dict[tuple[float, float, int], int] = {}
        for td in self.match.data.trials:
            d = td.decimation
            if d is not None:
                key = (round(d.rate_in_hz, 6), round(d.rate_out_hz, 6), d.factor)
                groups[key] = groups.get(key, 0) + 1
        return [
            f"{n} trial{'s' if n > 1 else ''} fitted at {out:.4g} Hz, decimated from "
            f"{rate:.4g} Hz (factor {q}, anti-aliased)"
            for (rate, out, q), n in groups.items()
        ]

    def _parameters_json(self) -> dict[str, dict[str, object]]:
        """Each parameter's JSON, with its own ``trusted`` and ``untrusted_because``
        (fitted ones; a held value is neither)."""
        distrust = self.parameter_distrust()
        out = {}
        for name, p in self.match.parameters.items():
            d = p.to_dict()
            if name in distrust:
                d["trusted"] = not distrust[name]
                d["untrusted_because"] = distrust[name]
            out[name] = d
        return out

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``fit`` JSON object (plus details)."""
        trials = []
        for td, rmse in zip(self.match.data.trials, self.match.trial_rmse, strict=True):
            trials.append(
                {
                    "index": td.index,
                    "thrust_N": td.thrust_N,
                    "direction": td.direction,
                    "rmse": rmse,
                    "source": td.source,
                    "fit_rate_hz": td.rate_hz,
                    "decimated_from_hz": td.decimation.rate_in_hz if td.decimation else None,
                }
            )
        sampling = [Note("fit.decimated", t, severity="info") for t in self.sampling_notes()]
        out: dict[str, object] = {
            "model": self.model,
            "files": self.sources,
            "parameters": self._parameters_json(),
            "correlations": self.match.correlations,
            "classic": self.classic.to_dict(),
            "trials": trials,
            "metrics": self.metrics,
            "converged": self.match.success,
            "optimizer_message": self.match.message,
            "warnings": texts(self.all_notes),
            "notes": notes_json([*self.all_notes, *sampling]),
            "trusted": self.trusted,
            "untrusted_because": self.untrusted_because,
            "optima": [o.to_dict() for o in self.match.optima],
        }
        if self.coupling is not None:
            out["coupling"] = self.coupling.to_dict()
            out["advice"] = self.advice.to_dict() if self.advice is not None else None
            late = self.servo_delay
            out["servo_delay"] = late.to_dict() if late is not None else None
        if self.include_per_trial and self.per_trial:
            out["per_trial"] = [p.to_dict() for p in self.per_trial]
        if self.tracking is not None:
            out["tracking"] = self.tracking.to_dict()
        if self.posterior is not None:
            out["posterior"] = self.posterior.to_dict()
        out["band"] = self.band_summary()
        return json_ready(out)

    def band_summary(self) -> dict[str, object] | None:
        """The ``band`` object of the JSON (:func:`~balancer_id.identify.band.band_summary`):
        the 95 % band's median half-width per trial and the share of the measured samples
        outside the band widened by the noise; None when the band cannot be drawn.

        Returns
        -------
        dict or None
        """
        from balancer_id.identify.band import band_summary

        try:
            band = self.band()
        except (ValueError, FloatingPointError, np.linalg.LinAlgError):
            return None
        return band_summary(band, self.match.y)


def robot_coupling(
    model: Model, values: Mapping[str, float], moves: Sequence[TrialInput] = ()
) -> Coupling | None:
    """Robot-balancer loop figures of a fitted model that needs a reference move.

    Parameters
    ----------
    model : Model
        The fitted model.
    values : mapping of str to float
        Its fitted values.
    moves : sequence of TrialInput
        The fitted moves: with a variable viscosity the loop is linearized at the
        settling's effective viscosity after the first (the same damping ratio the
        advice starts from).

    Returns
    -------
    Coupling or None
        None when the model needs no reference move (no robot in the loop); else
        :func:`~balancer_id.identify.coupling.coupling_of` of the values.
    """
    if not model.needs_reference_move:
        return None
    share = viscosity_factor(model, values, moves[0]) if moves else 1.0
    return coupling_of(dict(values), viscosity_factor=share)


def fit_match(
    match: MatchResult,
    trials: TrialSet | None = None,
    *,
    classic: ClassicResult | None = None,
    fixed: Mapping[str, float] | None = None,
    effects_files: Sequence[str | Path] = (),
    warnings: Sequence[Note | str] = (),
    per_trial: bool = False,
    tracking: Any = None,
    posterior: Posterior | None = None,
) -> FitResult:
    """A :class:`FitResult` around a ready simulation-matching fit.

    Used for the refits of the diagnosis and improve (they share the trials, the paper's
    method and the fixed values of the fit they came from) and for fits made with
    :func:`~balancer_id.identify.matching.match_trials` directly.

    Parameters
    ----------
    match : MatchResult
        The fit.
    trials : TrialSet, optional
        Where its trials came from; None: an empty set (no logs to name).
    classic : ClassicResult, optional
        The paper's method on the same trials; None computes it.
    fixed : mapping of str to float, optional
        Values held in the fit (kept for the refits and the printed commands).
    effects_files : sequence of str or Path
        User effect files the model was resolved with.
    warnings : sequence of Note or str
        Notes of the identification around the fit (a string becomes ``fit.other``).
    per_trial : bool
        Fit each trial alone now and show the fits in :meth:`FitResult.to_dict`.
    tracking : Tracking, optional
        Parameters tracked in time (``fit --track``).
    posterior : Posterior, optional
        Posterior samples of the fit (:func:`~balancer_id.identify.posterior.sample_posterior`).

    Returns
    -------
    FitResult
        Complete: nothing is set on it afterwards.
    """
    result = FitResult(
        match=match,
        classic=classic if classic is not None else paper_method(match.data.trials),
        trial_set=trials if trials is not None else TrialSet(),
        fixed=dict(fixed or {}),
        effects_files=[str(f) for f in effects_files],
        coupling=robot_coupling(match.model, match.values(), [t.input for t in match.data.trials]),
        include_per_trial=per_trial,
        warnings=list(warnings),
        tracking=tracking,
        posterior=posterior,
    )
    if per_trial:
        result.per_trial_fits()
    return result
