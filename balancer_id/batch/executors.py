"""Where the logs are fitted: a pool of worker processes with crash isolation, or Dask.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from balancer_id.batch.rows import Payload, _crashed, _internal
from balancer_id.errors import UsageError

if TYPE_CHECKING:
    pass

#: What a forkserver imports once, so forked workers start with it loaded: the fitting
#: stack, and the kernels of the models the batch names (see :mod:`.preload`).
_PRELOAD = ("balancer_id.batch.preload",)


#: Each worker process runs one BLAS/OpenMP thread: the pool is the parallelism (and
#: the fits' small matrices run faster on one thread anyway). A value the user set wins.
_THREAD_ENV = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: Worker processes start as ``python -c ...``, which puts the working folder first on
#: ``sys.path``: a ``multiprocessing.py`` or ``json.py`` lying there would run as the
#: user. ``PYTHONSAFEPATH`` (Python 3.11) keeps it off.
_SAFE_PATH_ENV = "PYTHONSAFEPATH"


_DASK_HINT = "pip install 'balancer-id[dask]'"


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Within, SIGTERM (and SIGHUP) stops the batch as Ctrl-C does (main thread only)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: object) -> None:
        raise KeyboardInterrupt(f"stopped by signal {signum}")

    saved = {}
    for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None:
            saved[sig] = signal.signal(sig, stop)
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def available_cpus() -> int:
    """CPUs this process may run on (``os.cpu_count()`` narrowed by CPU affinity).

    Returns
    -------
    int
        At least 1.
    """
    counter = getattr(os, "process_cpu_count", None)  # Python 3.13
    if counter is not None:
        return counter() or 1
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):
        return os.cpu_count() or 1


@contextmanager
def _interrupt_ignored() -> Iterator[None]:
    """Processes started inside ignore Ctrl-C from their first instruction.

    Ctrl-C reaches the whole process group; the fork server (and the resource tracker it
    starts) would take it while Python starts up and print a traceback. An ignored signal
    stays ignored across ``exec`` and Python then installs no handler of its own; the fork
    server ignores it anyway once loaded, and its workers inherit that. The batch itself
    stops the workers. Starting the server takes milliseconds: a Ctrl-C in that window is
    lost (the next one stops the batch). Main thread only.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, saved)


@contextmanager
def _safe_path() -> Iterator[None]:
    """Processes started inside never import from the working folder (``PYTHONSAFEPATH``)."""
    if os.environ.get(_SAFE_PATH_ENV):
        yield
        return
    os.environ[_SAFE_PATH_ENV] = "1"
    try:
        yield
    finally:
        os.environ.pop(_SAFE_PATH_ENV, None)


@contextmanager
def _one_thread_env() -> Iterator[None]:
    """Processes started inside inherit one BLAS/OpenMP thread (unless the user chose)
    and never import from the working folder (``PYTHONSAFEPATH``)."""
    added = [name for name in (*_THREAD_ENV, _SAFE_PATH_ENV) if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


def _mp_context(
    models: Sequence[str] = (), *, diagnose: bool = False, trajectory: bool = False
) -> Any:
    """``forkserver`` with the fitting code preloaded where available, else ``spawn``.

    The fork server is launched now (when not running yet), so it imports the fitting
    code and loads the kernels of ``models`` (compiling what numba's disk cache lacks)
    while this process does other work; it then serves every later pool. A server
    already running keeps what it loaded; workers load anything else on first use.

    Parameters
    ----------
    models : sequence of str
        Model specs (built-in or installed effects only) whose kernels the server loads.
    diagnose : bool
        Load the diagnosis and the kernels of the models' candidates too.
    trajectory : bool
        Whether the batch has a robot reference move (which candidates are tried).
    """
    import json
    import multiprocessing

    from balancer_id.batch.preload import ENV

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    from multiprocessing import forkserver

    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(_PRELOAD))
    saved = os.environ.get(ENV)
    os.environ[ENV] = json.dumps(
        {"models": list(models), "diagnose": diagnose, "trajectory": trajectory}
    )
    try:
        with _one_thread_env(), _interrupt_ignored():
            forkserver.ensure_running()
    except OSError:  # the pool will try again, and report
        pass
    finally:
        if saved is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = saved
    return ctx


@_safe_path()  # the pool's helpers (resource tracker) start before any submit
def run_in_processes(
    func: Callable[[Any], Payload],
    items: Sequence[tuple[int, Any]],
    record: Callable[[int, Payload], None],
    jobs: int,
    *,
    context: Any = None,
    notify: Callable[[str], None] | None = None,
) -> None:
    """Call ``func(arg)`` for each ``(key, arg)`` in a process pool; ``record`` each result.

    A worker that dies (killed, out of memory, a crash in native code) breaks the whole
    pool. Results that arrived are kept; the items that did not finish run again, each
    in a process of its own (``jobs`` at a time), so a crash fails only its own item.

    Parameters
    ----------
    func : callable
        A picklable function returning a payload (``{"status": ...}``).
    items : sequence of (key, argument)
        The work.
    record : callable
        ``record(key, payload)``, called in this process as each result arrives.
    jobs : int
        Worker processes.
    context : multiprocessing context, optional
        How workers start (default: see :func:`_mp_context`).
    notify : callable, optional
        Told, in one line, when a worker died and the rest run one process each.
    """
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    ctx = context or _mp_context()
    retry: list[tuple[int, Any]] = []
    broken = False
    pool = ProcessPoolExecutor(
        max_workers=min(jobs, len(items)),
        mp_context=ctx,
        initializer=_die_with_parent,
        initargs=(os.getpid(),),
    )
    try:
        futures = {}
        with _one_thread_env():  # workers start on submit
            for n, (key, arg) in enumerate(items):
                try:
                    futures[pool.submit(func, arg)] = (key, arg)
                except BrokenProcessPool:
                    broken = True
                    retry += items[n:]
                    break
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                key, arg = futures[fut]
                try:
                    payload = fut.result()
                except BrokenProcessPool:
                    broken = True
                    retry.append((key, arg))
                    continue
                except Exception as exc:  # e.g. a result that cannot be pickled
                    payload = _internal(exc)
                record(key, payload)
    except BaseException:
        _stop_workers(pool)
        raise
    finally:
        if broken:  # a broken pool's manager thread can deadlock on a join (CPython 3.11)
            _stop_workers(pool)
        pool.shutdown(wait=not broken, cancel_futures=True)
    if retry:
        if notify is not None:
            notify(
                f"a worker process died; {len(retry)} unfinished item(s) run again, "
                "one process each"
            )
        _run_isolated(func, sorted(retry, key=lambda item: item[0]), record, jobs, ctx)


def _run_isolated(
    func: Callable[[Any], Payload],
    items: Sequence[tuple[int, Any]],
    record: Callable[[int, Payload], None],
    jobs: int,
    ctx: Any,
) -> None:
    """One single-worker pool per item, ``jobs`` at a time: a crash fails one item."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    queue = deque(items)
    active: dict[Any, tuple[int, ProcessPoolExecutor]] = {}
    try:
        while queue or active:
            while queue and len(active) < jobs:
                key, arg = queue.popleft()
                pool = ProcessPoolExecutor(
                    max_workers=1,
                    mp_context=ctx,
                    initializer=_die_with_parent,
                    initargs=(os.getpid(),),
                )
                with _one_thread_env():
                    active[pool.submit(func, arg)] = (key, pool)
            done, _ = wait(list(active), return_when=FIRST_COMPLETED)
            for fut in done:
                key, pool = active.pop(fut)
                try:
                    payload = fut.result()
                except BrokenProcessPool:
                    payload = _crashed("the worker process died while on this item")
                except Exception as exc:
                    payload = _internal(exc)
                pool.shutdown(wait=True)
                record(key, payload)
    except BaseException:
        for _, pool in active.values():
            _stop_workers(pool)
        raise
    finally:
        for _, pool in active.values():
            pool.shutdown(wait=True, cancel_futures=True)


def _die_with_parent(batch_pid: int) -> None:
    """Worker initializer: the worker ends when the batch process is gone.

    A forkserver's workers are children of the fork server, which itself only exits when
    the workers have, so neither notices a batch killed with SIGKILL. Each worker therefore
    watches the batch's process id from a daemon thread (twice a second) and exits when it
    is gone; on Linux it also asks for SIGKILL when its own parent dies.

    Parameters
    ----------
    batch_pid : int
        Process id of the batch that started the pool.
    """
    import threading

    if sys.platform.startswith("linux"):
        try:
            import ctypes
            import signal

            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # PDEATHSIG
        except (OSError, AttributeError):
            pass

    def watch() -> None:
        while True:
            time.sleep(0.5)
            try:
                os.kill(batch_pid, 0)
            except ProcessLookupError:
                os._exit(1)
            except OSError:
                pass

    threading.Thread(target=watch, name="balancer-id-watch-batch", daemon=True).start()


def _stop_workers(pool: Any) -> None:
    """Terminate a pool's worker processes now (an interrupted batch must not wait)."""
    for proc in list(getattr(pool, "_processes", {}).values()):
        try:
            proc.terminate()
        except (OSError, ValueError):
            pass


def _dask() -> Any:
    try:
        import dask.distributed as distributed
    except ImportError:
        raise UsageError(f"--scheduler needs Dask: {_DASK_HINT}") from None
    return distributed


#: Seconds to wait for a scheduler's port to answer, for Dask's handshake, and for a
#: first worker: an address that never answers must not hang the batch.
SCHEDULER_TIMEOUT_S = float(os.environ.get("BALANCER_ID_SCHEDULER_TIMEOUT", "10"))


def probe_scheduler(address: str, timeout: float = SCHEDULER_TIMEOUT_S) -> None:
    """Check that something listens at a Dask scheduler's ``address`` before Dask tries.

    Parameters
    ----------
    address : str
        ``tcp://host:port``, ``host:port`` or ``tls://host:port``.
    timeout : float
        Seconds for the name look-up and the TCP connection.

    Raises
    ------
    UsageError
        One line naming the problem: an address that is not ``host:port``, a host name
        that does not resolve, a port nobody listens on, or no answer in ``timeout``.
    """
    import socket
    from urllib.parse import urlsplit

    if address == "local":
        return
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if not host or port is None:
        raise UsageError(
            f"--scheduler {address}: expected tcp://HOST:PORT (e.g. tcp://10.0.0.5:8786) or local"
        )
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror:
        raise UsageError(
            f"--scheduler {address}: the host '{host}' is not known (check the name)"
        ) from None
    family, kind, proto, _, sockaddr = infos[0]
    with socket.socket(family, kind, proto) as sock:
        sock.settimeout(timeout)
        try:
            sock.connect(sockaddr)
        except ConnectionRefusedError:
            raise UsageError(
                f"--scheduler {address}: nothing listens on port {port} of {host} "
                "(is the Dask scheduler running?)"
            ) from None
        except TimeoutError:
            raise UsageError(
                f"--scheduler {address}: no answer from {host}:{port} in {timeout:g} s "
                "(a firewall, or the wrong address)"
            ) from None
        except OSError as exc:
            why = exc.strerror or exc
            raise UsageError(f"--scheduler {address}: cannot connect ({why})") from None


def _ask_identity(address: str, timeout: float) -> None:
    """Ask the scheduler at ``address`` who it is, within ``timeout`` seconds in all.

    Dask's own connection timeout does not bound its handshake: a listener that accepts
    and never answers (a stuck process, a server of another protocol) would hold
    ``Client()`` forever. The question runs on an event loop of its own, in a thread, so
    a caller's running loop (a notebook) does not matter.

    Raises
    ------
    UsageError
        Nothing answered as a Dask scheduler in time.
    """
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    from distributed.core import rpc

    async def ask() -> object:
        remote = rpc(address, timeout=timeout)
        try:
            return await remote.identity()
        finally:
            await remote.close_rpc()

    def run() -> object:
        return asyncio.run(asyncio.wait_for(ask(), timeout))

    pool = ThreadPoolExecutor(1, thread_name_prefix="balancer-id-dask-probe")
    try:
        pool.submit(run).result(timeout=timeout + 5)
    except Exception as exc:  # TimeoutError, OSError, a reply that is not Dask's
        raise UsageError(
            f"--scheduler {address}: no Dask scheduler answered in {timeout:g} s "
            f"({type(exc).__name__}; is it a Dask scheduler's address?)"
        ) from None
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


def _run_dask(
    func: Callable[[Any], Payload],
    items: Sequence[tuple[int, Any]],
    record: Callable[[int, Payload], None],
    scheduler: str,
    n_workers: int,
    say: Callable[[str], None],
) -> None:
    """Run the items on a Dask cluster (``"local"``: a LocalCluster of ``n_workers``)."""
    distributed = _dask()
    cluster = None
    try:
        if scheduler == "local":
            cluster = distributed.LocalCluster(
                n_workers=n_workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
            client = distributed.Client(cluster)
            where = f"a local Dask cluster of {n_workers} workers"
        else:
            probe_scheduler(scheduler)
            _ask_identity(scheduler, SCHEDULER_TIMEOUT_S)
            client = distributed.Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S:g}s")
            where = f"the Dask cluster at {scheduler}"
    except (OSError, TimeoutError, ValueError) as exc:
        if cluster is not None:
            cluster.close()
        raise UsageError(
            f"--scheduler {scheduler}: no Dask scheduler answered in {SCHEDULER_TIMEOUT_S:g} s "
            f"({type(exc).__name__}; is it a Dask scheduler's address?)"
        ) from None
    if cluster is None:
        try:
            client.wait_for_workers(1, timeout=SCHEDULER_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            client.close()
            raise UsageError(
                f"--scheduler {scheduler}: the scheduler has no worker after "
                f"{SCHEDULER_TIMEOUT_S:g} s; start one (dask worker {scheduler})"
            ) from exc
    try:
        say(f"identifying {len(items)} logs on {where}")
        futures = {client.submit(func, arg, pure=False): key for key, arg in items}
        for fut in distributed.as_completed(futures):
            key = futures[fut]
            try:
                payload = fut.result()
            except Exception as exc:  # KilledWorker, lost scheduler, ...
                payload = _crashed(f"the Dask task failed: {type(exc).__name__}: {exc}")
            record(key, payload)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
