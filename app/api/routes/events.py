"""Server-sent events: every change of the session, pushed to the pendant and scripts.

``GET /api/events`` is a ``text/event-stream``: one event per change, named by the session's
topic (robot, compliance, cell, guide_points, recording, postprocess, job, project, exports);
its data is JSON ``{"topic": ..., "time_s": ...}``, and for ``robot`` also the state (as
``GET /api/state``). Bursts are coalesced (a topic waiting to be sent is sent once). The
browser's ``EventSource`` reconnects by itself after a restart (``retry`` 1 s).

One ``EventHub`` per app serialises each event once for every listener: with a stream per
client each serialised the whole state itself, and 200 listeners took the event loop and the
thread pool (``/api/health`` p99 121-238 ms while the robot moved; issue 19, R10). The hub
listens to the session while a stream is open, reads and serialises each pending topic once in
a worker thread, and hands the same text to every stream, each of which keeps only the latest
text per topic (a slow reader skips states, it never queues them). Streams do no work while
nothing changes: the hub alone wakes every ``POLL_S`` to end them when the server stops and to
send the heartbeat; a client that leaves is noticed by the response (Starlette cancels its
stream when the connection closes).
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator, Callable

from fastapi import APIRouter, Request
from fastapi.responses import StreamingResponse

from app.api.routes import SessionDep
from app.api.schemas import ProjectStatusPublic, StatePublic
from app.session import Session

router = APIRouter(prefix="/api", tags=["state"])

RETRY_MS = 1000
POLL_S = 0.5  # how often the hub checks for a shutdown and the heartbeat
HEARTBEAT_S = 15.0


def _event(topic: str, session: Session) -> str:
    data: dict = {"topic": topic, "time_s": round(time.time(), 3)}
    if topic == "robot":
        status = ProjectStatusPublic.from_project(session.project())
        data["state"] = StatePublic.from_snapshot(
            session.robot.snapshot(), project_status=status
        ).model_dump()
    return f"event: {topic}\ndata: {json.dumps(data)}\n\n"


class _Listener:
    """One stream's mailbox: the latest text per topic, in the order topics first came."""

    def __init__(self) -> None:
        self.pending: dict[str, str] = {}
        self.wake = asyncio.Event()
        self.closed = False

    def put(self, topic: str, text: str) -> None:
        self.pending[topic] = text
        self.wake.set()

    def close(self) -> None:
        self.closed = True
        self.wake.set()

    def take(self) -> list[str]:
        texts = list(self.pending.values())
        self.pending.clear()
        self.wake.clear()
        return texts


class EventHub:
    """Fans each session change out to every open stream, serialised once (module docstring).

    Lives on the event loop; the session's listener (any thread) only marks a topic and wakes
    the hub's task. The task runs while at least one stream is open.

    Args:
        session: The session whose changes are sent.
        loop: The server's event loop.
        should_exit: True once the server stops (the streams then end), or None.
    """

    def __init__(
        self,
        session: Session,
        loop: asyncio.AbstractEventLoop,
        should_exit: Callable[[], bool] | None = None,
    ) -> None:
        self.session = session
        self.loop = loop
        self.should_exit = should_exit
        self.listeners: set[_Listener] = set()
        self._topics: dict[str, None] = {}  # ordered set of topics waiting
        self._wake = asyncio.Event()
        self._task: asyncio.Task | None = None
        self._unsubscribe: Callable[[], None] | None = None

    def add(self) -> _Listener:
        listener = _Listener()
        self.listeners.add(listener)
        if self._unsubscribe is None:
            self._unsubscribe = self.session.subscribe(self._on_change)
        if self._task is None or self._task.done():
            self._task = self.loop.create_task(self._run())
        return listener

    def remove(self, listener: _Listener) -> None:
        self.listeners.discard(listener)
        if not self.listeners:
            if self._unsubscribe is not None:
                self._unsubscribe()
                self._unsubscribe = None
            self._wake.set()  # the task sees no listener and ends

    def _on_change(self, topic: str) -> None:  # any thread
        try:
            self.loop.call_soon_threadsafe(self._mark, topic)
        except RuntimeError:  # the loop is closed: the server is stopping
            pass

    def _mark(self, topic: str) -> None:
        self._topics[topic] = None
        self._wake.set()

    def _fan_out(self, topic: str, text: str) -> None:
        for listener in list(self.listeners):
            listener.put(topic, text)

    async def _run(self) -> None:
        next_beat = time.monotonic() + HEARTBEAT_S
        while self.listeners:
            try:
                async with asyncio.timeout(POLL_S):
                    await self._wake.wait()
            except TimeoutError:
                pass
            if self.should_exit is not None and self.should_exit():
                for listener in list(self.listeners):
                    listener.close()
                return
            if time.monotonic() >= next_beat:
                next_beat = time.monotonic() + HEARTBEAT_S
                self._fan_out("_heartbeat", ": keep-alive\n\n")
            if not self._wake.is_set():
                continue
            self._wake.clear()
            topics = list(self._topics)
            self._topics.clear()
            for topic in topics:
                if not self.listeners:
                    break
                self._fan_out(topic, await asyncio.to_thread(_event, topic, self.session))


def _hub(request: Request, session: Session) -> EventHub:
    state = request.app.state
    hub = getattr(state, "event_hub", None)
    if hub is None or hub.session is not session or hub.loop is not asyncio.get_running_loop():
        should_exit = getattr(state, "should_exit", None)
        hub = state.event_hub = EventHub(session, asyncio.get_running_loop(), should_exit)
    return hub


@router.get(
    "/events",
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}, "description": "the event stream"}},
)
async def events(request: Request, session: SessionDep) -> StreamingResponse:
    """Server-sent events, one per change of the workbench (see the module docstring)."""
    hub = _hub(request, session)

    async def stream() -> AsyncIterator[str]:
        listener = hub.add()  # here: a stream that never starts leaves nothing behind
        try:
            yield f"retry: {RETRY_MS}\n\n"
            yield await asyncio.to_thread(_event, "hello", session)
            while not listener.closed:
                await listener.wake.wait()
                texts = listener.take()
                if texts:
                    yield "".join(texts)  # one write for a burst of topics
        finally:
            hub.remove(listener)

    return StreamingResponse(
        stream(),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )
