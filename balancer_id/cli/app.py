"""The ``balancer-id`` command: each command parses, loads, calls the library, renders.

Data go to stdout (one JSON object with ``--json``), messages to stderr. Errors are one
line with the exit codes of CONTRACT.md; there is never a traceback (set
``BALANCER_ID_DEBUG=1`` to see one). The options shared by several commands are declared
once in :mod:`balancer_id.cli.options`.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from balancer_id.cli.options import (
    AccelUnitOpt,
    ColumnsOpt,
    Command,
    EffectsFileOpt,
    FixOpt,
    ForceDelayOpt,
    ForceSignOpt,
    GOpt,
    Group,
    JsonOpt,
    LogsArg,
    ModelOpt,
    OverwriteOpt,
    QuietOpt,
    ThrustOpt,
    TrajectoryOpt,
    VerticalOpt,
    WindowOpt,
    assignments,
    at_least,
    check_outputs,
    emit_json,
    error_record,
    floats,
    guarded,
    inputs_of,
    one_line,
    printable,
    read_options,
    trajectory,
)
from balancer_id.cli.progress import stage
from balancer_id.constants import G_DEFAULT
from balancer_id.errors import UsageError

if TYPE_CHECKING:
    from balancer_id.trials import ReadOptions

#: Physical ranges of simulate's options: beyond them a log would hold inf/NaN samples or
#: not fit in memory (issue 21: nothing silent).
MAX_THRUST_N = 1e6
MAX_ACCEL_NOISE = 1e3
MAX_RATE_HZ = 1e5
MAX_DURATION_S = 86400.0
MAX_SIM_SAMPLES = 5e7
#: Text width when stdout is not a terminal (rich would take 80 and cut names): wide
#: enough for any table row; tables are as wide as their content, not this.
WIDTH_WITHOUT_TERMINAL = 160
#: More optimizer starts than this is a mistake (each start is a whole fit).
MAX_STARTS = 1000

app = typer.Typer(
    cls=Group,
    add_completion=True,
    context_settings={"help_option_names": ["-h", "--help"]},
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Identify a passive balancer's dynamics from force/acceleration step logs.",
)


def _version(value: bool) -> None:
    if value:
        from balancer_id import __version__

        typer.echo(f"balancer-id {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
    quiet: Annotated[
        bool, typer.Option("--quiet", "-q", help="No progress messages on stderr.")
    ] = False,
) -> None:
    """Identify a passive balancer's dynamics from force/acceleration step logs.

    Example: balancer-id fit sample_logs/paper_balancer.csv
    """
    from balancer_id.cli import progress

    progress.QUIET = quiet


def _console():
    import os

    from rich.console import Console

    if sys.stdout.isatty() or os.environ.get("COLUMNS"):
        return Console()  # the terminal's real width
    # a pipe or a file: no width to fit, so never cut a name; tables keep their own width
    return Console(width=WIDTH_WITHOUT_TERMINAL)


def _load(logs: list[Path], options: ReadOptions, trajectory_text: str | None):
    from balancer_id.trials import load_trials

    with stage(f"reading {logs[0].name}" if len(logs) == 1 else f"reading {len(logs)} logs"):
        return load_trials(logs, options, trajectory(trajectory_text), trajectory_text)


def _bounds(items: list[str] | None) -> dict[str, tuple[float, float]]:
    """``NAME=MIN:MAX`` items (``--bounds``) as a dict."""

    out: dict[str, tuple[float, float]] = {}
    for item in items or []:
        name, sep, span = item.partition("=")
        lo, colon, hi = span.partition(":")
        try:
            if not (sep and colon):
                raise ValueError
            out[name.strip()] = (float(lo), float(hi))
        except ValueError:
            raise UsageError(f"--bounds '{item}': expected NAME=MIN:MAX, e.g. m_a=5:30") from None
    return out


def _priors(items: list[str] | None) -> list:
    """``--prior NAME=normal:MU,SD ...`` parsed (a usage error names the bad one)."""
    if not items:
        return []
    from balancer_id.identify.posterior import parse_prior

    return [parse_prior(item) for item in items]


def _write_series(frame, path: Path) -> None:
    """``--series``: per trial, time, measured, simulated and residual, as CSV."""
    from balancer_id.files import atomic_write_text

    atomic_write_text(path, frame.to_csv(index=False))
    typer.echo(f"wrote {path}", err=True)


def _track_series_path(series: Path) -> Path:
    """Where ``--series FILE`` puts the tracked parameters: ``FILE-track.csv`` beside it."""
    return series.with_name(f"{series.stem}-track.csv")


def _write_json(obj: object, path: Path) -> None:
    """``--save``: the command's JSON object to a file."""
    import json

    from balancer_id.files import atomic_write_text

    atomic_write_text(path, json.dumps(obj, indent=2, allow_nan=False, default=str) + "\n")
    typer.echo(f"wrote {path}", err=True)


def _params_model(path: Path, model: str | None) -> str | None:
    """The model of ``--params FILE`` (its ``model`` key) unless ``--model`` names one."""
    import json

    if model is not None:
        return model
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None  # read_params_file says what is wrong with it
    spec = data.get("model") if isinstance(data, dict) else None
    return spec if isinstance(spec, str) else None


def _render(out: Any, json_out: bool, printer: str) -> None:
    """``out`` as one JSON object on stdout, or drawn by the terminal renderer ``printer``
    (a ``print_*`` function of :mod:`balancer_id.report.terminal`) with control characters
    escaped."""
    if json_out:
        emit_json(out)
        return
    from balancer_id.report import terminal

    getattr(terminal, printer)(_console(), printable(out))


# Commands -----------------------------------------------------------------------------
@app.command(cls=Command)
@guarded
def inspect(
    log: Annotated[Path, typer.Argument(metavar="LOG", help="The log to read.")],
    json_out: JsonOpt = False,
    plot: Annotated[
        Path | None, typer.Option("--plot", metavar="FILE", help="Draw the channels to a PNG.")
    ] = None,
    trajectory_text: TrajectoryOpt = None,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
    thrust: ThrustOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = G_DEFAULT,
    accel_unit: AccelUnitOpt = "auto",
    window: WindowOpt = None,
    force_delay: ForceDelayOpt = 0.0,
) -> None:
    """Show what was read from LOG and the step trials (or the robot move) found in it.

    Example: balancer-id inspect sample_logs/paper_balancer.csv --plot channels.png
    """
    from balancer_id.errors import NoTrialError
    from balancer_id.trials import describe_log, read, segment

    options = read_options(
        thrust, force_sign, vertical, columns, g, accel_unit, window, force_delay
    )
    check_outputs({"--plot": plot}, inputs_of([log], None, trajectory_text), overwrite)
    with stage(f"reading {log.name}"):
        data = read(log, options)
        try:
            trials = segment(data, options, trajectory(trajectory_text))
            problem = None
        except NoTrialError as exc:
            trials, problem = [], exc
    info = describe_log(data, trials)
    if problem is not None:
        info["error"] = error_record(one_line(problem), problem.exit_code, problem)
    if plot is not None:
        from balancer_id.report.inspect_plot import plot_inspection

        plot_inspection(data, trials, plot, g=options.g, vertical=options.vertical)
        typer.echo(f"wrote {plot}", err=True)
    _render(info, json_out, "print_inspection")
    if problem is not None:
        typer.echo(f"balancer-id: error: {one_line(problem)}", err=True)
        raise typer.Exit(problem.exit_code)


@app.command(cls=Command)
@guarded
def fit(
    logs: LogsArg,
    model: ModelOpt = None,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    report: Annotated[
        Path | None, typer.Option("--report", metavar="FILE", help="Write FILE.html or FILE.pdf.")
    ] = None,
    per_trial: Annotated[
        bool, typer.Option("--per-trial", help="Also fit each trial alone.")
    ] = False,
    starts: Annotated[
        int | None,
        typer.Option(
            "--starts",
            metavar="INTEGER",
            help="Optimizer starts (default: spread starts where the model has limits, "
            "friction or delays).",
        ),
    ] = None,
    no_cache: Annotated[
        bool, typer.Option("--no-cache", help="Recompute even if this exact run is cached.")
    ] = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    params: Annotated[
        Path | None,
        typer.Option(
            "--params",
            metavar="FILE",
            help="Hold the parameters of an earlier 'fit --json' output.",
        ),
    ] = None,
    start_values: Annotated[
        list[str] | None,
        typer.Option(
            "--start",
            metavar="TEXT...",
            help="Start value of a parameter: NAME=VALUE (repeatable).",
        ),
    ] = None,
    bounds: Annotated[
        list[str] | None,
        typer.Option(
            "--bounds", metavar="TEXT...", help="Narrower bounds: NAME=MIN:MAX (repeatable)."
        ),
    ] = None,
    save: Annotated[
        Path | None,
        typer.Option(
            "--save", metavar="FILE", help="Write the fit (JSON) to FILE, for --params of compare."
        ),
    ] = None,
    series: Annotated[
        Path | None,
        typer.Option(
            "--series",
            metavar="FILE",
            help="Write time, measured, simulated, residual to FILE.csv.",
        ),
    ] = None,
    overwrite: OverwriteOpt = False,
    track: Annotated[
        list[str] | None,
        typer.Option(
            "--track",
            metavar="NAME...",
            help="Track a parameter in time within the session, with a 95 % band "
            "(repeatable, or NAME,NAME).",
        ),
    ] = None,
    per_log: Annotated[
        list[str] | None,
        typer.Option(
            "--per-log",
            metavar="NAME...",
            help="Each log's own value of NAME, the rest shared over all logs; compares "
            "the sharings (repeatable, or NAME,NAME).",
        ),
    ] = None,
    group_by: Annotated[
        str | None,
        typer.Option(
            "--group-by", metavar="TEXT", help="run|log|runs:1-3,4-6: identify each group apart."
        ),
    ] = None,
    posterior: Annotated[
        bool,
        typer.Option(
            "--posterior", help="Also sample the posterior (emcee): credible intervals, corner."
        ),
    ] = False,
    prior: Annotated[
        list[str] | None,
        typer.Option(
            "--prior",
            metavar="NAME=normal:MU,SD",
            help="A normal prior for --posterior (repeatable); others uniform in bounds.",
        ),
    ] = None,
    quiet: QuietOpt = False,
    thrust: ThrustOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = G_DEFAULT,
    accel_unit: AccelUnitOpt = "auto",
    window: WindowOpt = None,
    force_delay: ForceDelayOpt = 0.0,
) -> None:
    """Identify the parameters of the model over all trials of all LOGS.

    Example: balancer-id fit sample_logs/paper_balancer.csv --model viscous+karnopp
    """
    from balancer_id.cli.request import FitRequest

    options = read_options(
        thrust, force_sign, vertical, columns, g, accel_unit, window, force_delay
    )
    fixed = assignments(fix, "--fix")
    if params is not None:  # issue 9: hold an earlier fit's values; --fix wins
        from balancer_id.identify.params_file import held_for_model

        fixed = {**held_for_model(params, model, effects_file or ()), **fixed}

    if starts is not None:
        at_least(starts, 1, "--starts")
    if starts is not None and starts > MAX_STARTS:
        raise UsageError(f"--starts {starts}: give at most {MAX_STARTS} starts")
    user_start = assignments(start_values, "--start")
    user_bounds = _bounds(bounds)
    ins = inputs_of(logs, effects_file, trajectory_text)
    if params is not None:
        ins.append(params)
    tracked = tuple(n.strip() for item in track or [] for n in item.split(",") if n.strip())
    track_series = _track_series_path(series) if tracked and series is not None else None
    check_outputs(
        {
            "--report": report,
            "--save": save,
            "--series": series,
            "--series (tracked)": track_series,
        },
        ins,
        overwrite,
    )
    if group_by is not None and tracked:
        raise UsageError("--track follows one session's fit: not with --group-by")
    own = tuple(n.strip() for item in per_log or [] for n in item.split(",") if n.strip())
    if own and (group_by is not None or tracked or series is not None or report is not None):
        raise UsageError(
            "--per-log fits all logs at once: not with --group-by, --track, --series or --report"
        )
    priors = _priors(prior)  # issue 34.2: checked before any log is read
    if group_by is not None and (posterior or priors):
        raise UsageError("--posterior and --prior are for one fit: not with --group-by")
    if group_by is not None:
        if user_start or user_bounds or save is not None or series is not None:
            raise UsageError(
                "--start, --bounds, --save and --series are for one fit: not with --group-by"
            )
        _fit_groups(
            _load(logs, options, trajectory_text),
            group_by,
            json_out=json_out,
            report=report,
            model=model,
            fixed=fixed,
            effects_files=tuple(str(p) for p in effects_file or ()),
            per_trial=per_trial,
            n_starts=starts,
        )
        return

    request = FitRequest(
        logs=tuple(str(p) for p in logs),
        model=model,
        fixed=fixed,
        options=options,
        per_trial=per_trial,
        starts=starts,
        trajectory=trajectory_text,
        effects_files=tuple(str(p) for p in effects_file or ()),
        track=tracked,
        per_log=own,
    )
    tuned = bool(user_start or user_bounds or posterior or priors)
    key = None if (no_cache or tuned) else request.cache_key()
    from balancer_id import cache

    out = cache.load(key) if report is None and series is None else None
    if out is None:
        from balancer_id.identify.api import fit as run_fit

        if report is not None:
            from balancer_id.report.document import check_report_path

            check_report_path(report, logs)
        with stage(f"fitting {model or 'variable_viscosity'} ({starts or 'default'} start(s))"):
            result = run_fit(
                _load(logs, options, trajectory_text),
                model=model,
                fixed=request.fixed,
                effects_files=request.effects_files,
                per_trial=per_trial,
                n_starts=starts,
                start=user_start,
                bounds=user_bounds,
                track=tracked,
                per_log=own,
                posterior=posterior,
                priors=priors,
            )
        out = result.to_dict()  # a robot pair's advice included (issue 9)
        cache.store(key, out)
        if report is not None:
            from balancer_id.report.document import write_fit_report

            with stage(f"writing {report}"):
                write_fit_report(result, report)
            typer.echo(f"wrote {report}", err=True)
        if series is not None:
            _write_series(result.to_frame(), series)
        if track_series is not None and result.tracking is not None:
            _write_series(result.tracking.to_frame(), track_series)
    if save is not None:
        _write_json(out, save)
    _render(out, json_out, "print_per_log" if own else "print_fit")
    _exit_if_untrusted([out])


def _exit_if_untrusted(results: list[Any]) -> None:
    """Exit :data:`~balancer_id.errors.UNTRUSTED_EXIT_CODE` when any fit printed is not
    trusted (its output already written: scripts read the reason from it)."""
    from balancer_id.errors import UNTRUSTED_EXIT_CODE

    if any(isinstance(r, dict) and r.get("trusted") is False for r in results):
        raise typer.Exit(UNTRUSTED_EXIT_CODE)


def _fit_groups(trial_set, group_by: str, *, json_out: bool, report, **kwargs) -> None:
    """``fit --group-by``: one identification per group of trials (``bid.fit_groups``)."""
    from balancer_id.identify.api import fit_groups

    if report is not None:
        raise UsageError("--report takes one model: give it without --group-by")
    out = fit_groups(trial_set, group_by, **kwargs).to_dict()
    if json_out:
        emit_json(out)
    else:
        from balancer_id.report.terminal import print_fit

        console = _console()
        for item in out["groups"]:  # type: ignore[attr-defined]
            console.print(f"[bold]group {printable(item['group'])}[/bold]")
            print_fit(console, printable(item))
    _exit_if_untrusted(out["groups"])  # type: ignore[arg-type]


@app.command(cls=Command)
@guarded
def simulate(
    model: ModelOpt = None,
    param: Annotated[
        list[str] | None,
        typer.Option(
            "--param", metavar="TEXT...", help="NAME=VALUE of the true model (repeatable)."
        ),
    ] = None,
    thrust: Annotated[
        str, typer.Option("--thrust", metavar="TEXT", help="Thrusts in N, one run each.")
    ] = ("2.45,-2.45,4.9,-4.9,7.35,-7.35"),
    out: Annotated[
        Path, typer.Option("--out", metavar="FILE", help="The CSV to write (PASCO Capstone).")
    ] = Path("simulated.csv"),
    noise: Annotated[
        float, typer.Option("--noise", metavar="NUMBER", help="Acceleration noise (m/s^2).")
    ] = 0.03,
    force_noise: Annotated[
        float, typer.Option("--force-noise", metavar="NUMBER", help="Force noise (N).")
    ] = 0.03,
    noise_correlation: Annotated[
        float,
        typer.Option(
            "--noise-correlation", metavar="NUMBER", help="Lag-one correlation of the noise."
        ),
    ] = 0.0,
    quantize: Annotated[bool, typer.Option("--quantize", help="Sensor resolution.")] = False,
    tilt: Annotated[
        float, typer.Option("--tilt", metavar="NUMBER", help="Sensor tilt (degrees).")
    ] = 10.0,
    drop: Annotated[
        float, typer.Option("--drop", metavar="NUMBER", help="Fraction of samples dropped.")
    ] = 0.0,
    rate: Annotated[
        float, typer.Option("--rate", metavar="NUMBER", help="Sample rate (Hz).")
    ] = 200.0,
    rest: Annotated[
        float, typer.Option("--rest", metavar="NUMBER", help="Rest before each step (s).")
    ] = 2.0,
    duration: Annotated[
        float, typer.Option("--duration", metavar="NUMBER", help="Motion after each step (s).")
    ] = 8.0,
    force_sign: Annotated[
        int, typer.Option("--force-sign", metavar="INTEGER", help="Sign of the force channel.")
    ] = 1,
    seed: Annotated[int, typer.Option("--seed", metavar="INTEGER", help="Random seed.")] = 0,
    overwrite: OverwriteOpt = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    json_out: JsonOpt = False,
    params: Annotated[
        Path | None,
        typer.Option(
            "--params", metavar="FILE", help="The model and values of 'fit --save' (or --json)."
        ),
    ] = None,
    quiet: QuietOpt = False,
) -> None:
    """Write a synthetic log in PASCO Capstone CSV format (one run per thrust).

    Example: balancer-id simulate --param m_a=0.5 --out sim.csv
    """
    from balancer_id.model.spec import resolve_model
    from balancer_id.simulation.synth import SensorSettings, write_synthetic_log

    known: dict[str, float] = {}
    if params is not None:  # issue 11: simulate an identified model
        from balancer_id.identify.params_file import read_params_file

        model = _params_model(params, model)
        mdl = resolve_model(model, effects_file or ())
        known = {k: v for k, v in read_params_file(params).items() if k in mdl.param_names}
    mdl = resolve_model(model, effects_file or ())
    values = mdl.resolve({**known, **assignments(param, "--param")})
    thrusts = floats(thrust, "--thrust") or []
    if not thrusts:
        raise UsageError("--thrust: give at least one thrust")
    for name, low, high, what, value in [
        *(("--thrust", -MAX_THRUST_N, MAX_THRUST_N, "N", f) for f in thrusts),
        ("--noise", 0.0, MAX_ACCEL_NOISE, "m/s^2", noise),
        ("--force-noise", 0.0, MAX_THRUST_N, "N", force_noise),
        ("--rate", 1e-9, MAX_RATE_HZ, "Hz", rate),
        ("--rest", 0.0, MAX_DURATION_S, "s", rest),
        ("--duration", 1e-9, MAX_DURATION_S, "s", duration),
    ]:
        if not (math.isfinite(value) and low <= value <= high):
            raise UsageError(
                f"{name} {value:g}: give a finite value in {low:g}..{high:g} {what} (a log "
                "outside these would hold overflowing or unreadable samples)"
            )
    if rate * (rest + duration) * len(thrusts) > MAX_SIM_SAMPLES:
        raise UsageError(
            f"--rate {rate:g} x (--rest + --duration) x {len(thrusts)} runs is more than "
            f"{MAX_SIM_SAMPLES:.0e} samples; shorten the runs or lower the rate"
        )
    if seed < 0:
        raise UsageError(f"--seed {seed}: give a seed >= 0")
    traj = trajectory(trajectory_text)
    mdl.require_reference_move(traj)
    if force_sign not in (1, -1):
        raise UsageError("--force-sign must be +1 or -1")
    if not 0.0 <= noise_correlation < 1.0:
        raise UsageError("--noise-correlation must be in [0, 1)")
    if not (math.isfinite(rate) and rate > 0):
        raise UsageError(f"--rate {rate}: give a sample rate > 0 Hz, e.g. 200")
    for option, value in (("--noise", noise), ("--force-noise", force_noise), ("--rest", rest)):
        at_least(value, 0.0, option)
    if not (math.isfinite(duration) and duration > 0):
        raise UsageError(f"--duration {duration}: give the motion's length in s (> 0)")
    if not (math.isfinite(drop) and 0.0 <= drop < 1.0):
        raise UsageError(f"--drop {drop}: give the fraction of samples dropped, in [0, 1)")
    if not math.isfinite(tilt):
        raise UsageError(f"--tilt {tilt}: give the sensor's tilt in degrees")
    inputs = inputs_of([], effects_file, trajectory_text) + ([params] if params else [])
    check_outputs({"--out": out}, inputs, overwrite)
    sensor = SensorSettings(
        rate_hz=rate,
        accel_noise=noise,
        force_noise=force_noise,
        noise_correlation=noise_correlation,
        quantize=quantize,
        tilt_deg=tilt,
        drop_fraction=drop,
        force_sign=force_sign,
    )
    recs = write_synthetic_log(
        out,
        mdl,
        values,
        thrusts,
        sensor=sensor,
        rest_s=rest,
        duration_s=duration,
        trajectory=traj,
        seed=seed,
        overwrite=overwrite,
    )
    info = {
        "out": str(out),
        "model": mdl.spec,
        "parameters": values,
        "thrusts": thrusts,
        "seed": seed,
    }
    if json_out:
        emit_json(info)
    else:
        typer.echo(f"wrote {out}: {len(recs)} runs of model {mdl.spec}", err=True)


@app.command(cls=Command)
@guarded
def compare(
    logs: LogsArg,
    model: Annotated[
        str | None,
        typer.Option(
            "--model",
            "-m",
            metavar="TEXT",
            help="Models to compare: SPEC[,SPEC2...] (viscous,variable_viscosity).",
        ),
    ] = None,
    plot: Annotated[
        Path | None, typer.Option("--plot", metavar="FILE", help="Measured vs simulated PNG.")
    ] = None,
    vibration_plot: Annotated[
        Path | None,
        typer.Option(
            "--vibration-plot", metavar="FILE", help="With --trajectory: the moves' vibration PNG."
        ),
    ] = None,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    params: Annotated[
        Path | None,
        typer.Option(
            "--params",
            metavar="FILE",
            help="Validate the model of 'fit --save' on LOGS (no refit).",
        ),
    ] = None,
    series: Annotated[
        Path | None,
        typer.Option(
            "--series",
            metavar="FILE",
            help="Write time, measured, simulated, residual to FILE.csv.",
        ),
    ] = None,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
    thrust: ThrustOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = G_DEFAULT,
    accel_unit: AccelUnitOpt = "auto",
    window: WindowOpt = None,
    force_delay: ForceDelayOpt = 0.0,
) -> None:
    """Measured vs simulated for several models: errors per trial and where each fails.

    With --trajectory it also sets the vibration of each log's move side by side
    (human against robot: band power around the coupled mode).

    Example: balancer-id compare sample_logs/paper_balancer.csv -m viscous,karnopp
    """
    from balancer_id.diagnostics.api import compare as run_compare

    options = read_options(
        thrust, force_sign, vertical, columns, g, accel_unit, window, force_delay
    )
    fixed = assignments(fix, "--fix")
    if params is not None:  # issue 11: an identified model on new logs, as MATLAB's compare
        from balancer_id.identify.params_file import read_params_file

        model = _params_model(params, model)
        fixed = {**read_params_file(params), **fixed}
    model = model or "viscous,variable_viscosity"
    specs = [m.strip() for m in model.split(",") if m.strip()]
    if not specs:
        raise UsageError(f"--model '{model}': give one or more models, e.g. viscous,karnopp")
    ins = inputs_of(logs, effects_file, trajectory_text)
    if params is not None:
        ins.append(params)
    check_outputs(
        {"--plot": plot, "--vibration-plot": vibration_plot, "--series": series}, ins, overwrite
    )
    trials = _load(logs, options, trajectory_text)
    with stage(f"fitting {len(specs)} model(s): {', '.join(specs)}"):
        results = run_compare(
            trials,
            specs,
            fixed=fixed,
            effects_files=effects_file or (),
        )
    out = {"models": [r.to_dict() for r in results]}
    if params is not None and len(results) == 1 and results[0].validation is not None:
        # every value known: the saved model on new logs, with a verdict (issue 20.4)
        out["validation"] = results[0].validation.to_dict()
    if trajectory_text is not None:  # issue 9: the vibration of each move, side by side
        from balancer_id.diagnostics.vibration import compare_vibration

        vib = compare_vibration(trials.trials)  # the moves read once, above
        out["vibration"] = vib.to_dict()
        if vibration_plot is not None:
            from balancer_id.report.vibration_plot import plot_vibration

            plot_vibration(vib, vibration_plot)
            typer.echo(f"wrote {vibration_plot}", err=True)
    if plot is not None:
        from balancer_id.report.sections import plot_comparison

        plot_comparison(results, plot)
        typer.echo(f"wrote {plot}", err=True)
    if series is not None:
        import pandas as pd

        frames = [r.to_frame().assign(model=r.match.model.spec) for r in results]
        _write_series(pd.concat(frames, ignore_index=True), series)
    if json_out:
        from balancer_id.jsonsafe import json_ready

        emit_json(json_ready(out))
    else:
        from balancer_id.report.terminal import print_compare

        print_compare(_console(), printable(out))


def _fit(
    logs: list[Path],
    options: ReadOptions,
    *,
    model: str | None,
    fix: list[str] | None,
    effects_file: list[Path] | None,
    trajectory_text: str | None,
    per_trial: bool = False,
):
    """Parse the fit's own options, load the trials, fit.

    The kernels of the model and of the candidates a diagnosis refits are compiled first,
    all at once (several processes) when the disk cache lacks them.
    """
    from balancer_id.diagnostics.candidates import candidates
    from balancer_id.identify.api import fit as run_fit
    from balancer_id.identify.api import resolve_model
    from balancer_id.simulation.kernel import compile_models

    fixed = assignments(fix, "--fix")
    trials = _load(logs, options, trajectory_text)
    start = resolve_model(model, effects_file or ())
    cands = candidates(start, with_trajectory=trajectory_text is not None)
    compile_models([start, *(c.model for c in cands)])
    with stage(f"fitting {model or 'variable_viscosity'}"):
        return run_fit(
            trials,
            model=model,
            fixed=fixed,
            effects_files=effects_file or (),
            per_trial=per_trial,
        )


@app.command(cls=Command)
@guarded
def diagnose(
    logs: LogsArg,
    model: ModelOpt = None,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    quiet: QuietOpt = False,
    thrust: ThrustOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = G_DEFAULT,
    accel_unit: AccelUnitOpt = "auto",
    window: WindowOpt = None,
    force_delay: ForceDelayOpt = 0.0,
) -> None:
    """Residual tests and ranked suggestions of missing effects.

    Example: balancer-id diagnose sample_logs/paper_balancer.csv
    """
    from balancer_id.diagnostics.diagnosis import diagnose as run_diagnose

    options = read_options(
        thrust, force_sign, vertical, columns, g, accel_unit, window, force_delay
    )
    fitted = _fit(
        logs,
        options,
        model=model,
        fix=fix,
        effects_file=effects_file,
        trajectory_text=trajectory_text,
    )
    with stage("diagnosing"):
        result = run_diagnose(fitted)
    out = result.to_dict()
    _render(out, json_out, "print_diagnosis")


@app.command(cls=Command)
@guarded
def plan(
    logs: LogsArg,
    model: ModelOpt = None,
    param: Annotated[
        str | None,
        typer.Option(
            "--param",
            metavar="NAME",
            help="Shrink this parameter's interval ('all': D-optimal; default: the widest).",
        ),
    ] = None,
    count: Annotated[
        int, typer.Option("--count", metavar="INTEGER", help="Trials to propose.")
    ] = 3,
    no_separate: Annotated[
        bool,
        typer.Option("--no-separate", help="Skip the diagnosis (competing explanations)."),
    ] = False,
    report: Annotated[
        Path | None,
        typer.Option("--report", metavar="FILE", help="The fit's report with the plan."),
    ] = None,
    posterior: Annotated[
        bool, typer.Option("--posterior", help="Sample the fit's posterior too (emcee).")
    ] = False,
    overwrite: OverwriteOpt = False,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    quiet: QuietOpt = False,
    thrust: ThrustOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = G_DEFAULT,
    accel_unit: AccelUnitOpt = "auto",
    window: WindowOpt = None,
    force_delay: ForceDelayOpt = 0.0,
) -> None:
    """The trials to record next: those that shrink the widest interval most.

    Example: balancer-id plan sample_logs/paper_balancer.csv --param A
    """
    from balancer_id.workflows.plan import plan as run_plan

    at_least(count, 1, "--count")
    options = read_options(
        thrust, force_sign, vertical, columns, g, accel_unit, window, force_delay
    )
    check_outputs({"--report": report}, inputs_of(logs, effects_file, None), overwrite)
    if report is not None:
        from balancer_id.report.document import check_report_path

        check_report_path(report, logs)
    with stage("fitting and planning the next trials"):
        result = run_plan(
            _load(logs, options, None),
            model=model,
            fixed=assignments(fix, "--fix"),
            effects_files=tuple(str(p) for p in effects_file or ()),
            param=param,
            count=count,
            separate=not no_separate,
            posterior=posterior,
        )
    if report is not None:
        with stage(f"writing {report}"):
            result.write_report(report)
        typer.echo(f"wrote {report}", err=True)
    _render(result.to_dict(), json_out, "print_plan")


@app.command(cls=Command)
@guarded
def improve(
    logs: LogsArg,
    start: Annotated[
        str | None,
        typer.Option(
            "--start", metavar="TEXT", help="Model to start from (default variable_viscosity)."
        ),
    ] = None,
    max_steps: Annotated[
        int, typer.Option("--max-steps", metavar="INTEGER", help="Effects to add at most.")
    ] = 4,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    report: Annotated[
        Path | None, typer.Option("--report", metavar="FILE", help="FILE.html or FILE.pdf.")
    ] = None,
    plot: Annotated[
        Path | None, typer.Option("--plot", metavar="FILE", help="The error ladder as PNG.")
    ] = None,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    overwrite: OverwriteOpt = False,
    discover: Annotated[
        bool,
        typer.Option("--discover", help="Then find a missing force in the states (needs FILE)."),
    ] = False,
    effects_out: Annotated[
        Path | None,
        typer.Option(
            "--effects-out", metavar="FILE", help="--discover: write the force here as an effect."
        ),
    ] = None,
    quiet: QuietOpt = False,
    thrust: ThrustOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = G_DEFAULT,
    accel_unit: AccelUnitOpt = "auto",
    window: WindowOpt = None,
    force_delay: ForceDelayOpt = 0.0,
) -> None:
    """Add effects one by one while the error falls and BIC and held-out trials improve.

    Example: balancer-id improve sample_logs/paper_balancer.csv --report improve.html
    """
    from balancer_id.diagnostics.improve import improve as run_improve

    options = read_options(
        thrust, force_sign, vertical, columns, g, accel_unit, window, force_delay
    )
    at_least(max_steps, 0, "--max-steps")
    check_outputs(
        {"--report": report, "--plot": plot},
        inputs_of(logs, effects_file, trajectory_text),
        overwrite,
    )
    if report is not None:
        from balancer_id.report.document import check_report_path

        check_report_path(report, logs)
    if discover != (effects_out is not None):
        raise UsageError("--discover and --effects-out FILE.py go together; give both")
    if effects_out is not None:
        from balancer_id.diagnostics.discover import check_effects_out

        check_effects_out(
            effects_out, inputs=inputs_of(logs, effects_file, trajectory_text), overwrite=overwrite
        )
    fitted = _fit(
        logs,
        options,
        model=start,
        fix=fix,
        effects_file=effects_file,
        trajectory_text=trajectory_text,
    )
    with stage(f"improving {fitted.model}: adding effects (at most {max_steps})"):
        result = run_improve(
            fitted, max_steps=max_steps, discover_to=effects_out, overwrite=overwrite
        )
    if result.discovery_note is not None:
        typer.echo(f"balancer-id: {result.discovery_note}", err=True)
    out = result.to_dict()
    if plot is not None:
        from balancer_id.report.plots import plot_error_ladder

        plot_error_ladder(out["steps"], plot)
        typer.echo(f"wrote {plot}", err=True)
    if report is not None:
        from balancer_id.report.sections import write_improve_report

        with stage(f"writing {report}"):
            write_improve_report(result, report)
        typer.echo(f"wrote {report}", err=True)
    _render(out, json_out, "print_improve")


@app.command(cls=Command)
@guarded
def report(
    logs: LogsArg,
    out: Annotated[Path, typer.Option("--out", metavar="FILE", help="FILE.html or FILE.pdf.")],
    model: ModelOpt = None,
    fix: FixOpt = None,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
    thrust: ThrustOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = G_DEFAULT,
    accel_unit: AccelUnitOpt = "auto",
    window: WindowOpt = None,
    force_delay: ForceDelayOpt = 0.0,
) -> None:
    """The full report: identification, paper's method, diagnosis and per-trial plots.

    Example: balancer-id report sample_logs/paper_balancer.csv --out report.html
    """
    from balancer_id.workflows import full_report as run_report

    options = read_options(
        thrust, force_sign, vertical, columns, g, accel_unit, window, force_delay
    )
    with stage(f"reporting on {len(logs)} log(s)"):
        done = run_report(
            logs,
            out,
            model=model,
            fixed=assignments(fix, "--fix"),
            options=options,
            effects_files=effects_file or (),
            trajectory=trajectory_text,
            overwrite=overwrite,
        )
    typer.echo(f"wrote {done.path}", err=True)


@app.command(cls=Command)
@guarded
def batch(
    paths: Annotated[list[Path], typer.Argument(metavar="PATHS", help="Logs or folders of logs.")],
    out: Annotated[
        Path,
        typer.Option("--out", metavar="FILE", help="Folder for summary.csv and one JSON per log."),
    ],
    model: ModelOpt = None,
    fix: FixOpt = None,
    jobs: Annotated[
        int | None,
        typer.Option("--jobs", metavar="INTEGER", help="Processes (default: all cores)."),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option("--scheduler", metavar="TEXT", help="Dask scheduler address (or 'local')."),
    ] = None,
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    resume: Annotated[
        bool,
        typer.Option("--resume", help="Keep results already in OUT for unchanged logs."),
    ] = False,
    overwrite: OverwriteOpt = False,
    diagnose_logs: Annotated[
        bool,
        typer.Option("--diagnose", help="Diagnose each fit too (the fleet report lists them)."),
    ] = False,
    fleet_report: Annotated[
        Path | None,
        typer.Option(
            "--report", metavar="FILE", help="FILE.html or FILE.pdf: the fleet view of the logs."
        ),
    ] = None,
    per_log: Annotated[
        list[str] | None,
        typer.Option(
            "--per-log",
            metavar="NAME...",
            help="Then fit the counted logs together: NAME each log's own, the rest "
            "shared (a fleet of one type); writes OUT/shared_fit.json.",
        ),
    ] = None,
    quiet: QuietOpt = False,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = G_DEFAULT,
    accel_unit: AccelUnitOpt = "auto",
    window: WindowOpt = None,
    force_delay: ForceDelayOpt = 0.0,
) -> None:
    """Identify many logs in parallel; summary.csv plus one JSON per log in OUT.

    Example: balancer-id batch logs/ --out results/
    """
    from balancer_id.batch import run_batch
    from balancer_id.cli.progress import batch_progress

    options = read_options(None, force_sign, vertical, columns, g, accel_unit, window, force_delay)
    if fleet_report is not None:
        from balancer_id.report.document import check_report_path

        check_report_path(fleet_report)
        check_outputs(
            {"--report": fleet_report}, inputs_of(paths, effects_file, trajectory_text), overwrite
        )
    with batch_progress(lambda msg: typer.echo(one_line(msg), err=True)) as (say, tick):
        result = run_batch(
            paths,
            out,
            model=model,
            fixed=assignments(fix, "--fix"),
            options=options,
            effects_files=effects_file or (),
            jobs=jobs,
            scheduler=scheduler,
            progress=say,
            resume=resume,
            overwrite=overwrite,
            trajectory=trajectory(trajectory_text),
            diagnose=diagnose_logs,
            tick=tick,
            per_log=[n.strip() for item in per_log or [] for n in item.split(",") if n.strip()],
        )
    shared = result.shared_fit
    if shared is not None:
        from balancer_id.batch.shared import SHARED_NAME

        said = shared.get("error") or f"shared fit: {shared.get('verdict')}"
        typer.echo(f"{one_line(said)}; wrote {out / SHARED_NAME}", err=True)
    if fleet_report is not None:
        from balancer_id.report.fleet import write_fleet_report

        write_fleet_report(result.rows, fleet_report, shared)
        typer.echo(f"wrote {fleet_report}", err=True)
    if json_out:
        emit_json(result.to_dict())
    else:
        typer.echo(
            f"{result.n_ok} identified, {result.n_failed} failed; wrote {result.summary_path}",
            err=True,
        )
    if result.exit_code:
        raise typer.Exit(result.exit_code)


@app.command(cls=Command)
@guarded
def effects(
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """List the effects available, built in and user-supplied, with their parameters.

    Example: balancer-id effects --effects-file my_effects.py
    """
    from balancer_id.model.effects.base_model import Base
    from balancer_id.model.registry import default_registry

    registry = default_registry(effects_file or ())
    items = [{**Base.describe(), "origin": "built-in (always present)"}]
    items += [{**cls.describe(), "origin": registry.origin(cls.name)} for cls in registry]
    if json_out:
        emit_json({"effects": items})
    else:
        from balancer_id.report.terminal import print_effects

        print_effects(_console(), printable(items))


def _asks_for_json(argv: list[str]) -> bool:
    """Whether the command line asks for ``--json`` (before a ``--`` that ends options)."""
    words = argv[: argv.index("--")] if "--" in argv else argv
    return "--json" in words


def main() -> None:
    """Entry point of the ``balancer-id`` console script.

    Usage errors (unknown option, a value of the wrong type) are one line on stderr with
    exit 2, like every other error, instead of click's framed box. A terminal or pipe whose
    encoding cannot show a character (``PYTHONIOENCODING=ascii``) gets it escaped.
    """
    for stream in (sys.stdout, sys.stderr):
        if stream is not None and hasattr(stream, "reconfigure"):
            try:
                stream.reconfigure(errors="backslashreplace")
            except (OSError, ValueError):
                pass
    try:
        code = app(standalone_mode=False)
    except typer.Abort:
        typer.echo("balancer-id: error: interrupted", err=True)
        code = 130
    except Exception as exc:  # click's usage errors (typer vendors click in recent versions)
        if not (hasattr(exc, "format_message") and hasattr(exc, "exit_code")):
            raise
        ctx = getattr(exc, "ctx", None)
        if type(exc).__name__ == "NoArgsIsHelpError":
            pass  # typer has shown the usage already: once is enough
        else:
            hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
            line = one_line(exc.format_message()) + hint
            typer.echo(f"balancer-id: error: {line}", err=True)
            if _asks_for_json(sys.argv[1:]):  # the error object, as for every other failure
                emit_json({"error": error_record(line, exc.exit_code, UsageError(line))})
        code = exc.exit_code
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
