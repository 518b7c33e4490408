"""The placement panel mirrors the placement (what is tried, else where the part is) without
fighting the person's typing: a refresh for another cause (the cell, after an upload, on the
workbench's next tick) came between a number typed in the browser reaching the server and its
listener trying it, and wrote the old number back (the browser test of placing, calibrating
and learning failed so under load: the part stayed at x = 800 mm). A real viser server and a
real Session; fresh numbers each run (``ROBOMACH_SEED`` replays one)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
import viser

from app.gui.panels.placement import PlacementPanel
from app.session import Session
from tests.api.server_process import free_port
from tests.envelope import replay, run_seed

SEED = run_seed()


@pytest.fixture(scope="module")
def panel() -> Iterator[PlacementPanel]:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    session = Session(real_time=False)
    yield PlacementPanel(server, session)
    server.stop()
    session.close()


def test_a_number_typed_before_its_listener_ran_survives_a_refresh_for_another_cause(panel):
    rng = np.random.default_rng(SEED)
    controls = (*panel.position, *panel.angles)
    for _ in range(5):
        k = int(rng.integers(0, len(controls)))
        placed = panel.session.preview.placed()
        typed = round(placed[k] + float(rng.uniform(1.0, 20.0)) * rng.choice([-1, 1]), 1)
        # The browser's number has reached the input; its listener has not run yet (viser
        # keeps the value in the handle's state before it calls the listeners).
        controls[k]._impl.value = typed
        panel.refresh()  # the cell's topic, on the workbench's tick
        assert float(controls[k].value) == typed, f"{replay(SEED)}: {panel.values()}"
        panel._try()  # the listener: the typed number is tried
        assert panel.session.preview.values()[k] == typed, replay(SEED)
        panel.refresh()  # the placement's topic
        assert float(controls[k].value) == typed, replay(SEED)
        panel.session.preview.clear()  # Put it back: the inputs show where the part is
        panel.refresh()
        assert panel.values() == placed, f"{replay(SEED)}: {panel.values()} != {placed}"
