"""A cache of command results, so re-running the same command on the same logs is instant.

The key is a SHA-256 over everything the result depends on: the bytes of every input
log and effects file, the command's options, and the source of the installed
balancer-id package itself (so a new version never serves an old result). Entries live
in ``$BALANCER_ID_CACHE/results`` (default ``~/.cache/balancer-id/results``); set
``BALANCER_ID_NO_CACHE=1`` or pass ``--no-cache`` to bypass it. Only plain JSON results
are cached, read back as objects (:mod:`balancer_id.records`); reports and plots are
always made anew.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
from collections.abc import Iterable
from functools import lru_cache, partial
from pathlib import Path
from typing import Any, TypeVar

from balancer_id.errors import BalancerIdError
from balancer_id.files import atomic_write_text, cache_root, private_folder
from balancer_id.records import ResultRecord

R = TypeVar("R", bound=ResultRecord)

#: Version of the entry layout; entries of another version are recomputed.
SCHEMA = 2
#: Bytes hashed at a time (a log is never held in memory whole for its key).
_CHUNK = 1 << 20


def enabled() -> bool:
    """Whether the result cache is on (``BALANCER_ID_NO_CACHE`` unset)."""
    return os.environ.get("BALANCER_ID_NO_CACHE", "") in ("", "0")


def _plugin_sources() -> list[Path]:
    """The source files of the effects installed by other packages (entry-point group
    ``balancer_id.effects``): a changed plug-in must not be served an old result."""
    from importlib.metadata import entry_points
    from importlib.util import find_spec

    files: list[Path] = []
    for ep in entry_points(group="balancer_id.effects"):
        try:
            spec = find_spec(ep.module)
        except (ImportError, ValueError):
            continue
        if spec is None or not spec.origin or not os.path.isfile(spec.origin):
            continue
        origin = Path(spec.origin)
        # a package's plug-in may keep its constants in sibling modules: hash them all
        files += sorted(origin.parent.rglob("*.py")) if origin.name == "__init__.py" else [origin]
    return files


@lru_cache(maxsize=1)
def _package_fingerprint() -> str:
    h = hashlib.sha256()
    package = Path(__file__).resolve().parent
    for path in sorted(package.rglob("*.py")):
        h.update(path.relative_to(package).as_posix().encode())
        h.update(path.read_bytes())
    for path in _plugin_sources():
        h.update(str(path).encode())
        try:
            h.update(path.read_bytes())
        except OSError:
            h.update(b"unreadable")
    return h.hexdigest()


def result_key(command: str, files: Iterable[str | Path], options: dict[str, Any]) -> str | None:
    """The cache key of a command's result, or None when an input cannot be read.

    Parameters
    ----------
    command : str
        Name of the command (``fit``, ``diagnose`` ...); results of different commands
        never share a key.
    files : iterable of str or Path
        Every file the result depends on (logs, effects files); their bytes are hashed in
        chunks (never held in memory whole), so an edited file gives a new key.
    options : dict
        The command's options; hashed as sorted JSON, values that are not JSON hashed
        through ``str``.

    Returns
    -------
    str or None
        The hex SHA-256 key, or None when one of ``files`` is not a regular file or cannot
        be read (the result is then not cached).
    """
    h = hashlib.sha256()
    h.update(command.encode())
    h.update(_package_fingerprint().encode())
    h.update(json.dumps(options, sort_keys=True, default=str).encode())
    for f in files:
        try:
            if not stat.S_ISREG(os.stat(f).st_mode):
                return None
            with open(f, "rb") as fh:
                for chunk in iter(partial(fh.read, _CHUNK), b""):
                    h.update(chunk)
        except OSError:
            return None
    return h.hexdigest()


def _results_dir(create: bool) -> Path | None:
    """The private folder of cached results, or None when it is unsafe or cannot be made.

    The folder is created 0700; one that others may write to is never used (anyone who can
    write it could plant results).
    """
    folder = cache_root() / "results"
    if not create and not folder.is_dir():
        return None
    return folder if private_folder(folder) is None else None


def _checksum(result: Any) -> str:
    return hashlib.sha256(json.dumps(result, sort_keys=True).encode()).hexdigest()


def load(key: str | None, kind: type[R] = ResultRecord) -> R | None:  # type: ignore[assignment]
    """A cached result, read back as an object, or None.

    An entry is served only when it is whole and unaltered: it must hold the schema
    version, its key and a SHA-256 of its result. A corrupted entry is deleted and the
    result is recomputed.

    Parameters
    ----------
    key : str or None
        A key from :func:`result_key`; None (an unreadable input) never hits.
    kind : type of ResultRecord
        What the result is read back as (:class:`~balancer_id.records.FitRecord` for a
        fit): the object a fresh result of the command is shown from.

    Returns
    -------
    ResultRecord or None
        The stored result (its ``to_dict()`` the JSON stored), or None when the cache is
        off, holds no valid entry for ``key``, or is unsafe (writable by others).
    """
    if key is None or not enabled():
        return None
    folder = _results_dir(create=False)
    if folder is None:
        return None
    path = folder / f"{key}.json"
    try:
        entry = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, ValueError):
        entry = None
    valid = (
        isinstance(entry, dict)
        and entry.get("schema") == SCHEMA
        and entry.get("key") == key
        and isinstance(entry.get("result"), dict)
        and entry.get("sha256") == _checksum(entry["result"])
    )
    if not valid:
        path.unlink(missing_ok=True)
        return None
    return kind.from_dict(entry["result"])


def store(key: str | None, result: ResultRecord | dict[str, Any]) -> None:
    """Keep a result (silently does nothing when the cache cannot be written).

    Parameters
    ----------
    key : str or None
        A key from :func:`result_key`; None stores nothing.
    result : ResultRecord or dict
        The command's result (its JSON-ready ``to_dict()``). It is stored with its key,
        the schema version and a checksum, written whole or not at all.
    """
    if key is None or not enabled():
        return
    if isinstance(result, ResultRecord):
        result = result.to_dict()
    folder = _results_dir(create=True)
    if folder is None:
        return
    entry = {"schema": SCHEMA, "key": key, "sha256": _checksum(result), "result": result}
    try:
        atomic_write_text(folder / f"{key}.json", json.dumps(entry))
    except (OSError, BalancerIdError):
        return
