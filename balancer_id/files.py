"""Ground-floor file utilities, each in one place: writing files safely (the one place
that decides whether an output may be written), the cache folder, importing a Python file
by its path.

Every file balancer-id writes (reports, plots, synthetic logs, batch results, cache
entries) goes through :func:`atomic_write`: a temporary file in the target's folder,
flushed to disk, then one ``os.replace``, so a reader never sees half a file and a
failure (full disk, Ctrl-C, SIGKILL) leaves the target as it was. Before anything is
computed, the commands call :func:`check_output` on each output path: an output that is
one of the inputs (same file, by inode, or the same path) is refused, an existing file is
replaced only when the user said ``--overwrite``, and a read-only file never.
"""

from __future__ import annotations

import contextlib
import errno
import importlib.util
import json
import os
import stat
import sys
import tempfile
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from types import ModuleType
from typing import IO

from balancer_id.errors import OutputExistsError, OutputWriteError, UsageError


def same_file(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` name the same file (same path or same inode), whether or
    not it exists yet.

    Parameters
    ----------
    a, b : Path
        The two paths.

    Returns
    -------
    bool
    """
    try:
        if a.resolve() == b.resolve():
            return True
    except (OSError, RuntimeError):  # RuntimeError: a symbolic link loop (Python < 3.13)
        pass
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_output(
    path: str | Path,
    *,
    inputs: Iterable[str | Path] = (),
    overwrite: bool = False,
    option: str = "output",
) -> Path:
    """Refuse an output path that would destroy something the user gave.

    Parameters
    ----------
    path : str or Path
        The file about to be written.
    inputs : iterable of str or Path
        Files the command reads (logs, effect files, trajectories, folders of logs): the
        output may be none of them.
    overwrite : bool
        Whether an existing file may be replaced (the user's ``--overwrite``).
    option : str
        How the user named the path (``--report``, ``--plot``), for the message.

    Returns
    -------
    Path
        ``path`` as a Path.

    Raises
    ------
    UsageError
        The folder does not exist, the path is a folder or a special file, or it is one of
        the inputs.
    OutputExistsError
        The file exists and ``overwrite`` is False, or it is read-only.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise UsageError(
            f"{option} '{path}': the folder '{parent}' does not exist; create it first"
        )
    for src in inputs:
        if same_file(Path(src), path):
            raise UsageError(
                f"{option} '{path}' is one of the inputs; writing it would destroy your data: "
                "give another file name"
            )
    if refusal := _not_replaceable(path):
        raise UsageError(f"{option} '{path}' {refusal}")
    if not os.path.lexists(path):
        return path
    if is_read_only(path):
        raise OutputExistsError(
            f"{option} '{path}' exists and is read-only; it is never replaced: give another name"
        )
    if not overwrite:
        raise OutputExistsError(
            f"{option} '{path}' exists already; add --overwrite to replace it, or give another name"
        )
    return path


def _not_replaceable(path: Path) -> str | None:
    """Why ``path`` may never be replaced by an output (a folder, a symbolic link, a device,
    a pipe), or None when it is a regular file or does not exist.

    ``os.replace`` replaces a link itself, not the file it names: ``--save /dev/stdout``
    run as root would turn ``/dev/stdout`` into a plain file. A link is refused, whatever
    it points at (a loop included).
    """
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    except OSError as exc:
        return f"cannot be checked ({exc.strerror or exc}); give another file name"
    if stat.S_ISLNK(st.st_mode):
        return "is a symbolic link; links are never replaced: give the file's own name"
    if stat.S_ISDIR(st.st_mode):
        return "is a folder; give a file name"
    if not stat.S_ISREG(st.st_mode):
        return "is not a regular file (a device or a pipe); give a file name"
    return None


def _umask() -> int:
    """The process's umask, read without changing it where the system allows."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def is_read_only(path: str | Path) -> bool:
    """Whether ``path`` is read-only: no write permission bit, or not writable by us.

    The permission bits count even for a superuser, who could write anyway: a file made
    read-only says "keep this".

    Parameters
    ----------
    path : str or Path
        An existing file.

    Returns
    -------
    bool
    """
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not (mode & 0o222) or not os.access(path, os.W_OK)


def atomic_write(path: str | Path, write: Callable[[IO[bytes]], object]) -> Path:
    """Write a file whole or not at all.

    ``write`` fills a temporary file in the target's folder, which is flushed to disk and
    then replaces the target in one ``os.replace``; on any error (including a full disk or
    an interrupt) the temporary file is removed and the target is left as it was. A
    read-only target is never replaced.

    Parameters
    ----------
    path : str or Path
        The file to write.
    write : callable
        Called with the open binary temporary file.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    UsageError
        The folder does not exist or the target is a folder.
    OutputWriteError
        The disk is full or the folder not writable (with what to do).
    OutputExistsError
        The target exists and is read-only.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise UsageError(f"cannot write '{path}': the folder '{parent}' does not exist")
    if refusal := _not_replaceable(path):
        raise UsageError(f"cannot write '{path}': it {refusal.removeprefix('is ')}")
    if path.exists() and is_read_only(path):
        raise OutputExistsError(f"'{path}' is read-only; it is never replaced: give another name")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=parent)
    except OSError as exc:
        raise _write_error(path, exc) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, path.stat().st_mode & 0o777 if path.exists() else 0o666 & ~_umask())
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise _write_error(path, exc) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` whole or not at all (see :func:`atomic_write`).

    Parameters
    ----------
    path : str or Path
        The file to write.
    text : str
        Its content.

    Returns
    -------
    Path
        ``path``.
    """
    data = text.encode("utf-8")
    return atomic_write(path, lambda fh: fh.write(data))


def _write_error(path: Path, exc: OSError) -> OutputWriteError:
    """A one-line error for an OSError met while writing ``path``."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        what = "the disk is full; free some space or write elsewhere"
    elif exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        what = "permission denied; choose a folder you can write to"
    else:
        what = f"{exc.strerror or exc}"
    return OutputWriteError(f"cannot write '{path}': {what}")


def cache_root() -> Path:
    """The cache folder: ``$BALANCER_ID_CACHE``, else ``$XDG_CACHE_HOME/balancer-id``, else
    ``~/.cache/balancer-id`` (compiled kernels and cached results live below it).

    Returns
    -------
    Path
    """
    root = os.environ.get("BALANCER_ID_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache"), "balancer-id"
    )
    return Path(root)


def private_folder(folder: Path) -> str | None:
    """Create ``folder`` private (0700) and check it; the reason it cannot be trusted, or None.

    Compiled kernels are Python code run by import and numba's cache holds pickles, cached
    results are read back: a folder that someone else can write, or a symbolic link that
    someone else may point elsewhere, would let them run code as the user or plant results.
    ``folder`` and every folder between it and :func:`cache_root` (included) must be real
    folders (not links), owned by the user and writable by nobody else.

    Parameters
    ----------
    folder : Path
        The folder to create (with its parents) and check.

    Returns
    -------
    str or None
        None when the folder is safe to use, else why not (one phrase naming the folder).
    """
    root = cache_root()
    try:
        if root in folder.parents:  # every folder from the root down private, not by umask
            root.mkdir(mode=0o700, parents=True, exist_ok=True)
            for part in reversed([p for p in folder.parents if root in p.parents]):
                part.mkdir(mode=0o700, exist_ok=True)
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError as exc:
        return f"cannot create {folder}: {exc.strerror or exc}"
    chain = [folder]
    if folder != root and root in folder.parents:
        chain += [p for p in folder.parents if p == root or root in p.parents]
    for path in chain:
        try:
            st = os.lstat(path)
        except OSError as exc:
            return f"cannot read {path}: {exc.strerror or exc}"
        if stat.S_ISLNK(st.st_mode):
            return f"{path} is a symbolic link (remove it; the cache must be a real folder)"
        if not stat.S_ISDIR(st.st_mode):
            return f"{path} is not a folder"
        if hasattr(os, "getuid") and st.st_uid != os.getuid():
            return f"{path} belongs to another user"
        if st.st_mode & 0o022:
            return f"{path} is writable by others (chmod 700 it)"
    return None


def import_path(name: str, path: str | Path) -> ModuleType:
    """Import the Python file ``path`` as the module ``name`` (once per process).

    Parameters
    ----------
    name : str
        The module name to register in ``sys.modules``; an already imported module of
        that name is returned as is.
    path : str or Path
        The ``.py`` file.

    Returns
    -------
    module

    Raises
    ------
    ImportError
        When the file cannot be imported as a module.
    Exception
        Whatever running the file raises; the half-imported module is then removed from
        ``sys.modules``.
    """
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"{path}: cannot be imported as a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        # what the file prints while it is imported goes to stderr: stdout carries --json
        with contextlib.redirect_stdout(sys.stderr):
            spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def check_outputs(
    outputs: Mapping[str, str | Path | None], inputs: Iterable[Path | str], overwrite: bool
) -> None:
    """Refuse, before any work, outputs that are inputs, exist (without --overwrite) or are
    read-only.

    Parameters
    ----------
    outputs : mapping of str to str, Path or None
        Option name -> the file it names (None: not given).
    inputs : iterable of Path or str
        Every file the command reads.
    overwrite : bool
        ``--overwrite``.
    """
    inputs = list(inputs)
    given = [(option, Path(path)) for option, path in outputs.items() if path is not None]
    for i, (option, path) in enumerate(given):
        for other, other_path in given[:i]:
            if same_file(path, other_path):
                raise UsageError(
                    f"{other} and {option} name the same file '{path}'; one would replace "
                    "the other: give two names"
                )
        check_output(path, inputs=inputs, overwrite=overwrite, option=option)


def inputs_of(
    logs: Iterable[str | Path],
    effects_file: Iterable[str | Path] | None,
    trajectory_text: str | None = None,
) -> list[Path | str]:
    """Every file a command reads (an output may be none of them).

    Parameters
    ----------
    logs : iterable of str or Path
        The logs.
    effects_file : iterable of str or Path, or None
        ``--effects-file`` paths.
    trajectory_text : str, optional
        ``--trajectory`` (a file unless it is a ``trapezoid:`` spec).

    Returns
    -------
    list of Path or str
    """
    files: list[Path | str] = [*logs, *(effects_file or ())]
    if trajectory_text and not trajectory_text.strip().startswith("trapezoid:"):
        files.append(trajectory_text)
    return files


def emit_json(obj: object) -> None:
    """Print one JSON object on stdout.

    Parameters
    ----------
    obj : object
        JSON-ready data.

    Raises
    ------
    OutputWriteError
        When stdout is closed or cannot take the text (a full disk): exit 3, one line.
    """
    text = json.dumps(obj, indent=2, allow_nan=False, default=str) + "\n"
    if sys.stdout is None:
        raise OutputWriteError("cannot print the JSON: stdout is closed; redirect it to a file")
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:
        raise
    except (OSError, ValueError) as exc:
        _stdout_to_null()  # the interpreter's last flush must not fail again
        why = getattr(exc, "strerror", None) or str(exc)
        raise OutputWriteError(f"cannot print the JSON on stdout: {why}") from None


def _stdout_to_null() -> None:
    """Point stdout's file descriptor at the null device (and drop what is buffered)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass
