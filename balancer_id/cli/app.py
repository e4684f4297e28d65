"""The ``balancer-id`` command: each command parses, makes one library call, renders.

Data go to stdout (one JSON object with ``--json``), messages to stderr. Errors are one
line with the exit codes of CONTRACT.md; there is never a traceback (set
``BALANCER_ID_DEBUG=1`` to see one). The options shared by several commands are declared
once in :mod:`balancer_id.cli.options`; the reading options once, in
:data:`balancer_id.trials.READ_OPTION_SPELLINGS` (:func:`~balancer_id.cli.options.reads_logs`).
The work behind each command is a library call of :mod:`balancer_id.workflows` (or
:mod:`balancer_id.batch`), so a script gets the same checks, cache and outputs.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any

import typer

from balancer_id.arguments import assignments, bounds, floats, names
from balancer_id.cli.options import (
    Command,
    EffectsFileOpt,
    FixOpt,
    Group,
    JsonOpt,
    LogsArg,
    ModelOpt,
    Opt,
    OverwriteOpt,
    QuietOpt,
    SeriesOpt,
    TrajectoryOpt,
    emit_json,
    guarded,
    one_line,
    reads_logs,
)
from balancer_id.cli.progress import stage
from balancer_id.errors import UsageError, error_record
from balancer_id.text import printable
from balancer_id.trials import ReadOptions

#: Text width when stdout is not a terminal (rich would take 80 and cut names): wide
#: enough for any table row; tables are as wide as their content, not this.
WIDTH_WITHOUT_TERMINAL = 160

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


def _console() -> Any:
    import os

    from rich.console import Console

    if sys.stdout.isatty() or os.environ.get("COLUMNS"):
        return Console()  # the terminal's real width
    # a pipe or a file: no width to fit, so never cut a name; tables keep their own width
    return Console(width=WIDTH_WITHOUT_TERMINAL)


def _render(out: Any, json_out: bool, printer: str, written: Sequence[Path] = ()) -> None:
    """Say which files were written, then show ``out``: one JSON object on stdout, or drawn
    by the terminal renderer ``printer`` (a ``print_*`` function of
    :mod:`balancer_id.report.terminal`) with control characters escaped."""
    for path in written:
        typer.echo(f"wrote {path}", err=True)
    if json_out:
        from balancer_id.jsonsafe import json_ready

        emit_json(json_ready(out))
        return
    from balancer_id.report import terminal

    getattr(terminal, printer)(_console(), printable(out))


def _exit_if_untrusted(trusted: bool) -> None:
    """Exit :data:`~balancer_id.errors.UNTRUSTED_EXIT_CODE` when a fit printed is not
    trusted (its output already written: scripts read the reason from it)."""
    from balancer_id.errors import UNTRUSTED_EXIT_CODE

    if not trusted:
        raise typer.Exit(UNTRUSTED_EXIT_CODE)


def _files(paths: list[Path] | None) -> tuple[str, ...]:
    return tuple(str(p) for p in paths or ())


PlotOpt = Annotated[Path | None, Opt("--plot", "FILE", "Draw the channels to a PNG.")]


# Commands -----------------------------------------------------------------------------
@app.command(cls=Command)
@guarded
@reads_logs
def inspect(
    log: Annotated[Path, typer.Argument(metavar="LOG", help="The log to read.")],
    json_out: JsonOpt = False,
    plot: PlotOpt = None,
    trajectory_text: TrajectoryOpt = None,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
    *,
    options: ReadOptions,
) -> None:
    """Show what was read from LOG and the step trials (or the robot move) found in it.

    Example: balancer-id inspect sample_logs/paper_balancer.csv --plot channels.png
    """
    from balancer_id.workflows.examine import inspect_log

    with stage(f"reading {log.name}"):
        seen = inspect_log(log, options, trajectory_text=trajectory_text, plot=plot,
                           overwrite=overwrite)
    _render(seen.out, json_out, "print_inspection", seen.written)
    if seen.problem is not None:
        typer.echo(f"balancer-id: error: {one_line(seen.problem)}", err=True)
        raise typer.Exit(seen.problem.exit_code)


@app.command(cls=Command)
@guarded
@reads_logs
def fit(
    logs: LogsArg,
    model: ModelOpt = None,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    report: Annotated[Path | None, Opt("--report", "FILE", "Write FILE.html or FILE.pdf.")] = None,
    per_trial: Annotated[bool, Opt("--per-trial", None, "Also fit each trial alone.")] = False,
    starts: Annotated[int | None, Opt("--starts", "INTEGER", "Optimizer starts (default: "
                                      "spread starts where the model has limits, friction or "
                                      "delays).")] = None,
    no_cache: Annotated[bool, Opt("--no-cache", None, "Recompute even if this exact run is "
                                  "cached.")] = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    params: Annotated[Path | None, Opt("--params", "FILE", "Hold the parameters of an earlier "
                                       "'fit --json' output.")] = None,
    start_values: Annotated[list[str] | None, Opt("--start", "TEXT...", "Start value of a "
                                                  "parameter: NAME=VALUE (repeatable).")] = None,
    bounds_text: Annotated[list[str] | None, Opt("--bounds", "TEXT...", "Narrower bounds: "
                                                 "NAME=MIN:MAX (repeatable).")] = None,
    save: Annotated[Path | None, Opt("--save", "FILE", "Write the fit (JSON) to FILE, for "
                                     "--params of compare.")] = None,
    series: SeriesOpt = None,
    overwrite: OverwriteOpt = False,
    track: Annotated[list[str] | None, Opt("--track", "NAME...", "Track a parameter in time "
                                           "within the session, with a 95 % band (repeatable, "
                                           "or NAME,NAME).")] = None,
    per_log: Annotated[list[str] | None, Opt("--per-log", "NAME...", "Each log's own value of "
                                             "NAME, the rest shared over all logs; compares the "
                                             "sharings (repeatable, or NAME,NAME).")] = None,
    group_by: Annotated[str | None, Opt("--group-by", "TEXT", "run|log|runs:1-3,4-6: identify "
                                        "each group apart.")] = None,
    posterior: Annotated[bool, Opt("--posterior", None, "Also sample the posterior (emcee): "
                                   "credible intervals, corner.")] = False,
    prior: Annotated[list[str] | None, Opt("--prior", "NAME=normal:MU,SD", "A normal prior for "
                                           "--posterior (repeatable); others uniform in "
                                           "bounds.")] = None,
    quiet: QuietOpt = False,
    *,
    options: ReadOptions,
) -> None:
    """Identify the parameters of the model over all trials of all LOGS.

    Example: balancer-id fit sample_logs/paper_balancer.csv --model viscous+karnopp
    """
    from balancer_id.workflows.fit_logs import FitJob, FitRequest

    job = FitJob(
        FitRequest(_files(logs), model, assignments(fix, "--fix"), options, per_trial, starts,
                   trajectory_text, _files(effects_file), names(track), names(per_log)),
        params, assignments(start_values, "--start"), bounds(bounds_text), posterior,
        tuple(prior or ()), group_by, report, save, series, overwrite, not no_cache,
    )
    with stage(f"fitting {model or 'variable_viscosity'} ({starts or 'default'} start(s))"):
        done = job.run()
    _render(done.out, json_out, done.printer, done.written)
    _exit_if_untrusted(done.trusted)


@app.command(cls=Command)
@guarded
def simulate(
    model: ModelOpt = None,
    param: Annotated[list[str] | None, Opt("--param", "TEXT...", "NAME=VALUE of the true model "
                                           "(repeatable).")] = None,
    thrust: Annotated[str, Opt("--thrust", "TEXT", "Thrusts in N, one run each.")] = (
        "2.45,-2.45,4.9,-4.9,7.35,-7.35"),
    out: Annotated[Path, Opt("--out", "FILE", "The CSV to write (PASCO Capstone).")] = Path(
        "simulated.csv"),
    noise: Annotated[float, Opt("--noise", "NUMBER", "Acceleration noise (m/s^2).")] = 0.03,
    force_noise: Annotated[float, Opt("--force-noise", "NUMBER", "Force noise (N).")] = 0.03,
    noise_correlation: Annotated[float, Opt("--noise-correlation", "NUMBER", "Lag-one "
                                            "correlation of the noise.")] = 0.0,
    quantize: Annotated[bool, Opt("--quantize", None, "Sensor resolution.")] = False,
    tilt: Annotated[float, Opt("--tilt", "NUMBER", "Sensor tilt (degrees).")] = 10.0,
    drop: Annotated[float, Opt("--drop", "NUMBER", "Fraction of samples dropped.")] = 0.0,
    rate: Annotated[float, Opt("--rate", "NUMBER", "Sample rate (Hz).")] = 200.0,
    rest: Annotated[float, Opt("--rest", "NUMBER", "Rest before each step (s).")] = 2.0,
    duration: Annotated[float, Opt("--duration", "NUMBER", "Motion after each step (s).")] = 8.0,
    force_sign: Annotated[int, Opt("--force-sign", "INTEGER", "Sign of the force channel.")] = 1,
    seed: Annotated[int, Opt("--seed", "INTEGER", "Random seed.")] = 0,
    overwrite: OverwriteOpt = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    json_out: JsonOpt = False,
    params: Annotated[Path | None, Opt("--params", "FILE", "The model and values of 'fit "
                                       "--save' (or --json).")] = None,
    servo_delay: Annotated[float, Opt("--servo-delay", "NUMBER", "With a robot servo: it acts "
                                      "this late (s).")] = 0.0,
    quiet: QuietOpt = False,
) -> None:
    """Write a synthetic log in PASCO Capstone CSV format (one run per thrust).

    Example: balancer-id simulate --param m_a=0.5 --out sim.csv
    """
    from balancer_id.simulation.synth import SensorSettings
    from balancer_id.workflows.simulate_log import simulate_log

    sensor = SensorSettings(
        rate_hz=rate, accel_noise=noise, force_noise=force_noise,
        noise_correlation=noise_correlation, quantize=quantize, tilt_deg=tilt,
        drop_fraction=drop, force_sign=force_sign,
    )
    done = simulate_log(
        out, model=model, values=assignments(param, "--param"), params=params,
        thrusts=floats(thrust, "--thrust") or [], sensor=sensor, rest_s=rest,
        duration_s=duration, trajectory_text=trajectory_text, seed=seed,
        effects_files=effects_file or (), overwrite=overwrite, servo_delay_s=servo_delay,
    )
    if json_out:
        emit_json(done.to_dict())
    else:
        typer.echo(f"wrote {out}: {done.runs} runs of model {done.model}", err=True)


@app.command(cls=Command)
@guarded
@reads_logs
def compare(
    logs: LogsArg,
    model: Annotated[str | None, Opt("--model", "TEXT", "Models to compare: SPEC[,SPEC2...] "
                                     "(viscous,variable_viscosity).", "-m")] = None,
    plot: Annotated[Path | None, Opt("--plot", "FILE", "Measured vs simulated PNG.")] = None,
    vibration_plot: Annotated[Path | None, Opt("--vibration-plot", "FILE", "With --trajectory: "
                                               "the moves' vibration PNG.")] = None,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    params: Annotated[Path | None, Opt("--params", "FILE", "Validate the model of 'fit --save' "
                                       "on LOGS (no refit).")] = None,
    series: SeriesOpt = None,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
    *,
    options: ReadOptions,
) -> None:
    """Measured vs simulated for several models: errors per trial and where each fails.

    With --trajectory it also sets the vibration of each log's move side by side
    (human against robot: band power around the coupled mode).

    Example: balancer-id compare sample_logs/paper_balancer.csv -m viscous,karnopp
    """
    from balancer_id.workflows.compare_logs import compare_logs

    with stage(f"comparing models on {len(logs)} log(s)"):
        done = compare_logs(
            logs, model, fixed=assignments(fix, "--fix"), params=params, options=options,
            effects_files=effects_file or (), trajectory_text=trajectory_text, plot=plot,
            vibration_plot=vibration_plot, series=series, overwrite=overwrite,
        )
    _render(done.to_dict(), json_out, "print_compare", done.written)


@app.command(cls=Command)
@guarded
@reads_logs
def diagnose(
    logs: LogsArg,
    model: ModelOpt = None,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    quiet: QuietOpt = False,
    *,
    options: ReadOptions,
) -> None:
    """Residual tests and ranked suggestions of missing effects.

    Example: balancer-id diagnose sample_logs/paper_balancer.csv
    """
    from balancer_id.workflows.examine import diagnose_logs

    with stage(f"diagnosing {len(logs)} log(s)"):
        done = diagnose_logs(logs, options, model=model, fixed=assignments(fix, "--fix"),
                             effects_files=effects_file or (), trajectory_text=trajectory_text)
    _render(done.out, json_out, "print_diagnosis")


@app.command(cls=Command)
@guarded
@reads_logs
def plan(
    logs: LogsArg,
    model: ModelOpt = None,
    param: Annotated[str | None, Opt("--param", "NAME", "Shrink this parameter's interval "
                                     "('all': D-optimal; default: the widest).")] = None,
    count: Annotated[int, Opt("--count", "INTEGER", "Trials to propose.")] = 3,
    no_separate: Annotated[bool, Opt("--no-separate", None, "Skip the diagnosis (competing "
                                     "explanations).")] = False,
    report: Annotated[Path | None, Opt("--report", "FILE", "The fit's report with the "
                                       "plan.")] = None,
    posterior: Annotated[bool, Opt("--posterior", None, "Sample the fit's posterior too "
                                   "(emcee).")] = False,
    overwrite: OverwriteOpt = False,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    quiet: QuietOpt = False,
    *,
    options: ReadOptions,
) -> None:
    """The trials to record next: those that shrink the widest interval most.

    Example: balancer-id plan sample_logs/paper_balancer.csv --param A
    """
    from balancer_id.workflows.plan import plan_logs

    with stage("fitting and planning the next trials"):
        result = plan_logs(
            logs, options, model=model, fixed=assignments(fix, "--fix"),
            effects_files=_files(effects_file), param=param, count=count,
            separate=not no_separate, posterior=posterior, report=report, overwrite=overwrite,
        )
    _render(result.to_dict(), json_out, "print_plan", [report] if report is not None else [])


@app.command(cls=Command)
@guarded
@reads_logs
def improve(
    logs: LogsArg,
    start: Annotated[str | None, Opt("--start", "TEXT", "Model to start from (default "
                                     "variable_viscosity).")] = None,
    max_steps: Annotated[int, Opt("--max-steps", "INTEGER", "Effects to add at most.")] = 4,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    report: Annotated[Path | None, Opt("--report", "FILE", "FILE.html or FILE.pdf.")] = None,
    plot: Annotated[Path | None, Opt("--plot", "FILE", "The error ladder as PNG.")] = None,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    overwrite: OverwriteOpt = False,
    discover: Annotated[bool, Opt("--discover", None, "Then find a missing force in the states "
                                  "(needs FILE).")] = False,
    effects_out: Annotated[Path | None, Opt("--effects-out", "FILE", "--discover: write the "
                                            "force here as an effect.")] = None,
    quiet: QuietOpt = False,
    *,
    options: ReadOptions,
) -> None:
    """Add effects one by one while the error falls and BIC and held-out trials improve.

    Example: balancer-id improve sample_logs/paper_balancer.csv --report improve.html
    """
    from balancer_id.workflows.examine import check_discover, improve_logs

    check_discover(discover, effects_out)
    with stage(f"improving {start or 'variable_viscosity'}: adding effects (at most "
               f"{max_steps})"):
        done = improve_logs(
            logs, options, max_steps=max_steps, report=report, plot=plot,
            effects_out=effects_out, overwrite=overwrite, model=start,
            fixed=assignments(fix, "--fix"), effects_files=effects_file or (),
            trajectory_text=trajectory_text,
        )
    if done.result.discovery_note is not None:
        typer.echo(f"balancer-id: {done.result.discovery_note}", err=True)
    _render(done.out, json_out, "print_improve", done.written)


@app.command(cls=Command)
@guarded
@reads_logs
def report(
    logs: LogsArg,
    out: Annotated[Path, Opt("--out", "FILE", "FILE.html or FILE.pdf.")],
    model: ModelOpt = None,
    fix: FixOpt = None,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
    *,
    options: ReadOptions,
) -> None:
    """The full report: identification, paper's method, diagnosis and per-trial plots.

    Example: balancer-id report sample_logs/paper_balancer.csv --out report.html
    """
    from balancer_id.workflows import full_report

    with stage(f"reporting on {len(logs)} log(s)"):
        done = full_report(logs, out, model=model, fixed=assignments(fix, "--fix"),
                           options=options, effects_files=effects_file or (),
                           trajectory=trajectory_text, overwrite=overwrite)
    typer.echo(f"wrote {done.path}", err=True)


@app.command(cls=Command)
@guarded
@reads_logs(thrust=False)
def batch(
    paths: Annotated[list[Path], typer.Argument(metavar="PATHS", help="Logs or folders of logs.")],
    out: Annotated[Path, Opt("--out", "FILE", "Folder for summary.csv and one JSON per log.")],
    model: ModelOpt = None,
    fix: FixOpt = None,
    jobs: Annotated[int | None, Opt("--jobs", "INTEGER", "Processes (default: all cores).")] = None,
    scheduler: Annotated[str | None, Opt("--scheduler", "TEXT", "Dask scheduler address (or "
                                         "'local').")] = None,
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    trajectory_text: TrajectoryOpt = None,
    resume: Annotated[bool, Opt("--resume", None, "Keep results already in OUT for unchanged "
                                "logs.")] = False,
    overwrite: OverwriteOpt = False,
    diagnose_logs: Annotated[bool, Opt("--diagnose", None, "Diagnose each fit too (the fleet "
                                       "report lists them).")] = False,
    fleet_report: Annotated[Path | None, Opt("--report", "FILE", "FILE.html or FILE.pdf: the "
                                             "fleet view of the logs.")] = None,
    per_log: Annotated[list[str] | None, Opt("--per-log", "NAME...", "Then fit the counted logs "
                                             "together: NAME each log's own, the rest shared (a "
                                             "fleet of one type); writes "
                                             "OUT/shared_fit.json.")] = None,
    quiet: QuietOpt = False,
    *,
    options: ReadOptions,
) -> None:
    """Identify many logs in parallel; summary.csv plus one JSON per log in OUT.

    Example: balancer-id batch logs/ --out results/
    """
    from balancer_id.batch.command import batch_logs
    from balancer_id.cli.progress import batch_progress

    with batch_progress(lambda msg: typer.echo(one_line(msg), err=True)) as (say, tick):
        done = batch_logs(
            paths, out, report=fleet_report, trajectory_text=trajectory_text,
            effects_files=effects_file or (), overwrite=overwrite, model=model,
            fixed=assignments(fix, "--fix"), options=options, jobs=jobs, scheduler=scheduler,
            progress=say, resume=resume, diagnose=diagnose_logs, tick=tick,
            per_log=list(names(per_log)),
        )
    result = done.result
    for line in done.said:
        typer.echo(one_line(line), err=True)
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
    from balancer_id.model.registry import describe_effects

    items = describe_effects(effects_file or ())
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
