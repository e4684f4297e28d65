"""The ``balancer-id`` command: it parses arguments, calls the library and writes output.

Data go to stdout (one JSON object with ``--json``), messages to stderr. Errors are one
line with the exit codes of CONTRACT.md; there is never a traceback (set
``BALANCER_ID_DEBUG=1`` to see one).
"""

from __future__ import annotations

import functools
import json
import math
import os
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Identify a passive balancer's dynamics from force/acceleration step logs.",
)

F = TypeVar("F", bound=Callable[..., Any])

# Options shared by several commands -----------------------------------------------------
ModelOpt = Annotated[
    str | None,
    typer.Option("--model", "-m", help="Effects joined by '+' (default variable_viscosity)."),
]
EffectsFileOpt = Annotated[
    list[Path] | None,
    typer.Option("--effects-file", help="A .py file of user effects (repeatable)."),
]
ThrustOpt = Annotated[
    str | None,
    typer.Option("--thrust", help="Thrust of each trial in N, e.g. 2.45,-4.9 (one log)."),
]
ForceSignOpt = Annotated[
    int | None, typer.Option("--force-sign", help="+1 or -1: fix the sign of the force channel.")
]
VerticalOpt = Annotated[
    str, typer.Option("--vertical", help="auto|x|y|z|-z|...: up axis of logs without gravity.")
]
ColumnsOpt = Annotated[
    str | None, typer.Option("--columns", help="Column map of a generic CSV: time=t,force=F,ax=...")
]
GOpt = Annotated[float, typer.Option("--g", help="Gravity in m/s^2.")]
AccelUnitOpt = Annotated[
    str, typer.Option("--accel-unit", help="auto|m/s^2|g: unit of the acceleration columns.")
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")]
FixOpt = Annotated[
    list[str] | None, typer.Option("--fix", help="Hold a parameter: NAME=VALUE (repeatable).")
]
OverwriteOpt = Annotated[
    bool,
    typer.Option("--overwrite", help="Replace output files that exist (never an input)."),
]
TrajectoryOpt = Annotated[
    str | None,
    typer.Option(
        "--trajectory",
        help="Robot reference: 'trapezoid:distance=..,speed=..,accel=..[,start=..]' or a "
        "CSV of time,position.",
    ),
]


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
) -> None:
    """Identify a passive balancer's dynamics from force/acceleration step logs."""


def _one_line(text: object) -> str:
    """``text`` on one line, with control characters (terminal escapes) made visible."""
    flat = " ".join(str(text).split())
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in flat)


def _fail(
    message: str, code: int, exc: BaseException | None = None, json_out: bool = False
) -> None:
    line = _one_line(message)
    typer.echo(f"balancer-id: error: {line}", err=True)
    if json_out:
        _emit_json({"error": _error_record(line, code, exc)})
    raise typer.Exit(code)


def _error_record(line: str, code: int, exc: BaseException | None) -> dict[str, object]:
    """The ``error`` object of ``--json`` output: kind, message, exit code, where."""
    file = getattr(exc, "file", None)
    return {
        "kind": type(exc).__name__ if exc is not None else "Error",
        "message": line,
        "exit_code": code,
        "file": None if file is None else str(file),
        "line": getattr(exc, "line", None),
        "column": getattr(exc, "column", None),
    }


def guarded(func: F) -> F:
    """Turn library errors into one-line messages and CONTRACT.md exit codes."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from balancer_id.errors import BalancerIdError

        json_out = bool(kwargs.get("json_out"))
        try:
            with warnings.catch_warnings():
                # numpy's floating-point RuntimeWarnings mean nothing to a user; what matters
                # is said as findings and warnings of the results
                warnings.filterwarnings("ignore", category=RuntimeWarning)
                return func(*args, **kwargs)
        except (typer.Exit, typer.Abort):
            raise
        except BalancerIdError as exc:
            _fail(str(exc), exc.exit_code, exc, json_out)
        except KeyboardInterrupt as exc:
            _fail("interrupted", 130, exc, json_out)
        except SystemExit as exc:  # sys.exit() inside a user's effects file
            _fail(
                f"a user effects file called sys.exit({exc.code!r}) while loading or running; "
                "effects must not exit: remove the call",
                2,
                exc,
                json_out,
            )
        except MemoryError as exc:
            _fail("out of memory: the input is too large for this machine", 3, exc, json_out)
        except OSError as exc:
            name = f" '{exc.filename}'" if exc.filename else ""
            _fail(f"cannot access{name}: {exc.strerror or exc}", 3, exc, json_out)
        except Exception as exc:  # never a traceback for the user
            if os.environ.get("BALANCER_ID_DEBUG"):
                raise
            _fail(
                f"internal error {type(exc).__name__}: {exc} "
                "(rerun with BALANCER_ID_DEBUG=1 and report it)",
                1,
                exc,
                json_out,
            )

    return wrapper  # type: ignore[return-value]


def _floats(text: str | None, what: str) -> list[float] | None:
    from balancer_id.errors import UsageError

    if text is None:
        return None
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UsageError(f"{what} '{text}': give numbers separated by commas") from None


def _assignments(items: list[str] | None, what: str) -> dict[str, float]:
    from balancer_id.errors import UsageError

    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[name.strip()] = float(value)
        except ValueError:
            raise UsageError(f"{what} '{item}': expected NAME=VALUE, e.g. m_a=15.1") from None
    return out


def _read_options(
    thrust: str | None,
    force_sign: int | None,
    vertical: str,
    columns: str | None,
    g: float,
    accel_unit: str = "auto",
):
    from balancer_id.errors import UsageError
    from balancer_id.pipeline import ReadOptions

    if force_sign not in (None, 1, -1):
        raise UsageError("--force-sign must be +1 or -1")
    if vertical.lstrip("+-") not in ("auto", "x", "y", "z") or vertical in ("+auto", "-auto"):
        raise UsageError("--vertical must be auto or an axis with an optional sign: x, -z, +y")
    if not (math.isfinite(g) and g > 0):
        raise UsageError(f"--g {g}: gravity must be a positive number of m/s^2, e.g. 9.81")
    if accel_unit not in ("auto", "m/s^2", "g"):
        raise UsageError("--accel-unit must be auto, m/s^2 or g")
    cmap = None
    if columns:
        cmap = {}
        for item in columns.split(","):
            key, sep, value = item.partition("=")
            if not sep:
                raise UsageError(f"--columns '{item}': expected ROLE=COLUMN, e.g. time=t")
            cmap[key.strip()] = value.strip()
    return ReadOptions(
        columns=cmap,
        thrusts=_floats(thrust, "--thrust"),
        force_sign=force_sign,
        vertical=vertical,
        g=g,
        accel_unit=accel_unit,
    )


def _check_outputs(
    outputs: dict[str, Path | None], inputs: list[Path | str], overwrite: bool
) -> None:
    """Refuse, before any work, outputs that are inputs, exist (without --overwrite) or are
    read-only."""
    from balancer_id.files import check_output

    for option, path in outputs.items():
        if path is not None:
            check_output(path, inputs=inputs, overwrite=overwrite, option=option)


def _inputs(logs: list[Path], effects_file: list[Path] | None, trajectory: str | None = None):
    """Every file a command reads (an output may be none of them)."""
    files: list[Path | str] = [*logs, *(effects_file or ())]
    if trajectory and not trajectory.strip().startswith("trapezoid:"):
        files.append(trajectory)
    return files


def _at_least(value: int | float, low: int | float, option: str) -> None:
    from balancer_id.errors import UsageError

    if not (isinstance(value, int) or math.isfinite(value)) or value < low:
        raise UsageError(f"{option} {value}: give a number >= {low}")


def _trajectory(text: str | None):
    from balancer_id.errors import UsageError
    from balancer_id.simulate.inputs import parse_trajectory

    if text is None:
        return None
    if not text.startswith("trapezoid") and Path(text).is_file():  # time,position (issue 9)
        from balancer_id.segment.move import read_trajectory_csv

        return read_trajectory_csv(text)
    try:
        return parse_trajectory(text)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def _printable(obj: Any) -> Any:
    """``obj`` with control characters in every string made visible (``\x1b``), so a run
    or file name holding terminal escape sequences cannot drive the user's terminal."""
    if isinstance(obj, str):
        if obj.isprintable():
            return obj
        return "".join(ch if ch.isprintable() or ch == "\n" else repr(ch)[1:-1] for ch in obj)
    if isinstance(obj, dict):
        return {k: _printable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_printable(v) for v in obj]
    return obj


def _emit_json(obj: object) -> None:
    sys.stdout.write(json.dumps(obj, indent=2, allow_nan=False, default=str) + "\n")


def _console():
    from rich.console import Console

    return Console(width=max(100, Console().width))


# Commands -----------------------------------------------------------------------------
@app.command()
@guarded
def inspect(
    log: Annotated[Path, typer.Argument(help="The log to read.")],
    json_out: JsonOpt = False,
    plot: Annotated[Path | None, typer.Option("--plot", help="Draw the channels to a PNG.")] = None,
    thrust: ThrustOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = 9.8,
    accel_unit: AccelUnitOpt = "auto",
    trajectory: TrajectoryOpt = None,
    overwrite: OverwriteOpt = False,
) -> None:
    """Show what was read from LOG and the step trials (or the robot move) found in it."""
    from balancer_id.errors import NoTrialError
    from balancer_id.pipeline import describe_log, read, segment

    options = _read_options(thrust, force_sign, vertical, columns, g, accel_unit)
    _check_outputs({"--plot": plot}, [log], overwrite)
    data = read(log, options)
    try:
        trials = segment(data, options, _trajectory(trajectory))
        problem = None
    except NoTrialError as exc:
        trials, problem = [], exc
    info = describe_log(data, trials)
    if problem is not None:
        info["error"] = _error_record(_one_line(problem), problem.exit_code, problem)
    if plot is not None:
        from balancer_id.report.inspect_plot import plot_inspection

        plot_inspection(data, trials, plot, g=options.g, vertical=options.vertical)
    if json_out:
        _emit_json(info)
    else:
        print_inspection = __import__(
            "balancer_id.report.terminal", fromlist=["print_inspection"]
        ).print_inspection
        print_inspection(_console(), _printable(info))
    if problem is not None:
        typer.echo(f"balancer-id: error: {_one_line(problem)}", err=True)
        raise typer.Exit(problem.exit_code)


@app.command()
@guarded
def fit(
    logs: Annotated[list[Path], typer.Argument(help="One or more logs.")],
    model: ModelOpt = None,
    thrust: ThrustOpt = None,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    report: Annotated[
        Path | None, typer.Option("--report", help="Write FILE.html or FILE.pdf.")
    ] = None,
    per_trial: Annotated[
        bool, typer.Option("--per-trial", help="Also fit each trial alone.")
    ] = False,
    starts: Annotated[int, typer.Option("--starts", help="Optimizer starts.")] = 1,
    no_cache: Annotated[
        bool, typer.Option("--no-cache", help="Recompute even if this exact run is cached.")
    ] = False,
    effects_file: EffectsFileOpt = None,
    trajectory: TrajectoryOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = 9.8,
    accel_unit: AccelUnitOpt = "auto",
    params: Annotated[
        Path | None,
        typer.Option("--params", help="Hold the parameters of an earlier 'fit --json' output."),
    ] = None,
    overwrite: OverwriteOpt = False,
    group_by: Annotated[
        str | None,
        typer.Option("--group-by", help="run|log|runs:1-3,4-6: identify each group apart."),
    ] = None,
) -> None:
    """Identify the parameters of the model over all trials of all LOGS."""
    from balancer_id import cache

    fixed = _assignments(fix, "--fix")
    if params is not None:  # issue 9: hold an earlier fit's values; --fix wins
        from balancer_id.fit.params_file import held_for_model

        fixed = {**held_for_model(params, model, effects_file or ()), **fixed}
    _at_least(starts, 1, "--starts")
    options = _read_options(thrust, force_sign, vertical, columns, g, accel_unit)
    _check_outputs({"--report": report}, _inputs(logs, effects_file, trajectory), overwrite)
    if group_by is not None:
        _fit_groups(
            logs,
            group_by,
            options,
            model=model,
            fixed=fixed,
            effects_files=effects_file or (),
            trajectory=_trajectory(trajectory),
            per_trial=per_trial,
            n_starts=starts,
            json_out=json_out,
            report=report,
        )
        return
    key_options = {
        "model": model,
        "thrust": thrust,
        "fix": fixed,
        "per_trial": per_trial,
        "starts": starts,
        "trajectory": trajectory,
        "force_sign": force_sign,
        "vertical": vertical,
        "columns": columns,
        "g": g,
        "accel_unit": accel_unit,
        "logs": [str(p) for p in logs],
        "effects": [str(p) for p in effects_file or ()],
    }
    key = None if no_cache else cache.result_key("fit", [*logs, *(effects_file or ())], key_options)
    out = cache.load(key) if report is None else None
    if out is None:
        from balancer_id.fit import fit as run_fit

        result = run_fit(
            logs,
            model=model,
            fixed=fixed,
            options=options,
            effects_files=effects_file or (),
            trajectory=_trajectory(trajectory),
            per_trial=per_trial,
            n_starts=starts,
        )
        out = result.to_dict()
        if result.coupling is not None:  # issue 9: advice for the robot-balancer pair
            from balancer_id.diagnose.advice import advise_fit

            moves = [t.input for t in result.match.data.trials]
            out["advice"] = advise_fit(result.match.model, result.values, moves).to_dict()
        cache.store(key, out)
        if report is not None:
            from balancer_id.report.document import write_fit_report

            write_fit_report(result, report)
    if json_out:
        _emit_json(out)
    else:
        from balancer_id.report.terminal import print_fit

        print_fit(_console(), _printable(out))


def _fit_groups(logs, group_by, options, *, json_out, report, **kwargs) -> None:
    """``fit --group-by``: one identification per group of trials."""
    from balancer_id.errors import UsageError
    from balancer_id.fit import fit as run_fit
    from balancer_id.fit.api import trial_data
    from balancer_id.fit.data import group_trials

    if report is not None:
        raise UsageError("--report takes one model: give it without --group-by")
    trials, _ = trial_data(logs, options, kwargs["trajectory"])
    groups = group_trials(trials, group_by)
    out = {"group_by": group_by, "groups": []}
    for label, group in groups:
        out["groups"].append({"group": label, **run_fit(group, **kwargs).to_dict()})
    if json_out:
        _emit_json(out)
        return
    from balancer_id.report.terminal import print_fit

    console = _console()
    for item in out["groups"]:
        console.print(f"[bold]group {_printable(item['group'])}[/bold]")
        print_fit(console, _printable(item))


@app.command()
@guarded
def simulate(
    model: ModelOpt = None,
    param: Annotated[
        list[str] | None, typer.Option("--param", help="NAME=VALUE of the true model (repeatable).")
    ] = None,
    thrust: Annotated[str, typer.Option("--thrust", help="Thrusts in N, one run each.")] = (
        "2.45,-2.45,4.9,-4.9,7.35,-7.35"
    ),
    out: Annotated[Path, typer.Option("--out", help="The CSV to write (PASCO Capstone).")] = Path(
        "simulated.csv"
    ),
    noise: Annotated[float, typer.Option("--noise", help="Acceleration noise (m/s^2).")] = 0.03,
    force_noise: Annotated[float, typer.Option("--force-noise", help="Force noise (N).")] = 0.03,
    noise_correlation: Annotated[
        float, typer.Option("--noise-correlation", help="Lag-one correlation of the noise.")
    ] = 0.0,
    quantize: Annotated[bool, typer.Option("--quantize", help="Sensor resolution.")] = False,
    tilt: Annotated[float, typer.Option("--tilt", help="Sensor tilt (degrees).")] = 10.0,
    drop: Annotated[float, typer.Option("--drop", help="Fraction of samples dropped.")] = 0.0,
    rate: Annotated[float, typer.Option("--rate", help="Sample rate (Hz).")] = 200.0,
    rest: Annotated[float, typer.Option("--rest", help="Rest before each step (s).")] = 2.0,
    duration: Annotated[
        float, typer.Option("--duration", help="Motion after each step (s).")
    ] = 8.0,
    force_sign: Annotated[int, typer.Option("--force-sign", help="Sign of the force channel.")] = 1,
    seed: Annotated[int, typer.Option("--seed", help="Random seed.")] = 0,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing file.")
    ] = False,
    effects_file: EffectsFileOpt = None,
    trajectory: TrajectoryOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Write a synthetic log in PASCO Capstone CSV format (one run per thrust)."""
    from balancer_id.errors import UsageError
    from balancer_id.fit import resolve_model
    from balancer_id.simulate.synth import SensorSettings, write_synthetic_log

    mdl = resolve_model(model, effects_file or ())
    values = mdl.resolve(_assignments(param, "--param"))
    thrusts = _floats(thrust, "--thrust") or []
    if not thrusts:
        raise UsageError("--thrust: give at least one thrust")
    traj = _trajectory(trajectory)
    if mdl.has("servo") and traj is None:
        raise UsageError("a model with 'servo' needs --trajectory")
    if force_sign not in (1, -1):
        raise UsageError("--force-sign must be +1 or -1")
    if not 0.0 <= noise_correlation < 1.0:
        raise UsageError("--noise-correlation must be in [0, 1)")
    if not (math.isfinite(rate) and rate > 0):
        raise UsageError(f"--rate {rate}: give a sample rate > 0 Hz, e.g. 200")
    for option, value in (("--noise", noise), ("--force-noise", force_noise), ("--rest", rest)):
        _at_least(value, 0.0, option)
    if not (math.isfinite(duration) and duration > 0):
        raise UsageError(f"--duration {duration}: give the motion's length in s (> 0)")
    if not (math.isfinite(drop) and 0.0 <= drop < 1.0):
        raise UsageError(f"--drop {drop}: give the fraction of samples dropped, in [0, 1)")
    if not math.isfinite(tilt):
        raise UsageError(f"--tilt {tilt}: give the sensor's tilt in degrees")
    _check_outputs({"--out": out}, _inputs([], effects_file, trajectory), overwrite)
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
        _emit_json(info)
    else:
        typer.echo(f"wrote {out}: {len(recs)} runs of model {mdl.spec}", err=True)


@app.command()
@guarded
def compare(
    logs: Annotated[list[Path], typer.Argument(help="One or more logs.")],
    model: Annotated[
        str, typer.Option("--model", "-m", help="Models to compare: SPEC[,SPEC2...].")
    ] = "viscous,variable_viscosity",
    plot: Annotated[Path | None, typer.Option("--plot", help="Measured vs simulated PNG.")] = None,
    vibration_plot: Annotated[
        Path | None,
        typer.Option("--vibration-plot", help="With --trajectory: the moves' vibration PNG."),
    ] = None,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    thrust: ThrustOpt = None,
    effects_file: EffectsFileOpt = None,
    trajectory: TrajectoryOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = 9.8,
    accel_unit: AccelUnitOpt = "auto",
    overwrite: OverwriteOpt = False,
) -> None:
    """Measured vs simulated for several models: errors per trial and where each fails.

    With --trajectory it also sets the vibration of each log's move side by side
    (human against robot: band power around the coupled mode).
    """
    from balancer_id.diagnose import compare as run_compare
    from balancer_id.errors import UsageError

    specs = [m.strip() for m in model.split(",") if m.strip()]
    if not specs:
        raise UsageError(f"--model '{model}': give one or more models, e.g. viscous,karnopp")
    options = _read_options(thrust, force_sign, vertical, columns, g, accel_unit)
    _check_outputs(
        {"--plot": plot, "--vibration-plot": vibration_plot},
        _inputs(logs, effects_file, trajectory),
        overwrite,
    )
    results = run_compare(
        logs,
        specs,
        fixed=_assignments(fix, "--fix"),
        options=options,
        effects_files=effects_file or (),
        trajectory=_trajectory(trajectory),
    )
    out = {"models": [r.to_dict() for r in results]}
    if trajectory is not None:  # issue 9: the vibration of each move, side by side
        from balancer_id.diagnose.vibration import vibration_of_logs

        vib = vibration_of_logs(logs, options, _trajectory(trajectory))
        out["vibration"] = vib.to_dict()
        if vibration_plot is not None:
            from balancer_id.report.vibration_plot import plot_vibration

            plot_vibration(vib, vibration_plot)
    if plot is not None:
        from balancer_id.report.sections import plot_comparison

        plot_comparison(results, plot)
    if json_out:
        from balancer_id.jsonsafe import json_ready

        _emit_json(json_ready(out))
    else:
        from balancer_id.report.terminal import print_compare

        print_compare(_console(), _printable(out))


@app.command()
@guarded
def diagnose(
    logs: Annotated[list[Path], typer.Argument(help="One or more logs.")],
    model: ModelOpt = None,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    thrust: ThrustOpt = None,
    effects_file: EffectsFileOpt = None,
    trajectory: TrajectoryOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = 9.8,
    accel_unit: AccelUnitOpt = "auto",
) -> None:
    """Residual tests and ranked suggestions of missing effects."""
    from balancer_id.diagnose import diagnose as run_diagnose

    result = run_diagnose(
        logs,
        model=model,
        fixed=_assignments(fix, "--fix"),
        options=_read_options(thrust, force_sign, vertical, columns, g, accel_unit),
        effects_files=effects_file or (),
        trajectory=_trajectory(trajectory),
    )
    out = result.to_dict()
    if json_out:
        _emit_json(out)
    else:
        from balancer_id.report.terminal import print_diagnosis

        print_diagnosis(_console(), _printable(out))


@app.command()
@guarded
def improve(
    logs: Annotated[list[Path], typer.Argument(help="One or more logs.")],
    start: Annotated[
        str | None,
        typer.Option("--start", help="Model to start from (default variable_viscosity)."),
    ] = None,
    max_steps: Annotated[int, typer.Option("--max-steps", help="Effects to add at most.")] = 4,
    fix: FixOpt = None,
    json_out: JsonOpt = False,
    report: Annotated[Path | None, typer.Option("--report", help="FILE.html or FILE.pdf.")] = None,
    plot: Annotated[Path | None, typer.Option("--plot", help="The error ladder as PNG.")] = None,
    thrust: ThrustOpt = None,
    effects_file: EffectsFileOpt = None,
    trajectory: TrajectoryOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = 9.8,
    accel_unit: AccelUnitOpt = "auto",
    overwrite: OverwriteOpt = False,
) -> None:
    """Add effects one by one while the error falls and BIC and held-out trials improve."""
    from balancer_id.diagnose import improve as run_improve

    _at_least(max_steps, 0, "--max-steps")
    options = _read_options(thrust, force_sign, vertical, columns, g, accel_unit)
    _check_outputs(
        {"--report": report, "--plot": plot}, _inputs(logs, effects_file, trajectory), overwrite
    )
    if report is not None and plot is not None and Path(report).resolve() == Path(plot).resolve():
        from balancer_id.errors import UsageError

        raise UsageError("--report and --plot name the same file; give two names")
    result = run_improve(
        logs,
        start=start,
        fixed=_assignments(fix, "--fix"),
        options=options,
        effects_files=effects_file or (),
        trajectory=_trajectory(trajectory),
        max_steps=max_steps,
    )
    out = result.to_dict()
    if plot is not None:
        from balancer_id.report.plots import plot_error_ladder

        plot_error_ladder(out["steps"], plot)
    if report is not None:
        from balancer_id.report.sections import write_improve_report

        write_improve_report(result, report, inputs=logs)
    if json_out:
        _emit_json(out)
    else:
        from balancer_id.report.terminal import print_improve

        print_improve(_console(), _printable(out))


@app.command()
@guarded
def report(
    logs: Annotated[list[Path], typer.Argument(help="One or more logs.")],
    out: Annotated[Path, typer.Option("--out", help="FILE.html or FILE.pdf.")],
    model: ModelOpt = None,
    fix: FixOpt = None,
    thrust: ThrustOpt = None,
    effects_file: EffectsFileOpt = None,
    trajectory: TrajectoryOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = 9.8,
    accel_unit: AccelUnitOpt = "auto",
    overwrite: OverwriteOpt = False,
) -> None:
    """The full report: identification, paper's method, diagnosis and per-trial plots."""
    from balancer_id.report.sections import write_full_report

    options = _read_options(thrust, force_sign, vertical, columns, g, accel_unit)
    _check_outputs({"--out": out}, _inputs(logs, effects_file, trajectory), overwrite)
    write_full_report(
        logs,
        out,
        model=model,
        fixed=_assignments(fix, "--fix"),
        options=options,
        effects_files=effects_file or (),
        trajectory=_trajectory(trajectory),
    )
    typer.echo(f"wrote {out}", err=True)


@app.command()
@guarded
def batch(
    paths: Annotated[list[Path], typer.Argument(help="Logs or folders of logs.")],
    out: Annotated[
        Path, typer.Option("--out", help="Folder for summary.csv and one JSON per log.")
    ],
    model: ModelOpt = None,
    fix: FixOpt = None,
    jobs: Annotated[
        int | None, typer.Option("--jobs", help="Processes (default: all cores).")
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Dask scheduler address (or 'local').")
    ] = None,
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
    force_sign: ForceSignOpt = None,
    vertical: VerticalOpt = "auto",
    columns: ColumnsOpt = None,
    g: GOpt = 9.8,
    accel_unit: AccelUnitOpt = "auto",
    trajectory: TrajectoryOpt = None,
    resume: Annotated[
        bool,
        typer.Option("--resume", help="Keep results already in OUT for unchanged logs."),
    ] = False,
    overwrite: OverwriteOpt = False,
) -> None:
    """Identify many logs in parallel; summary.csv plus one JSON per log in OUT."""
    from balancer_id.batch import run_batch

    result = run_batch(
        paths,
        out,
        model=model,
        fixed=_assignments(fix, "--fix"),
        options=_read_options(None, force_sign, vertical, columns, g, accel_unit),
        effects_files=effects_file or (),
        jobs=jobs,
        scheduler=scheduler,
        progress=lambda msg: typer.echo(_one_line(msg), err=True),
        resume=resume,
        overwrite=overwrite,
        trajectory=_trajectory(trajectory),
    )
    if json_out:
        _emit_json(result.to_dict())
    else:
        typer.echo(
            f"{result.n_ok} identified, {result.n_failed} failed; summary in {result.summary_path}",
            err=True,
        )
    if result.exit_code:
        raise typer.Exit(result.exit_code)


@app.command()
@guarded
def effects(
    json_out: JsonOpt = False,
    effects_file: EffectsFileOpt = None,
) -> None:
    """List the effects available, built in and user-supplied, with their parameters."""
    from balancer_id.model.effects.base import Base
    from balancer_id.model.registry import default_registry

    registry = default_registry(effects_file or ())
    items = [{**Base.describe(), "origin": "built-in (always present)"}]
    items += [{**cls.describe(), "origin": registry.origin(cls.name)} for cls in registry]
    if json_out:
        _emit_json({"effects": items})
    else:
        from balancer_id.report.terminal import print_effects

        print_effects(_console(), _printable(items))


def main() -> None:
    """Entry point of the ``balancer-id`` console script.

    Usage errors (unknown option, a value of the wrong type) are one line on stderr with
    exit 2, like every other error, instead of click's framed box.
    """
    try:
        code = app(standalone_mode=False)
    except typer.Abort:
        typer.echo("balancer-id: error: interrupted", err=True)
        code = 130
    except Exception as exc:  # click's usage errors (typer vendors click in recent versions)
        if not (hasattr(exc, "format_message") and hasattr(exc, "exit_code")):
            raise
        ctx = getattr(exc, "ctx", None)
        if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
            typer.echo(ctx.get_help(), err=True)
        else:
            hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
            typer.echo(f"balancer-id: error: {_one_line(exc.format_message())}{hint}", err=True)
        code = exc.exit_code
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
