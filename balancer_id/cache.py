"""A cache of command results, so re-running the same command on the same logs is instant.

The key is a SHA-256 over everything the result depends on: the bytes of every input
log and effects file, the command's options, and the source of the installed
balancer-id package itself (so a new version never serves an old result). Entries live
in ``$BALANCER_ID_CACHE/results`` (default ``~/.cache/balancer-id/results``); set
``BALANCER_ID_NO_CACHE=1`` or pass ``--no-cache`` to bypass it. Only plain JSON results
are cached; reports and plots are always made anew.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path
from typing import Any


def cache_root() -> Path:
    """``$BALANCER_ID_CACHE`` or ``~/.cache/balancer-id``."""
    root = os.environ.get("BALANCER_ID_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache"), "balancer-id"
    )
    return Path(root)


def enabled() -> bool:
    """Whether the result cache is on (``BALANCER_ID_NO_CACHE`` unset)."""
    return os.environ.get("BALANCER_ID_NO_CACHE", "") in ("", "0")


@lru_cache(maxsize=1)
def _package_fingerprint() -> str:
    h = hashlib.sha256()
    package = Path(__file__).resolve().parent
    for path in sorted(package.rglob("*.py")):
        h.update(path.relative_to(package).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def result_key(command: str, files: Iterable[str | Path], options: dict[str, Any]) -> str | None:
    """The cache key of a command's result, or None when an input cannot be read.

    Parameters
    ----------
    command : str
        Name of the command (``fit``, ``diagnose`` ...); results of different commands
        never share a key.
    files : iterable of str or Path
        Every file the result depends on (logs, effects files); their bytes are hashed,
        so an edited file gives a new key.
    options : dict
        The command's options; hashed as sorted JSON, values that are not JSON hashed
        through ``str``.

    Returns
    -------
    str or None
        The hex SHA-256 key, or None when one of ``files`` cannot be read (the result is
        then not cached).
    """
    h = hashlib.sha256()
    h.update(command.encode())
    h.update(_package_fingerprint().encode())
    h.update(json.dumps(options, sort_keys=True, default=str).encode())
    for f in files:
        try:  # a FIFO or a device is never opened here (it could block); the reader refuses it
            if not stat.S_ISREG(os.stat(f).st_mode):
                return None
            with open(f, "rb") as handle:  # streamed: the file is never whole in memory
                h.update(hashlib.file_digest(handle, "sha256").digest())
        except OSError:
            return None
    return h.hexdigest()


def load(key: str | None) -> dict[str, Any] | None:
    """A cached result, or None.

    Parameters
    ----------
    key : str or None
        A key from :func:`result_key`; None (an unreadable input) never hits.

    Returns
    -------
    dict or None
        The stored result, or None when the cache is off, holds no entry for ``key``, or
        the entry cannot be read.
    """
    if key is None or not enabled():
        return None
    path = cache_root() / "results" / f"{key}.json"
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def store(key: str | None, result: dict[str, Any]) -> None:
    """Keep a result (silently does nothing when the cache cannot be written).

    Parameters
    ----------
    key : str or None
        A key from :func:`result_key`; None stores nothing.
    result : dict
        The command's JSON-ready result. It is written to a temporary file and moved into
        place, so a concurrent reader never sees half an entry.
    """
    if key is None or not enabled():
        return
    folder = cache_root() / "results"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tmp = folder / f".{key}.{os.getpid()}.tmp"
        tmp.write_text(json.dumps(result), encoding="utf-8")
        os.replace(tmp, folder / f"{key}.json")
    except OSError:
        return
