"""Options shared by the commands, declared once, and the parsing of their values.

The six options that say how logs are read (``--thrust``, ``--force-sign``,
``--vertical``, ``--columns``, ``--g``, ``--accel-unit``) are added to a command by
:func:`read_options`, which hands the command one checked
:class:`~balancer_id.trials.ReadOptions`.
"""

from __future__ import annotations

import functools
import inspect
import os
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer

from balancer_id.constants import G_DEFAULT

F = TypeVar("F", bound=Callable[..., Any])

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
    str, typer.Option("--vertical", help="auto|x|y|z: vertical axis of logs without gravity.")
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
TrajectoryOpt = Annotated[
    str | None,
    typer.Option(
        "--trajectory", help="Robot reference: 'trapezoid:distance=..,speed=..,accel=..'."
    ),
]
LogsArg = Annotated[list[Path], typer.Argument(help="One or more logs.")]

#: The reading options: name -> (annotation, default). ``thrust`` is left out of
#: commands that read many logs (``batch``).
READ_OPTIONS: dict[str, tuple[Any, Any]] = {
    "thrust": (ThrustOpt, None),
    "force_sign": (ForceSignOpt, None),
    "vertical": (VerticalOpt, "auto"),
    "columns": (ColumnsOpt, None),
    "g": (GOpt, G_DEFAULT),
    "accel_unit": (AccelUnitOpt, "auto"),
}


def read_options(*, thrust: bool = True) -> Callable[[F], F]:
    """Add the reading options to a command; it receives them as ``options: ReadOptions``.

    Parameters
    ----------
    thrust : bool
        Whether the command takes ``--thrust`` (one log's trial thrusts).

    Returns
    -------
    callable
        A decorator for a typer command with an ``options`` parameter.
    """

    def decorate(func: F) -> F:
        sig = inspect.signature(func)
        kept = [
            p.replace(annotation=_evaluated(p.annotation, func))
            for p in sig.parameters.values()
            if p.name != "options"
        ]
        names = [n for n in READ_OPTIONS if thrust or n != "thrust"]
        added = [
            inspect.Parameter(
                n,
                inspect.Parameter.KEYWORD_ONLY,
                default=READ_OPTIONS[n][1],
                annotation=READ_OPTIONS[n][0],
            )
            for n in names
        ]

        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            from balancer_id.trials import ReadOptions

            given = {n: kwargs.pop(n) for n in names if n in kwargs}
            kwargs["options"] = ReadOptions.from_text(**given)
            return func(*args, **kwargs)

        params = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY) for p in kept] + added
        wrapper.__signature__ = sig.replace(parameters=params)  # type: ignore[attr-defined]
        wrapper.__annotations__ = {p.name: p.annotation for p in params}
        del wrapper.__wrapped__  # typer reads the new signature, not the function's
        return wrapper  # type: ignore[return-value]

    return decorate


def _evaluated(annotation: Any, func: Callable[..., Any]) -> Any:
    """A string annotation (``from __future__ import annotations``) as its object."""
    if isinstance(annotation, str):
        return eval(annotation, func.__globals__)
    return annotation


def fail(message: str, code: int) -> None:
    """Print one error line and exit with ``code``.

    Parameters
    ----------
    message : str
        What went wrong (whitespace is folded onto one line).
    code : int
        The CONTRACT.md exit code.
    """
    typer.echo(f"balancer-id: error: {' '.join(str(message).split())}", err=True)
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

        try:
            return func(*args, **kwargs)
        except (typer.Exit, typer.Abort):
            raise
        except BalancerIdError as exc:
            fail(str(exc), exc.exit_code)
        except KeyboardInterrupt:
            fail("interrupted", 130)
        except Exception as exc:  # never a traceback for the user
            if os.environ.get("BALANCER_ID_DEBUG"):
                raise
            fail(
                f"internal error {type(exc).__name__}: {exc} "
                "(rerun with BALANCER_ID_DEBUG=1 and report it)",
                1,
            )

    return wrapper  # type: ignore[return-value]


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
    Trapezoid or None

    Raises
    ------
    UsageError
        When the text is malformed.
    """
    from balancer_id.errors import UsageError
    from balancer_id.simulation.inputs import parse_trajectory

    if text is None:
        return None
    try:
        return parse_trajectory(text)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
