"""``batch --scheduler`` never hangs: an address is probed with a timeout and every way it
can be wrong is one line naming the problem (issue 29)."""

from __future__ import annotations

import socket
import threading
import time

import pytest

from balancer_id.batch.executors import probe_scheduler
from balancer_id.errors import UsageError


def test_an_unknown_host_is_named_not_called_a_timeout():
    with pytest.raises(UsageError, match=r"host 'no-such-host\.invalid' is not known"):
        probe_scheduler("tcp://no-such-host.invalid:8786", timeout=2)


def test_a_closed_port_says_nothing_listens():
    with socket.socket() as sock:  # a port that was free a moment ago
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    with pytest.raises(UsageError, match="nothing listens on port"):
        probe_scheduler(f"tcp://127.0.0.1:{port}", timeout=2)


def test_a_malformed_address_shows_the_expected_form():
    with pytest.raises(UsageError, match="expected tcp://HOST:PORT"):
        probe_scheduler("tcp://host-without-port", timeout=1)


def test_a_listener_that_never_answers_dask_is_refused_in_bounded_time(monkeypatch):
    """A port that accepts but never speaks Dask (an HTTP server, a stuck listener): the
    probe passes, Dask's handshake times out, and the batch says so instead of waiting."""
    pytest.importorskip("dask.distributed")
    from balancer_id.batch import executors

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    held: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                held.append(server.accept()[0])  # accepted, never answered
            except OSError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    monkeypatch.setattr(executors, "SCHEDULER_TIMEOUT_S", 2.0)
    start = time.monotonic()
    try:
        with pytest.raises(UsageError, match="no Dask scheduler answered"):
            executors._run_dask(
                str, [(0, 1)], lambda *a: None, f"tcp://127.0.0.1:{server.getsockname()[1]}",
                1, lambda msg: None,
            )
    finally:
        stop.set()
        thread.join()
        for conn in held:
            conn.close()
        server.close()
    assert time.monotonic() - start < 30


def test_a_real_scheduler_passes_the_probe_and_its_handshake():
    """The control: a Dask scheduler is reached and answers who it is."""
    distributed = pytest.importorskip("dask.distributed")
    import logging

    from balancer_id.batch.executors import _ask_identity

    cluster = distributed.LocalCluster(
        n_workers=0, processes=True, dashboard_address=None, silence_logs=logging.ERROR,
        protocol="tcp://",
    )
    try:
        probe_scheduler(cluster.scheduler_address, timeout=5)
        _ask_identity(cluster.scheduler_address, 10)
    finally:
        cluster.close()
