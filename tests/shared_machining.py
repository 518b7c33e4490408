"""The pump demo's machining comparison on an arm, shared by the tests that read it
(tests/core/machining/test_acceptance.py and test_read_back.py cut the UR10's same 18 runs):
each comparison runs once per test run, in whichever test process (pytest-xdist worker) asks
first, and is kept as a pickle beside the shared demos (tests/demo_project.py, under the same
lock discipline: the others wait and read it).

Tests read what they get and never change it: the rows are dicts, shared as they were within
one module before.
"""

from __future__ import annotations

import fcntl
import functools
import hashlib
import pickle
from collections.abc import Callable
from dataclasses import dataclass

from robomach_core import project as core
from robomach_core.cell import Robot
from robomach_core.machining import MachiningSettings
from robomach_core.part import Workpiece
from tests.demo_project import arm_demo, demos_root


@dataclass(frozen=True)
class Machined:
    """An arm's pump demo with its machining setup, the part and arm it was cut with, and the
    comparison (``project.machine``); ``project`` does not hold ``result`` (a test that
    exports from it adds it: ``with_machining_result``)."""

    project: core.Project
    workpiece: Workpiece
    robot: Robot
    result: core.MachiningResult


@functools.cache
def machined(
    arm: str,
    cell_options: tuple[str, ...],
    controllers: tuple[str, ...],
    compensations: tuple[str, ...],
    stages: str = "online",
) -> Machined:
    """The comparison of ``controllers`` x ``compensations`` on ``arm``'s pump demo (seed 0),
    the cell given ``cell_options``, the staged controllers' stages ``stages``; the cuts run in
    a process pool (``workers=None``), as ``robomach machine`` runs them."""
    project = core.load_project_file(arm_demo(arm).folder / "project.npz")
    setup = core.MachiningSetup(MachiningSettings(seed=0, stages=stages), cell_options=cell_options)
    project = core.with_machining_setup(project, setup)
    workpiece = core.build_workpiece(project.cell, project.mesh)
    robot = Robot(project.cell.robot, project.tool().T_flange_tcp)
    key = repr((arm, cell_options, controllers, compensations, stages))
    result = _stored(key, lambda: core.machine(
        project, workpiece, robot,
        controllers=controllers, compensations=compensations, workers=None,
    ))  # fmt: skip
    return Machined(project, workpiece, robot, result)


def _stored(key: str, compute: Callable[[], core.MachiningResult]) -> core.MachiningResult:
    """``compute()``'s result, computed by the first test process that asks for ``key`` in
    this run and read back by every other."""
    stored = demos_root() / f"machined-{hashlib.sha256(key.encode()).hexdigest()[:16]}.pickle"
    with open(stored.with_suffix(".lock"), "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # another worker may be cutting it: wait
        if not stored.is_file():
            partial = stored.with_suffix(".partial")
            partial.write_bytes(pickle.dumps(compute(), protocol=pickle.HIGHEST_PROTOCOL))
            partial.rename(stored)  # whole or absent
        return pickle.loads(stored.read_bytes())
