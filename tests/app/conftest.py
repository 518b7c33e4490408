"""Fixtures of the app's in-process tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import viser

from tests.api.server_process import free_port


@pytest.fixture(scope="module")
def server() -> Iterator[viser.ViserServer]:
    """A real viser server in process for a module's panels and widgets, stopped after it."""
    s = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    yield s
    s.stop()
