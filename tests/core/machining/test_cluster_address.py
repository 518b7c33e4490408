"""A cluster address that answers with something else than a Dask scheduler is refused with a
clear word (issue 32, point 7): one answering an HTTP status line was reported as "not
enough memory" (distributed read the status line as a frame length of 3 EiB), and one that
says nothing hung the client for ever."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from robomach_core.errors import InvalidInputError
from robomach_core.machining import parallel


@contextmanager
def tcp_server(answer: bytes | None) -> Iterator[int]:
    """A TCP server on a free port that sends ``answer`` to each connection (None: nothing)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                return
            if answer:
                conn.sendall(answer)
            stop.wait(2.0)
            conn.close()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield server.getsockname()[1]
    finally:
        stop.set()
        server.close()


def test_an_address_answering_http_is_not_a_scheduler() -> None:
    with tcp_server(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n") as port:
        with pytest.raises(InvalidInputError, match="answered with something else"):
            parallel.run_tasks([], cluster=f"tcp://127.0.0.1:{port}")


def test_an_address_that_says_nothing_is_not_a_scheduler(monkeypatch) -> None:
    monkeypatch.setattr(parallel, "CLUSTER_TIMEOUT_S", 0.5)
    with tcp_server(None) as port:
        with pytest.raises(InvalidInputError, match="said nothing within 0.5 s"):
            parallel.run_tasks([], cluster=f"tcp://127.0.0.1:{port}")


def test_an_address_nobody_listens_on_is_unreachable() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(InvalidInputError, match="cannot reach"):
        parallel.run_tasks([], cluster=f"tcp://127.0.0.1:{port}")
