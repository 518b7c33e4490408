"""Telling the user what went wrong: session errors become a notification in their browser."""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from typing import Any, TypeVar

import viser

from app.session.jobs import describe_unexpected
from robomach_core.errors import RobomachError

log = logging.getLogger(__name__)
E = TypeVar("E")


def notify_error(client: viser.ClientHandle | None, title: str, message: str) -> None:
    """A red notification for ``client`` that stays until the user closes it (a server-side
    event has none: only logged)."""
    log.info("%s: %s", title, message)
    if client is not None:
        client.add_notification(title, message, color="red", auto_close_seconds=None)


def notify_info(client: viser.ClientHandle | None, title: str, message: str) -> None:
    """A short blue notification for ``client`` (what just happened; it closes by itself)."""
    if client is not None:
        client.add_notification(title, message, color="blue", auto_close_seconds=6.0)


def client_of(event: viser.GuiEvent[Any]) -> viser.ClientHandle:
    """The browser behind the event of a ``guarded`` callback: ``guarded`` drops the events
    without one (those the server fires itself), so there always is one."""
    if event.client is None:
        raise RuntimeError("a GUI event without a browser reached a guarded callback")
    return event.client


def guarded(title: str, callback: Callable[[E], Any]) -> Callable[[E], None]:
    """Wrap a GUI callback so that a ``RobomachError`` (busy, bad input, ...) is shown to the
    user who clicked, not lost in the server log. Events fired by the server itself
    (``event.client is None``, e.g. a value set to mirror an API change) are ignored."""

    @functools.wraps(callback)
    def run(event: E) -> None:
        client = getattr(event, "client", None)
        if client is None:
            return
        try:
            callback(event)
        except RobomachError as exc:
            notify_error(client, title, str(exc))
        except Exception as exc:  # a bug must not kill the GUI thread pool silently
            log.exception("%s failed", title)
            notify_error(client, title, describe_unexpected(exc))

    return run


def upload_handled(
    server: viser.ViserServer, title: str, callback: Callable[[E], Any]
) -> Callable[[E], None]:
    """``guarded`` for an upload button's callback, which then forgets the upload's progress:
    viser keeps each transfer's last progress message for browsers that connect later, and a
    browser opened after an upload showed its "uploaded" note again (issue 31)."""
    run = guarded(title, callback)

    @functools.wraps(callback)
    def handled(event: E) -> None:
        try:
            run(event)
        finally:
            forget_upload_progress(server)

    return handled


def forget_upload_progress(server: viser.ViserServer) -> None:
    """Drop the finished uploads' progress messages from what a new browser is sent first
    (viser's broadcast buffer; nothing when viser's internals differ)."""
    from viser._messages import FileTransferPartAck

    try:
        buffer = server._websock_server.get_message_buffer()
    except AttributeError:  # another viser: its buffer is not where this one keeps it
        log.warning("cannot drop the upload progress of viser %s", viser.__version__)
        return
    buffer.remove_from_buffer(lambda message: isinstance(message, FileTransferPartAck))
