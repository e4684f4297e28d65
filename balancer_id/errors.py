"""The error hierarchy of balancer-id.

Every error carries the exit code the command line uses (see CONTRACT.md) and a
one-line message that says what went wrong, where, and what to do.
"""

from __future__ import annotations

#: Exit code of a command whose fit ran but is not trusted (``"trusted": false``): the
#: output is written as usual, and a script sees that the values are no identification.
UNTRUSTED_EXIT_CODE = 5


class BalancerIdError(Exception):
    """Base class of every error balancer-id raises on purpose."""

    exit_code: int = 1

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message

    def __str__(self) -> str:  # one line, always
        return " ".join(self.message.split())


class UsageError(BalancerIdError):
    """A command was called with arguments that do not make sense (exit 2)."""

    exit_code = 2


class LogReadError(BalancerIdError):
    """A log cannot be read or is not valid (exit 3).

    The message names the file and, where known, the line or column.
    """

    exit_code = 3

    def __init__(
        self,
        path: object,
        problem: str,
        *,
        line: int | None = None,
        column: str | None = None,
        hint: str | None = None,
    ) -> None:
        where = str(path)
        if line is not None:
            where += f", line {line}"
        if column is not None:
            where += f", column '{column}'"
        text = f"{where}: {problem}"
        if hint:
            text += f" ({hint})"
        super().__init__(text)
        self.path = path
        self.line = line
        self.column = column


class ModelSpecError(UsageError):
    """A model specification names unknown or incompatible effects (exit 2)."""


class EffectError(BalancerIdError):
    """A user-supplied effect is malformed or failed while running (exit 2)."""

    exit_code = 2


class IdentificationError(BalancerIdError):
    """Identification is impossible: no trial, too few thrust levels, no convergence (exit 4)."""

    exit_code = 4


class NoTrialError(IdentificationError):
    """A log reads fine but holds no step trial (exit 4)."""


class OutputExistsError(UsageError):
    """An output file exists already and overwriting was not asked for (exit 2)."""


class OutputWriteError(BalancerIdError):
    """An output cannot be written: full disk, no permission, a read-only file (exit 3).

    Exit 3 as for a file that cannot be read: the file system refused, not the command line.
    """

    exit_code = 3


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
