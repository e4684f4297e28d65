"""What a command is doing, on stderr, while it takes time (a spinner; a bar for batch).

Shown only when stderr is a terminal and ``--quiet`` was not given; nothing else is ever
written by it, so pipes, redirections and ``--json`` stay clean.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from typing import Any

from balancer_id.text import one_line

#: Set by ``--quiet`` (``-q``), given before the command or after it.
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

    What the analysis tells (:func:`balancer_id.status.tell`, "candidate 3/7: karnopp")
    is shown after ``text`` as it happens.

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

    from balancer_id.status import listening

    with (
        Console(stderr=True).status(text, spinner="dots") as shown,
        listening(lambda now: shown.update(f"{text}: {now}")),
    ):
        yield


@contextlib.contextmanager
def batch_progress(
    echo: Callable[[str], None],
) -> Iterator[tuple[Callable[[str], None], Callable[[int, int], None] | None]]:
    """A ``(say, tick)`` pair for :func:`balancer_id.batch.run_batch`.

    On a terminal, ``tick`` drives a rich progress bar (logs done, rate in logs per
    second, time left) and ``say`` prints each line above it. When stderr is not a
    terminal (a pipe, a file, CI) there is no bar: ``say`` is ``echo`` and ``tick`` None.

    Parameters
    ----------
    echo : callable
        Prints one line on stderr (used when there is no bar).

    Yields
    ------
    tuple
        ``(say, tick)``.
    """
    if QUIET:  # --quiet: no line per log (the summary line and summary.csv say it all)
        yield (lambda message: None), None
        return
    if not enabled():  # anything read from a file (names, headers) is shown, not obeyed
        yield (lambda message: echo(one_line(message))), None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        ProgressColumn,
        TextColumn,
        TimeRemainingColumn,
    )
    from rich.text import Text

    class _Rate(ProgressColumn):
        def render(self, task: Any) -> Text:
            speed = task.finished_speed or task.speed
            return Text("" if speed is None else f"{speed:.1f} logs/s")

    progress = Progress(
        TextColumn("logs"),
        BarColumn(),
        MofNCompleteColumn(),
        _Rate(),
        TextColumn("left"),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=True,
    )
    task = progress.add_task("batch", total=None)
    started = [False]

    def tick(done: int, total: int) -> None:
        if not started[0]:  # logs kept by --resume do not count in the rate
            started[0] = True
            progress.update(task, total=total, completed=done)
            progress.reset(task, total=total, completed=done)
        else:
            progress.update(task, total=total, completed=done)

    def say(message: str) -> None:
        progress.console.print(one_line(message), markup=False, highlight=False, soft_wrap=True)

    with progress:
        yield say, tick
