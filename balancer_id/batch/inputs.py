"""What a batch reads: the logs found in the paths given, the output folder's lock,
and the results a resumed batch keeps.
"""

from __future__ import annotations

import json
import os
import stat
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from balancer_id.batch.rows import (
    INTERNAL_EXIT_CODE,
    BatchRow,
    _Task,
    take_fit,
)
from balancer_id.errors import UsageError

if TYPE_CHECKING:
    from balancer_id.trials import ReadOptions

#: How a batch's own ``summary.csv`` starts; such files in an input folder are skipped.
_SUMMARY_SIGNATURE = "file,status,error,exit_code,"


def request_key(
    path: str,
    spec: str,
    fixed: Mapping[str, float] | None,
    options: ReadOptions | None,
    effects_files: Sequence[str],
    trajectory: Any = None,
    diagnose: bool = False,
) -> str | None:
    """What one log's result depends on: its bytes, the model, the options, the effects.

    Parameters
    ----------
    path : str
        The log.
    spec : str
        The model spec.
    fixed : mapping, optional
        Parameters held at known values.
    options : ReadOptions, optional
        Reading and segmentation options.
    effects_files : sequence of str
        User effect files (their bytes count too).
    trajectory : Trapezoid or TabulatedMove, optional
        A robot's reference move (counts when given).
    diagnose : bool
        Whether the result holds a diagnosis (counts when true).

    Returns
    -------
    str or None
        A SHA-256 key (see :func:`balancer_id.cache.result_key`), or None when a file
        cannot be read.
    """
    from balancer_id.cache import result_key

    request: dict[str, Any] = {"model": spec, "fixed": dict(fixed or {}), "options": repr(options)}
    if trajectory is not None:
        request["trajectory"] = _trajectory_digest(trajectory)
    if diagnose:
        request["diagnose"] = True
    return result_key("batch", [path, *effects_files], request)


def _trajectory_digest(trajectory: Any) -> str:
    """A reference move as key material: a table by its values (numpy's repr elides the
    middle of a long array, so two tables could share a repr), a trapezoid by its repr."""
    import hashlib

    import numpy as np

    time = getattr(trajectory, "time", None)
    position = getattr(trajectory, "position", None)
    if isinstance(time, np.ndarray) and isinstance(position, np.ndarray):
        h = hashlib.sha256()
        for arr in (time, position):
            h.update(np.ascontiguousarray(arr, dtype=float).tobytes())
        start = (getattr(trajectory, "start", None), getattr(trajectory, "start_given", None))
        return f"table:{h.hexdigest()}:{start!r}"
    return repr(trajectory)


def _resumed_row(task: _Task, key: str | None) -> BatchRow | None:
    """The row of a result already written for the same request, or None."""
    if key is None:
        return None
    try:
        doc = json.loads(task.output.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or key not in (doc.get("request"), doc.get("request_fit")):
        return None
    row = BatchRow(
        file=task.display,
        status=str(doc.get("status", "failed")),
        model=str(doc.get("model", "")),
        seconds=doc.get("seconds"),
        json=str(task.output),
    )
    if row.status == "ok":
        take_fit(row, doc)
    else:
        row.error = str(doc.get("error", "failed"))
        row.exit_code = int(doc.get("exit_code") or INTERNAL_EXIT_CODE)
    return row


def _is_regular(path: Path) -> bool:
    try:
        return stat.S_ISREG(path.stat().st_mode)
    except OSError:
        return True  # let the reader say why it cannot be read


def _irregular(display: str) -> str:
    """Why a path that is not a regular file is not a log."""
    if Path(display).is_dir():
        return f"{display}: a folder that cannot be listed (permission?); check its access rights"
    return f"{display}: not a regular file (a pipe or a device); give a CSV file"


#: Lock file that keeps two batches from writing into one folder.
LOCK_NAME = ".balancer-id-batch.lock"


@contextmanager
def _folder_lock(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``out`` (refuse at once when another batch holds it)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    path = out / LOCK_NAME
    try:  # never through a symlink planted in the folder; the lock file stays (race-free)
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
    except OSError as exc:
        why = "its lock is a symbolic link" if path.is_symlink() else exc.strerror
        raise UsageError(f"--out {out}: cannot write into the folder ({why})") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or (hasattr(os, "getuid") and info.st_uid != os.getuid()):
        os.close(fd)
        raise UsageError(
            f"--out {out}: its lock file {LOCK_NAME} is not a plain file of yours; remove it "
            "or give another --out"
        )
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            raise UsageError(
                f"--out {out}: another batch (process {holder}) is writing into this folder; "
                "wait for it to finish, or give another --out"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        try:
            yield
        finally:  # the file stays: unlinking a held lock lets two batches lock two inodes
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def collect_logs(paths: Iterable[str | Path], out_dir: str | Path | None = None) -> list[Path]:
    """The logs that ``paths`` stand for: files as given, folders expanded.

    Parameters
    ----------
    paths : iterable of path
        Files (kept as given, whatever their suffix) and folders (the ``.csv`` files
        below them, recursively and sorted; hidden files and folders, and the
        ``summary.csv`` of earlier batches, skipped).
    out_dir : path, optional
        A folder never to descend into (the batch's output).

    Returns
    -------
    list of Path
        In order, each log once (duplicates by resolved path dropped).

    Raises
    ------
    UsageError
        No log at all.
    """
    skip = Path(out_dir).resolve() if out_dir is not None else None
    found: list[Path] = []
    seen: set[Path] = set()
    given = [Path(p) for p in paths]
    for path in given:
        for log in _expand(path, skip) if path.is_dir() else [path]:
            key = log.resolve()
            if key not in seen:
                seen.add(key)
                found.append(log)
    if not found:
        where = ", ".join(str(p) for p in given) or "(nothing given)"
        raise UsageError(f"no log found in {where}: give CSV files or folders that hold them")
    return found


def _expand(folder: Path, skip: Path | None) -> list[Path]:
    """The CSV files below ``folder``; a subfolder that cannot be listed is returned as an
    entry of its own, so that it becomes a failed row instead of vanishing."""
    logs = []
    unreadable: list[Path] = []

    def onerror(exc: OSError) -> None:
        if exc.filename is not None:
            unreadable.append(Path(exc.filename))

    for root, dirs, names in os.walk(folder, onerror=onerror):
        base = Path(root)
        dirs[:] = [
            d
            for d in dirs
            if not d.startswith(".") and (skip is None or (base / d).resolve() != skip)
        ]
        logs += [
            base / n
            for n in names
            if n.lower().endswith(".csv") and not n.startswith(".") and not _is_summary(base / n)
        ]
    found = sorted(logs, key=lambda p: p.relative_to(folder).parts)
    return found + [p for p in unreadable if p != folder or not found]


def _is_summary(path: Path) -> bool:
    """Whether a CSV is the ``summary.csv`` of an earlier batch (not a log)."""
    if not _is_regular(path):  # never open a pipe or a device: it could block
        return False
    try:
        with path.open(encoding="utf-8", errors="replace") as handle:
            head = handle.readline(200)
    except OSError:
        return False
    return head.startswith(_SUMMARY_SIGNATURE)


def _check_out_dir(out: Path, given: Sequence[str | Path], logs: Sequence[Path]) -> None:
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: is a file; give a folder for the results")
    target = out.resolve()
    for path in [*map(Path, given), *logs]:
        resolved = path.resolve()
        if resolved == target or target in resolved.parents:
            raise UsageError(
                f"--out {out}: holds the input {path}; write the results into another folder"
            )


#: The longest result name's stem in bytes: file systems allow 255 bytes a name, and the
#: ``_2``, ``.json`` and temporary-file parts need room.
_MAX_STEM_BYTES = 160


def _result_stem(log: Path) -> str:
    """The stem of ``log``'s result file: control characters made ``_``, and a stem too long
    for the file system cut, with 8 hex digits of its hash to keep it apart."""
    import hashlib

    stem = "".join(ch if ch.isprintable() else "_" for ch in (log.stem or "log"))
    raw = os.fsencode(stem)
    if len(raw) <= _MAX_STEM_BYTES:
        return stem
    digest = hashlib.sha256(raw).hexdigest()[:8]
    cut = raw[: _MAX_STEM_BYTES - 9].decode("utf-8", "ignore")  # never half a character
    return f"{cut}_{digest}"


def _output_names(logs: Sequence[Path]) -> list[str]:
    """``<stem>.json`` per log; later logs with a taken stem get ``_2``, ``_3``, ...; a stem
    with control characters or too long for the file system is made safe (see
    :func:`_result_stem`)."""
    taken: set[str] = set()
    names = []
    for log in logs:
        stem = _result_stem(log)
        name, k = stem, 2
        while name.lower() in taken:
            name, k = f"{stem}_{k}", k + 1
        taken.add(name.lower())
        names.append(f"{name}.json")
    return names


def check_own_outputs(outputs: Iterable[Path], out: Path, replace: bool) -> None:
    """Refuse to write over a file this batch did not write (a user's own file).

    A per-log result of balancer-id is a JSON object with ``file`` and ``request``; any
    other file (or a symbolic link) at an output's name is refused by name, whatever the
    options. A result of an earlier batch is replaced only with ``replace``
    (``--resume`` or ``--overwrite``).

    Parameters
    ----------
    outputs : iterable of Path
        The per-log JSON files the batch will write.
    out : Path
        The output folder (for the message).
    replace : bool
        Whether results of an earlier batch may be replaced.

    Raises
    ------
    OutputExistsError
        Naming the first file that may not be written.
    """
    from balancer_id.errors import OutputExistsError

    for path in outputs:
        if path.is_symlink():
            raise OutputExistsError(
                f"--out {out}: {path.name} is a symbolic link; batch never writes through one "
                "(remove it or give another --out)"
            )
        if not path.exists():
            continue
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            doc = None
        ours = isinstance(doc, dict) and "file" in doc and "request" in doc
        if not ours:
            raise OutputExistsError(
                f"--out {out}: {path.name} is not a result of balancer-id and would be "
                "replaced by a log's result; move it away or give another --out"
            )
        if not replace:
            raise OutputExistsError(
                f"--out {out} holds the results of an earlier batch ({path.name}); add "
                "--resume to keep them and fit only what is missing or changed, or "
                "--overwrite to replace them"
            )
