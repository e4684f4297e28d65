"""What a command is doing, on stderr, while it takes time.

Shown only when stderr is a terminal and ``--quiet`` was not given; nothing else is ever
written by it, so pipes, redirections and ``--json`` stay clean.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator

#: Set by the global ``--quiet`` option.
QUIET = False


def enabled() -> bool:
    """Whether progress is shown (stderr is a terminal and not ``--quiet``).

    Returns
    -------
    bool
    """
    return not QUIET and sys.stderr.isatty()


@contextlib.contextmanager
def stage(text: str) -> Iterator[None]:
    """Show ``text`` with a spinner on stderr while the block runs.

    Parameters
    ----------
    text : str
        What is being done ("fitting variable_viscosity to 2 logs").

    Yields
    ------
    None
    """
    if not enabled():
        yield
        return
    from rich.console import Console

    with Console(stderr=True).status(text, spinner="dots"):
        yield
