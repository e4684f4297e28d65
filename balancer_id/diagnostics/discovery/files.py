"""Writing a discovery as a user effect file, never over a file of the user's."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from balancer_id.diagnostics.discovery.result import Discovery
from balancer_id.diagnostics.discovery.settings import (
    MARKER,
)
from balancer_id.diagnostics.discovery.terms import effect_name
from balancer_id.files import atomic_write_text

if TYPE_CHECKING:
    pass


def check_effects_out(
    path: str | Path, *, inputs: Sequence[str | Path] = (), overwrite: bool = False
) -> Path:
    """Refuse, before any work, an ``--effects-out`` that could destroy a file of the user's.

    Parameters
    ----------
    path : str or Path
        The ``.py`` file to write.
    inputs : sequence of str or Path
        Files the command reads (never written).
    overwrite : bool
        ``--overwrite``: a file an earlier ``--discover`` wrote may be replaced.

    Returns
    -------
    Path

    Raises
    ------
    UsageError
        Not a ``.py`` name, a missing folder, or one of the inputs.
    OutputExistsError
        The file exists and is the user's, or ``overwrite`` is not given.
    """
    from balancer_id.errors import UsageError
    from balancer_id.files import check_output

    path = Path(path)
    if path.suffix != ".py":
        raise UsageError(f"--effects-out '{path}': give a Python file name ending in .py")
    if path.exists():
        _check_ours(path, overwrite)
    return check_output(path, inputs=inputs, overwrite=True, option="--effects-out")


def _check_ours(path: Path, overwrite: bool) -> None:
    """Refuse an existing file unless an earlier ``--discover`` wrote it and ``overwrite``."""
    from balancer_id.errors import OutputExistsError

    first = ""
    try:
        with path.open(encoding="utf-8") as fh:
            first = fh.readline().strip()
    except (OSError, UnicodeDecodeError):
        pass
    if first != MARKER:
        raise OutputExistsError(
            f"--effects-out '{path}' exists and was not written by balancer-id: it is never "
            "replaced; give another name"
        )
    if not overwrite:
        raise OutputExistsError(
            f"--effects-out '{path}' exists already; add --overwrite to replace it, or "
            "give another name"
        )


def write_effect(
    discovery: Discovery, path: str | Path, *, evidence: str = "", overwrite: bool = False
) -> tuple[Path, str]:
    """Write the discovered effect to ``path`` and return its effect name.

    A file that exists is never replaced unless it was written by ``improve --discover``
    (its first line is :data:`MARKER`) and ``overwrite`` is given.

    Parameters
    ----------
    discovery : Discovery
    path : str or Path
        The ``.py`` file.
    evidence : str
        A line of evidence for the docstring.
    overwrite : bool
        Replace a file this command wrote before.

    Returns
    -------
    tuple
        The path and the effect's name.

    Raises
    ------
    OutputExistsError
        When the file exists and is the user's (or ``overwrite`` is not given).
    """
    path = Path(path)
    if path.exists():
        _check_ours(path, overwrite)
    name = effect_name(path)
    atomic_write_text(path, discovery.effect_source(name, evidence))
    return path, name
