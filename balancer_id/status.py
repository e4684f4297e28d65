"""What a long computation is doing now, told to whoever shows it.

The analysis layers call :func:`tell` at the steps a user waits for ("candidate 3/7:
karnopp"); nothing happens unless a listener is set. The command line sets one with
:func:`listening` while its spinner runs, so the library itself never prints.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

_listener: Callable[[str], None] | None = None


def tell(text: str) -> None:
    """Pass ``text`` to the current listener, if any.

    Parameters
    ----------
    text : str
        What is being done now, short ("candidate 3/7: karnopp").
    """
    if _listener is not None:
        _listener(text)


@contextlib.contextmanager
def listening(listener: Callable[[str], None]) -> Iterator[None]:
    """Send what :func:`tell` says to ``listener`` while the block runs.

    Parameters
    ----------
    listener : callable
        Called with each text; the previous listener is restored on exit.

    Yields
    ------
    None
    """
    global _listener
    previous, _listener = _listener, listener
    try:
        yield
    finally:
        _listener = previous


@contextlib.contextmanager
def step(text: str) -> Iterator[None]:
    """Tell ``text`` and put it before whatever is told inside the block.

    ``with step("step 2: +karnopp"): tell("candidate 3/5: bias")`` shows
    ``step 2: +karnopp, candidate 3/5: bias``.

    Parameters
    ----------
    text : str
        The outer step.

    Yields
    ------
    None
    """
    outer = _listener
    if outer is None:
        yield
        return
    outer(text)
    with listening(lambda inner: outer(f"{text}, {inner}")):
        yield
