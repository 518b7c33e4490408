"""Server-sent events: every change of the session, pushed to the pendant and scripts.

``GET /api/events`` is a ``text/event-stream``: one event per change, named by the session's
topic (robot, compliance, cell, guide_points, recording, postprocess, job, project, exports);
its data is JSON ``{"topic": ..., "time_s": ...}``, and for ``robot`` also the state (as
``GET /api/state``). Bursts are coalesced (a topic waiting to be sent is sent once). The
browser's ``EventSource`` reconnects by itself after a restart (``retry`` 1 s).
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator

from fastapi import APIRouter, Request
from fastapi.responses import StreamingResponse

from app.api.routes import SessionDep
from app.api.schemas import ProjectStatusPublic, StatePublic
from app.session import Session

router = APIRouter(prefix="/api", tags=["state"])

RETRY_MS = 1000
POLL_S = 0.5  # how often an idle stream checks for a disconnect or a shutdown
HEARTBEAT_S = 15.0


def _event(topic: str, session: Session) -> str:
    data: dict = {"topic": topic, "time_s": round(time.time(), 3)}
    if topic == "robot":
        status = ProjectStatusPublic.from_project(session.project())
        data["state"] = StatePublic.from_snapshot(
            session.snapshot(), project_status=status
        ).model_dump()
    return f"event: {topic}\ndata: {json.dumps(data)}\n\n"


@router.get(
    "/events",
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}, "description": "the event stream"}},
)
async def events(request: Request, session: SessionDep) -> StreamingResponse:
    """Server-sent events, one per change of the workbench (see the module docstring)."""
    loop = asyncio.get_running_loop()
    pending: dict[str, None] = {}  # ordered set of topics waiting to be sent
    wake = asyncio.Event()

    def mark(topic: str) -> None:
        pending[topic] = None
        wake.set()

    def on_change(topic: str) -> None:  # any thread
        try:
            loop.call_soon_threadsafe(mark, topic)
        except RuntimeError:  # the loop is closed: the server is stopping
            pass

    should_exit = getattr(request.app.state, "should_exit", None)
    unsubscribe = session.subscribe(on_change)

    async def stream() -> AsyncIterator[str]:
        try:
            yield f"retry: {RETRY_MS}\n\n"
            yield await asyncio.to_thread(_event, "hello", session)
            last = time.monotonic()
            while True:
                try:
                    await asyncio.wait_for(wake.wait(), POLL_S)
                except TimeoutError:
                    if (should_exit is not None and should_exit()) or (
                        await request.is_disconnected()
                    ):
                        return
                    if time.monotonic() - last > HEARTBEAT_S:
                        last = time.monotonic()
                        yield ": keep-alive\n\n"
                    continue
                wake.clear()
                topics = list(pending)
                pending.clear()
                for topic in topics:
                    yield await asyncio.to_thread(_event, topic, session)
                last = time.monotonic()
        finally:
            unsubscribe()

    return StreamingResponse(
        stream(),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )
