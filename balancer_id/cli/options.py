"""Options shared by the commands, declared once, and the parsing of their values.

The seven options that say how logs are read (``--thrust``, ``--force-sign``,
``--vertical``, ``--columns``, ``--g``, ``--accel-unit``, ``--window``) are declared by each
command that reads logs, and turned into one checked :class:`~balancer_id.trials.ReadOptions`
by :func:`read_options`. Every option names its value in words (``metavar``: TEXT, FILE,
NUMBER...); a flag names none (see :class:`Command`).
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
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

import typer
from typer.core import TyperCommand, TyperGroup

from balancer_id.cli import progress
from balancer_id.cli.progress import one_line

if TYPE_CHECKING:
    from balancer_id.trials import ReadOptions

F = TypeVar("F", bound=Callable[..., Any])



class Command(TyperCommand):
    """A command whose help shows no value type for a flag (``--json``, ``--help``).

    Typer >= 0.28 labels every option with its Python type, a flag too (``<bool>``); an
    option's ``metavar`` replaces the label, so a flag gets an empty one. The options that
    take a value give their own (``metavar="FILE"``).
    """

    def get_params(self, ctx: Any) -> list[Any]:
        """The command's parameters, each flag without a value label.

        Parameters
        ----------
        ctx : click.Context
            The command's context.

        Returns
        -------
        list of click.Parameter
        """
        return _flags_unlabelled(super().get_params(ctx))


class Group(TyperGroup):
    """The command group, its flags (``--version``, ``--install-completion``, ``--help``)
    without a value label (see :class:`Command`)."""

    def get_params(self, ctx: Any) -> list[Any]:
        """The group's parameters, each flag without a value label.

        Parameters
        ----------
        ctx : click.Context
            The group's context.

        Returns
        -------
        list of click.Parameter
        """
        return _flags_unlabelled(super().get_params(ctx))


def _flags_unlabelled(params: list[Any]) -> list[Any]:
    for param in params:
        if getattr(param, "is_flag", False) and param.metavar is None:
            param.metavar = ""
    return params


ModelOpt = Annotated[
    str | None,
    typer.Option(
        "--model", "-m", metavar="TEXT", help="Effects joined by '+' (default variable_viscosity)."
    ),
]
EffectsFileOpt = Annotated[
    list[Path] | None,
    typer.Option(
        "--effects-file", metavar="FILE...", help="A .py file of user effects (repeatable)."
    ),
]
ThrustOpt = Annotated[
    str | None,
    typer.Option(
        "--thrust", metavar="TEXT", help="Thrust of each trial in N, e.g. 2.45,-4.9 (one log)."
    ),
]
ForceSignOpt = Annotated[
    int | None,
    typer.Option(
        "--force-sign", metavar="INTEGER", help="+1 or -1: fix the sign of the force channel."
    ),
]
VerticalOpt = Annotated[
    str,
    typer.Option(
        "--vertical", metavar="TEXT", help="auto|x|y|z|-z|...: up axis of logs without gravity."
    ),
]
ColumnsOpt = Annotated[
    str | None,
    typer.Option(
        "--columns", metavar="TEXT", help="Column map of a generic CSV: time=t,force=F,ax=..."
    ),
]
GOpt = Annotated[float, typer.Option("--g", metavar="NUMBER", help="Gravity in m/s^2.")]
AccelUnitOpt = Annotated[
    str,
    typer.Option(
        "--accel-unit", metavar="TEXT", help="auto|m/s^2|g: unit of the acceleration columns."
    ),
]
ForceDelayOpt = Annotated[
    float,
    typer.Option(
        "--force-delay",
        metavar="SECONDS",
        help="The force channel's lag behind the acceleration (s; diagnose measures it).",
    ),
]
WindowOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--window",
        metavar="TEXT...",
        help="START:END in s: a stretch where only the measured force acts (repeatable); "
        "each is a trial, nothing is detected (a lab rig).",
    ),
]
QuietOpt = Annotated[
    bool,
    typer.Option(
        "--quiet", "-q", help="No progress on stderr (no spinner, no per-log lines); warnings "
        "and errors stay."
    ),
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")]
FixOpt = Annotated[
    list[str] | None,
    typer.Option("--fix", metavar="TEXT...", help="Hold a parameter: NAME=VALUE (repeatable)."),
]
OverwriteOpt = Annotated[
    bool,
    typer.Option("--overwrite", help="Replace output files that exist (never an input)."),
]
TrajectoryOpt = Annotated[
    str | None,
    typer.Option(
        "--trajectory",
        metavar="TEXT",
        help="Robot reference: 'trapezoid:distance=..,speed=..,accel=..[,start=..]' or a "
        "CSV of time,position.",
    ),
]
LogsArg = Annotated[list[Path], typer.Argument(metavar="LOGS", help="One or more logs.")]


def read_options(
    thrust: str | None,
    force_sign: int | None,
    vertical: str,
    columns: str | None,
    g: float,
    accel_unit: str,
    window: list[str] | None,
    force_delay: float = 0.0,
) -> ReadOptions:
    """The reading options of a command (its ``--thrust`` ... ``--window``), checked.

    Each command that reads logs declares the seven options itself (:data:`ThrustOpt` ...
    :data:`WindowOpt`, as its last parameters; ``batch`` has no ``--thrust``) and passes
    their values here, in this order.

    Parameters
    ----------
    thrust : str or None
        ``--thrust``: thrusts in N separated by commas.
    force_sign : int or None
        ``--force-sign``.
    vertical : str
        ``--vertical``.
    columns : str or None
        ``--columns``: ``ROLE=COLUMN`` pairs.
    g : float
        ``--g``.
    accel_unit : str
        ``--accel-unit``.
    window : list of str or None
        ``--window`` (repeatable).
    force_delay : float
        ``--force-delay``.

    Returns
    -------
    ReadOptions

    Raises
    ------
    UsageError
        A malformed value or one out of its range (the message names the option).
    """
    from balancer_id.trials import ReadOptions

    return ReadOptions.from_text(
        thrust=thrust,
        force_sign=force_sign,
        vertical=vertical,
        columns=columns,
        g=g,
        accel_unit=accel_unit,
        window=window,
        force_delay=force_delay,
    )


def error_record(line: str, code: int, exc: BaseException | None) -> dict[str, object]:
    """The ``error`` object of ``--json`` output: kind, message, exit code, where.

    Parameters
    ----------
    line : str
        The one-line message.
    code : int
        The exit code.
    exc : BaseException or None
        The error (its ``file`` or ``path``, ``line`` and ``column`` when it has them).

    Returns
    -------
    dict
    """
    file = getattr(exc, "file", None) or getattr(exc, "path", None)  # LogReadError: path
    return {
        "kind": type(exc).__name__ if exc is not None else "Error",
        "message": line,
        "exit_code": code,
        "file": None if file is None else str(file),
        "line": getattr(exc, "line", None),
        "column": getattr(exc, "column", None),
    }


def emit_json(obj: object) -> None:
    """Print one JSON object on stdout.

    Parameters
    ----------
    obj : object
        JSON-ready data.

    Raises
    ------
    OutputWriteError
        When stdout is closed or cannot take the text (a full disk): exit 3, one line.
    """
    from balancer_id.errors import OutputWriteError

    text = json.dumps(obj, indent=2, allow_nan=False, default=str) + "\n"
    if sys.stdout is None:
        raise OutputWriteError("cannot print the JSON: stdout is closed; redirect it to a file")
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:
        raise
    except (OSError, ValueError) as exc:
        _stdout_to_null()  # the interpreter's last flush must not fail again
        why = getattr(exc, "strerror", None) or str(exc)
        raise OutputWriteError(f"cannot print the JSON on stdout: {why}") from None


def _stdout_to_null() -> None:
    """Point stdout's file descriptor at the null device (and drop what is buffered)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass


def fail(
    message: str, code: int, exc: BaseException | None = None, json_out: bool = False
) -> None:
    """Print one error line (and the ``--json`` error object) and exit with ``code``.

    Parameters
    ----------
    message : str
        What went wrong (whitespace is folded onto one line).
    code : int
        The CONTRACT.md exit code.
    exc : BaseException, optional
        The error, for the ``--json`` record.
    json_out : bool
        Also print ``{"error": ...}`` on stdout.
    """
    from balancer_id.errors import OutputWriteError

    line = one_line(message)
    typer.echo(f"balancer-id: error: {line}", err=True)
    if json_out:
        try:
            emit_json({"error": error_record(line, code, exc)})
        except (OutputWriteError, BrokenPipeError):
            pass  # stdout is what failed: the line on stderr says it
    raise typer.Exit(code)


def guarded(func: F) -> F:
    """Turn library errors into one-line messages and CONTRACT.md exit codes.

    Parameters
    ----------
    func : callable
        A command.

    Returns
    -------
    callable
        The command, never raising a traceback at the user (set ``BALANCER_ID_DEBUG=1``
        to see one).
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from balancer_id.errors import BalancerIdError

        json_out = bool(kwargs.get("json_out"))
        if kwargs.get("quiet"):
            progress.QUIET = True
        try:
            with warnings.catch_warnings():
                # numpy's floating-point RuntimeWarnings mean nothing to a user; what matters
                # is said as findings and warnings of the results
                warnings.filterwarnings("ignore", category=RuntimeWarning)
                return func(*args, **kwargs)
        except (typer.Exit, typer.Abort):
            raise
        except BalancerIdError as exc:
            fail(str(exc), exc.exit_code, exc, json_out)
        except KeyboardInterrupt as exc:
            fail("interrupted", 130, exc, json_out)
        except BrokenPipeError:
            closed_pipe()
        except SystemExit as exc:
            if isinstance(exc.__context__, BrokenPipeError):  # rich's answer to a closed pipe
                closed_pipe()
            if not _raised_by_user_code(exc):
                raise
            fail(
                f"a user effects file called sys.exit({exc.code!r}) while loading or running; "
                "effects must not exit: remove the call",
                2,
                exc,
                json_out,
            )
        except MemoryError as exc:
            fail("out of memory: the input is too large for this machine", 3, exc, json_out)
        except OSError as exc:
            name = f" '{exc.filename}'" if exc.filename else ""
            fail(f"cannot access{name}: {exc.strerror or exc}", 3, exc, json_out)
        except Exception as exc:  # never a traceback for the user
            if isinstance(exc, RuntimeError) and str(exc).startswith("Symlink loop"):
                # pathlib's answer to a link that leads back to itself (before Python 3.13)
                fail(f"{exc}: a symbolic link that leads back to itself; give the real file",
                     3, exc, json_out)
            if os.environ.get("BALANCER_ID_DEBUG"):
                raise
            fail(
                f"internal error {type(exc).__name__}: {exc} "
                "(rerun with BALANCER_ID_DEBUG=1 and report it)",
                1,
                exc,
                json_out,
            )

    return wrapper  # type: ignore[return-value]


#: The exit status of a writer whose reader closed the pipe (128 + SIGPIPE), as ``head``
#: expects of ``yes``.
CLOSED_PIPE_EXIT = 141


def closed_pipe() -> None:
    """Stop quietly: the reader of stdout (``| head``) closed the pipe.

    stdout is pointed at the null device so that the interpreter's final flush cannot fail
    again; nothing is printed.
    """
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    raise typer.Exit(CLOSED_PIPE_EXIT)


def _raised_by_user_code(exc: BaseException) -> bool:
    """Whether ``exc`` was raised in a file outside balancer-id and the installed libraries
    (a user's effects file)."""
    import sysconfig

    ours = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    libraries = {sysconfig.get_paths()[k] for k in ("stdlib", "purelib", "platlib")}
    tb = exc.__traceback__
    while tb is not None:
        name = os.path.abspath(tb.tb_frame.f_code.co_filename)
        tb = tb.tb_next
        if name.startswith(ours) or any(name.startswith(lib) for lib in libraries):
            continue
        if not name.startswith("<"):
            return True
    return False


def check_outputs(
    outputs: dict[str, Path | None], inputs: list[Path | str], overwrite: bool
) -> None:
    """Refuse, before any work, outputs that are inputs, exist (without --overwrite) or are
    read-only.

    Parameters
    ----------
    outputs : dict of str to Path or None
        Option name -> the file it names (None: not given).
    inputs : list of Path or str
        Every file the command reads.
    overwrite : bool
        ``--overwrite``.
    """
    from balancer_id.errors import UsageError
    from balancer_id.files import check_output, same_file

    given = [(option, Path(path)) for option, path in outputs.items() if path is not None]
    for i, (option, path) in enumerate(given):
        for other, other_path in given[:i]:
            if same_file(path, other_path):
                raise UsageError(
                    f"{other} and {option} name the same file '{path}'; one would replace "
                    "the other: give two names"
                )
        check_output(path, inputs=inputs, overwrite=overwrite, option=option)


def inputs_of(
    logs: list[Path], effects_file: list[Path] | None, trajectory_text: str | None = None
) -> list[Path | str]:
    """Every file a command reads (an output may be none of them).

    Parameters
    ----------
    logs : list of Path
        The logs.
    effects_file : list of Path or None
        ``--effects-file`` paths.
    trajectory_text : str, optional
        ``--trajectory`` (a file unless it is a ``trapezoid:`` spec).

    Returns
    -------
    list of Path or str
    """
    files: list[Path | str] = [*logs, *(effects_file or ())]
    if trajectory_text and not trajectory_text.strip().startswith("trapezoid:"):
        files.append(trajectory_text)
    return files


def at_least(value: int | float, low: int | float, option: str) -> None:
    """Refuse a number below ``low`` (or not finite).

    Parameters
    ----------
    value : int or float
        The option's value.
    low : int or float
        The smallest value allowed.
    option : str
        The option's name, for the message.

    Raises
    ------
    UsageError
        When ``value`` is below ``low`` or not finite.
    """
    from balancer_id.errors import UsageError

    if not (isinstance(value, int) or math.isfinite(value)) or value < low:
        raise UsageError(f"{option} {value}: give a number >= {low}")


def printable(obj: Any) -> Any:
    """``obj`` with control characters in every string made visible (``\\x1b``), so a run
    or file name holding terminal escape sequences cannot drive the user's terminal.

    Parameters
    ----------
    obj : object
        JSON-like data.

    Returns
    -------
    object
        The same structure, strings escaped.
    """
    if isinstance(obj, str):
        if obj.isprintable():
            return obj
        return "".join(ch if ch.isprintable() or ch == "\n" else repr(ch)[1:-1] for ch in obj)
    if isinstance(obj, dict):
        return {k: printable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [printable(v) for v in obj]
    return obj


def floats(text: str | None, what: str) -> list[float] | None:
    """Numbers separated by commas, or None.

    Parameters
    ----------
    text : str or None
        The option's value.
    what : str
        The option's name, for the error message.

    Returns
    -------
    list of float or None

    Raises
    ------
    UsageError
        When an item is not a number.
    """
    from balancer_id.errors import UsageError

    if text is None:
        return None
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UsageError(f"{what} '{text}': give numbers separated by commas") from None


def assignments(items: list[str] | None, what: str) -> dict[str, float]:
    """``NAME=VALUE`` items as a dict.

    Parameters
    ----------
    items : list of str or None
        The repeated option's values.
    what : str
        The option's name, for the error message.

    Returns
    -------
    dict of str to float

    Raises
    ------
    UsageError
        When an item is not ``NAME=NUMBER``.
    """
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


def trajectory(text: str | None) -> Any:
    """The ``--trajectory`` reference move, or None.

    Parameters
    ----------
    text : str or None
        ``trapezoid:distance=..,speed=..,accel=..[,start=..]``.

    Returns
    -------
    Trapezoid, TabulatedMove or None

    Raises
    ------
    UsageError
        When the text is malformed.
    """
    if text is None:  # before any import: a batch's start waits for this
        return None
    from balancer_id.trials import reference_move

    return reference_move(text)
