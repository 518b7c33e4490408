"""A cell the session replaces is freed even when the heap it was built in is frozen.

``robomach serve`` freezes its startup heap out of the collector's full passes (``gc.freeze``
in the API's lifespan, issue 32): garbage in a cycle there is never collected. The first
cell's robot and the supervisor kept on it hold each other, so that robot, its supervisor and
the part's mesh and trees stayed for the life of the server after the first cell change (50-150
MB for an 80k-triangle part; the memory test's warm-up round hid it). A replaced robot now lets
go of its supervisor (``forget_supervisor``), and nothing of the old cell sits in a cycle.
"""

from __future__ import annotations

import gc
import weakref
from collections.abc import Iterator
from pathlib import Path

import pytest

from app.session import Session
from app.store import Store


@pytest.fixture
def frozen_heap() -> Iterator[None]:
    """The heap frozen as the server's lifespan freezes it; frozen again afterwards as the
    test run left it (``tests/conftest.py``), without the garbage of this test."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
        gc.collect()
        gc.freeze()


@pytest.mark.parametrize("change", ["workpiece", "robot", "project"])
def test_a_replaced_cell_is_freed_from_a_frozen_heap(
    frozen_heap, change: str, tmp_path: Path
) -> None:
    session = Session(Store(tmp_path / "robomach.sqlite"), real_time=False)
    try:
        gc.unfreeze()  # the session's first cell is part of the startup heap, as in serve
        gc.collect()
        gc.freeze()
        first = session.robot.cell
        kept = {
            "robot": weakref.ref(first.robot),
            "workpiece": weakref.ref(first.workpiece),
            "cell": weakref.ref(first),
        }
        del first
        if change == "workpiece":
            session.set_cell(workpiece="block")
        elif change == "robot":
            session.set_cell(robot="ur5")
        else:
            session.projects.open_project(session.projects.create_project("other").id)
        alive = [name for name, ref in kept.items() if ref() is not None]
        assert alive == [], f"after a {change} change the first cell's {alive} stayed"
    finally:
        session.close()
