"""Server-sent events are serialised once for all listeners (issue 19, R10: each stream
serialised the whole state itself; with 200 listeners ``/api/health`` p99 was 121-238 ms while
the robot moved). Real HTTP (uvicorn in a thread, the streams over sockets); the count of
serialisations is read from the route's own ``_event``. The latency figure is the benchmark's
(``benchmarks/bench_events.py``), not an assert."""

from __future__ import annotations

import threading
import time
from collections import Counter
from collections.abc import Iterator

import httpx
import pytest
import uvicorn

from app.api.app import create_app
from app.api.routes import events
from app.session import Session
from app.settings import ServerSettings
from tests.api.server_process import free_port

LISTENERS = 30
CHANGES = 5


@pytest.fixture
def served(monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[str, Session, Counter]]:
    calls: Counter = Counter()
    real = events._event

    def counted(topic: str, session: Session) -> str:
        calls[topic] += 1
        return real(topic, session)

    monkeypatch.setattr(events, "_event", counted)
    session = Session(real_time=False)
    port = free_port()
    app = create_app(session, ServerSettings(viser_port=None))
    config = uvicorn.Config(
        app,
        host="127.0.0.1",
        port=port,
        log_level="error",
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.05)
    yield f"http://127.0.0.1:{port}", session, calls, app
    server.should_exit = True
    thread.join(10)


def _listen(url: str, got: list, ready: threading.Barrier, stop: threading.Event) -> None:
    with httpx.Client(base_url=url, timeout=30) as client:
        with client.stream("GET", "/api/events") as r:
            lines = r.iter_lines()
            for line in lines:  # "retry", then the hello event
                if line.startswith("data: ") and '"hello"' in line:
                    break
            ready.wait()
            for line in lines:
                if line.startswith("data: ") and '"topic": "robot"' in line:
                    got.append(line)
                if stop.is_set() or len(got) >= CHANGES:
                    return


def test_each_change_is_serialised_once_for_every_listener(served) -> None:
    url, session, calls, app = served
    got: list[list[str]] = [[] for _ in range(LISTENERS)]
    ready, stop = threading.Barrier(LISTENERS + 1, timeout=30), threading.Event()
    threads = [
        threading.Thread(target=_listen, args=(url, got[i], ready, stop), daemon=True)
        for i in range(LISTENERS)
    ]
    for t in threads:
        t.start()
    ready.wait()
    time.sleep(0.3)
    for _ in range(CHANGES):
        session.notify("robot")  # what a move notifies
        time.sleep(0.3)  # apart, so that none is coalesced into the next
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and any(len(g) < CHANGES for g in got):
        time.sleep(0.05)
    stop.set()
    assert all(len(g) == CHANGES for g in got), [len(g) for g in got]
    assert calls["robot"] == CHANGES, calls  # not LISTENERS x CHANGES
    for k in range(CHANGES):  # every listener got the very same text of each change
        assert len({g[k] for g in got}) == 1
    for t in threads:
        t.join(10)
    deadline = time.monotonic() + 10  # the closed streams leave the hub
    while time.monotonic() < deadline and app.state.event_hub.listeners:
        time.sleep(0.05)
    assert not app.state.event_hub.listeners
