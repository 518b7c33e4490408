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
