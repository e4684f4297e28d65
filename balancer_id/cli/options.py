"""Options shared by the commands, declared once, and the parsing of their values.

The options that say how logs are read (``--thrust``, ``--force-sign``, ``--vertical``,
``--columns``, ``--g``, ``--accel-unit``, ``--window``, ``--force-delay``) are declared once,
in :data:`balancer_id.trials.READ_OPTION_SPELLINGS`; :func:`reads_logs` gives them to a
command, which receives one checked :class:`~balancer_id.trials.ReadOptions`. Every option
names its value in words (``metavar``: TEXT, FILE, NUMBER...); a flag names none (see
:class:`Command`).
"""

from __future__ import annotations

import functools
import inspect
import os
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from typer.core import TyperCommand, TyperGroup

from balancer_id.cli import progress
from balancer_id.errors import error_record
from balancer_id.files import emit_json
from balancer_id.text import one_line

F = TypeVar("F", bound=Callable[..., Any])


class Command(TyperCommand):
    """A command whose help shows no value type for a flag (``--json``, ``--help``).

    Typer >= 0.28 labels every option with its Python type, a flag too (``<bool>``); an
    option's ``metavar`` replaces the label, so a flag gets an empty one. The options that
    take a value give their own (``metavar="FILE"``).
    """

    def get_params(self, ctx: Any) -> list[Any]:
        """The command's parameters (``ctx``: its click context), flags without a label."""
        return _flags_unlabelled(super().get_params(ctx))


class Group(TyperGroup):
    """The command group, its flags (``--version``, ``--help``) without a value label."""

    def get_params(self, ctx: Any) -> list[Any]:
        """The group's parameters (``ctx``: its click context), flags without a label."""
        return _flags_unlabelled(super().get_params(ctx))


def _flags_unlabelled(params: list[Any]) -> list[Any]:
    for param in params:
        if getattr(param, "is_flag", False) and param.metavar is None:
            param.metavar = ""
    return params


def Opt(flag: str, metavar: str | None, help: str, *aliases: str) -> Any:
    """An option's declaration, on one line of a command's signature.

    Parameters
    ----------
    flag : str
        The option (``--report``).
    metavar : str or None
        What its value is, in words (``FILE``); None for a flag.
    help : str
        One line of help.
    *aliases : str
        Other spellings (``-m``).

    Returns
    -------
    typer.models.OptionInfo
    """
    return typer.Option(flag, *aliases, metavar=metavar, help=help)


ModelOpt = Annotated[
    str | None, Opt("--model", "TEXT", "Effects joined by '+' (default variable_viscosity).", "-m")
]
EffectsFileOpt = Annotated[
    list[Path] | None, Opt("--effects-file", "FILE...", "A .py file of user effects (repeatable).")
]
QuietOpt = Annotated[bool, Opt("--quiet", None, "No progress on stderr (no spinner, no per-log "
                                                "lines); warnings and errors stay.", "-q")]
JsonOpt = Annotated[bool, Opt("--json", None, "Print one JSON object on stdout.")]
FixOpt = Annotated[
    list[str] | None, Opt("--fix", "TEXT...", "Hold a parameter: NAME=VALUE (repeatable).")
]
OverwriteOpt = Annotated[
    bool, Opt("--overwrite", None, "Replace output files that exist (never an input).")
]
TrajectoryOpt = Annotated[str | None, Opt("--trajectory", "TEXT", "Robot reference: "
                                          "'trapezoid:distance=..,speed=..,accel=..[,start=..]' "
                                          "or a CSV of time,position.")]
SeriesOpt = Annotated[
    Path | None, Opt("--series", "FILE", "Write time, measured, simulated, residual to FILE.csv.")
]
LogsArg = Annotated[list[Path], typer.Argument(metavar="LOGS", help="One or more logs.")]


def reads_logs(func: F | None = None, *, thrust: bool = True) -> Any:
    """Give a command the reading options, declared once; it gets them as one object.

    The command declares a keyword-only parameter ``options: ReadOptions``; its ``--help``
    lists instead every option of :data:`~balancer_id.trials.READ_OPTION_SPELLINGS` (after
    its own), and it is called with their values made into one checked
    :class:`~balancer_id.trials.ReadOptions` (a bad value fails first, exit 2).

    Parameters
    ----------
    func : callable, optional
        The command (``@reads_logs``), or None (``@reads_logs(thrust=False)``).
    thrust : bool
        Whether the command takes ``--thrust`` (``batch`` reads many logs: it does not).

    Returns
    -------
    callable
        The command with the reading options in its signature (or the decorator).
    """
    if func is None:
        return functools.partial(reads_logs, thrust=thrust)
    from balancer_id.trials import READ_OPTION_SPELLINGS, ReadOptions

    spellings = [s for s in READ_OPTION_SPELLINGS if thrust or s.name != "thrust"]
    own = inspect.signature(func, eval_str=True)
    params = [p for p in own.parameters.values() if p.name != "options"]
    params += [
        inspect.Parameter(
            s.name,
            inspect.Parameter.KEYWORD_ONLY,
            default=s.default,
            annotation=Annotated[s.kind, typer.Option(s.flag, metavar=s.metavar, help=s.help)],
        )
        for s in spellings
    ]

    @functools.wraps(func)
    def command(*args: Any, **kwargs: Any) -> Any:
        values = {s.name: kwargs.pop(s.name) for s in spellings if s.name in kwargs}
        return func(*args, options=ReadOptions.from_text(**values), **kwargs)

    command.__signature__ = own.replace(parameters=params)  # type: ignore[attr-defined]
    command.__annotations__ = {p.name: p.annotation for p in params}
    return command


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
