"""A fit of logs as one library call: ``balancer-id fit`` is :meth:`FitJob.run`.

Everything the command does beyond parsing lives here, so a script gets it too: the held
values of an earlier fit (``params``), the checks of option combinations, the result
cache (keyed by the whole request, :class:`~balancer_id.workflows.request.FitRequest`),
the fit of each group (``group_by``), and the report, series and JSON written.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from balancer_id import cache
from balancer_id.arguments import at_least, trajectory
from balancer_id.errors import UsageError
from balancer_id.files import atomic_write_text, check_outputs, inputs_of
from balancer_id.records import FitRecord, ResultRecord
from balancer_id.status import tell
from balancer_id.trials import load_trials
from balancer_id.workflows.request import FitRequest

__all__ = ["MAX_STARTS", "FitJob", "FitRequest", "FitRun", "track_series_path"]

#: More optimizer starts than this is a mistake (each start is a whole fit).
MAX_STARTS = 1000


def track_series_path(series: Path) -> Path:
    """Where ``series=FILE`` puts the tracked parameters: ``FILE-track.csv`` beside it.

    Parameters
    ----------
    series : Path
        The series' CSV.

    Returns
    -------
    Path
    """
    return series.with_name(f"{series.stem}-track.csv")


@dataclass(frozen=True)
class FitRun:
    """What a fit job printed and wrote.

    Attributes
    ----------
    result : ResultRecord
        The result read back (:class:`~balancer_id.records.FitRecord`; a fresh fit and a
        cached one are the same object): ``{"groups": [...]}`` with ``group_by``.
    shape : str
        ``fit``, ``per_log`` or ``groups``: how it is shown.
    written : tuple of Path
        The files written, in order.
    """

    result: ResultRecord
    shape: str = "fit"
    written: tuple[Path, ...] = ()

    @property
    def out(self) -> dict[str, Any]:
        """The JSON object."""
        return self.result.to_dict()

    @property
    def printer(self) -> str:
        """The terminal renderer of :mod:`balancer_id.report.terminal` that shows it."""
        return {"per_log": "print_per_log", "groups": "print_groups"}.get(self.shape, "print_fit")

    @property
    def trusted(self) -> bool:
        """False when any fit in it is not trusted (``trusted: false``)."""
        return self.result.trusted


@dataclass(frozen=True)
class FitJob:
    """A ``fit`` of logs: what the result depends on (a :class:`FitRequest`), how it is
    tuned and grouped, and its outputs (see :func:`balancer_id.fit` for the options).

    Attributes
    ----------
    request : FitRequest
        The logs, the model, the ``--fix`` values, the reading options and the rest the
        result depends on (the result cache's key); ``params``' held values join its
        ``fixed`` when run.
    params : Path or None
        An earlier fit's JSON: its values of this model's parameters are held.
    start : dict of str to float
        Start values (``--start``).
    bounds : dict of str to (float, float)
        Narrower bounds (``--bounds``).
    posterior : bool
        Also sample the posterior.
    priors : tuple of str
        ``NAME=normal:MU,SD`` priors for the posterior.
    group_by : str or None
        ``run``, ``log`` or ``runs:1-3,4-6``: one fit per group.
    report, save, series : Path or None
        The report (HTML/PDF), the JSON, the series (CSV) to write.
    overwrite : bool
        Replace outputs that exist.
    use_cache : bool
        Serve and keep the result in the result cache (a tuned fit never is).
    """

    request: FitRequest
    params: Path | None = None
    start: Mapping[str, float] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    posterior: bool = False
    priors: tuple[str, ...] = ()
    group_by: str | None = None
    report: Path | None = None
    save: Path | None = None
    series: Path | None = None
    overwrite: bool = False
    use_cache: bool = True

    @property
    def track_series(self) -> Path | None:
        """The tracked parameters' CSV, beside ``series``."""
        return track_series_path(self.series) if self.request.track and self.series else None

    def held(self) -> dict[str, float]:
        """The values held: ``params``' of this model's parameters, then ``fixed``."""
        r = self.request
        if self.params is None:
            return dict(r.fixed)
        from balancer_id.identify.params_file import held_for_model

        return {**held_for_model(self.params, r.model, r.effects_files), **r.fixed}

    def check(self) -> None:
        """Refuse, before any work, bad values, outputs and option combinations.

        Raises
        ------
        UsageError
            The first problem, naming its options.
        """
        r = self.request
        if r.starts is not None:
            at_least(r.starts, 1, "--starts")
            if r.starts > MAX_STARTS:
                raise UsageError(f"--starts {r.starts}: give at most {MAX_STARTS} starts")
        ins = inputs_of(r.logs, r.effects_files, r.trajectory)
        check_outputs(
            {"--report": self.report, "--save": self.save, "--series": self.series,
             "--series (tracked)": self.track_series},
            ins + ([self.params] if self.params is not None else []),
            self.overwrite,
        )
        if self.group_by is not None and r.track:
            raise UsageError("--track follows one session's fit: not with --group-by")
        if r.per_log and (self.group_by is not None or r.track or self.series is not None
                          or self.report is not None):
            raise UsageError("--per-log fits all logs at once: not with --group-by, --track, "
                             "--series or --report")

    def _check_groups(self, priors: Sequence[Any]) -> None:
        if self.posterior or priors:
            raise UsageError("--posterior and --prior are for one fit: not with --group-by")
        if self.start or self.bounds or self.save is not None or self.series is not None:
            raise UsageError(
                "--start, --bounds, --save and --series are for one fit: not with --group-by"
            )
        if self.report is not None:
            raise UsageError("--report takes one model: give it without --group-by")

    def run(self) -> FitRun:
        """Check, then fit (or serve the cached result), write the outputs.

        Returns
        -------
        FitRun
            A fresh fit and a cached one alike hold the result read back
            (:class:`~balancer_id.records.FitRecord`).
        """
        held = self.held()
        self.check()
        priors = self._priors()  # issue 34.2: checked before any log is read
        if self.group_by is not None:
            self._check_groups(priors)
            return self._fit_groups(held)
        tuned = bool(self.start or self.bounds or self.posterior or priors)
        key = (replace(self.request, fixed=held).cache_key()
               if self.use_cache and not tuned else None)
        loaded = self.report is None and self.series is None
        result = cache.load(key, FitRecord) if loaded else None
        written: list[Path] = []
        if result is None:
            result = FitRecord.from_dict(self._fit(held, priors, written))
            cache.store(key, result)
        if self.save is not None:
            atomic_write_text(self.save, json.dumps(result.to_dict(), indent=2, allow_nan=False,
                                                    default=str) + "\n")
            written.append(self.save)
        shape = "per_log" if self.request.per_log else "fit"
        return FitRun(result, shape, tuple(written))

    def _priors(self) -> list[Any]:
        if not self.priors:
            return []
        from balancer_id.identify.posterior import parse_prior

        return [parse_prior(item) for item in self.priors]

    def _trials(self) -> Any:
        r = self.request
        return load_trials(list(r.logs), r.options, trajectory(r.trajectory), r.trajectory)

    def _fit_groups(self, held: dict[str, float]) -> FitRun:
        from balancer_id.identify.api import fit_groups

        r = self.request
        out = fit_groups(
            self._trials(), self.group_by or "", model=r.model, fixed=held,
            effects_files=r.effects_files, per_trial=r.per_trial, n_starts=r.starts,
        ).to_dict()
        return FitRun(ResultRecord.from_dict(out), "groups")

    def _fit(self, held: dict[str, float], priors: list[Any], written: list[Path]) -> dict:
        from balancer_id.identify.api import fit

        r = self.request
        if self.report is not None:
            from balancer_id.report.document import check_report_path

            check_report_path(self.report, r.logs)
        trials = self._trials()
        tell(f"fitting {r.model or 'variable_viscosity'} ({r.starts or 'default'} start(s))")
        result: Any = fit(
            trials, model=r.model, fixed=held, effects_files=r.effects_files,
            per_trial=r.per_trial, n_starts=r.starts, start=self.start,
            bounds=self.bounds, track=r.track, per_log=r.per_log,
            posterior=self.posterior, priors=priors,
        )
        out = result.to_dict()  # a robot pair's advice included (issue 9)
        if self.report is not None:
            from balancer_id.report.document import write_fit_report

            tell(f"writing {self.report}")
            write_fit_report(result, self.report)
            written.append(self.report)
        if self.series is not None:
            atomic_write_text(self.series, result.to_frame().to_csv(index=False))
            written.append(self.series)
        if self.track_series is not None and result.tracking is not None:
            atomic_write_text(self.track_series, result.tracking.to_frame().to_csv(index=False))
            written.append(self.track_series)
        return out
