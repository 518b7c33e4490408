"""The session keeps a user's arm in the project: it survives a restart (a new process has an
empty registry, so the arm is registered again from the stored file)."""

from __future__ import annotations

import numpy as np

from app.session import Session
from app.store import Store
from robomach_core.cell.robot import robot_urdf_path
from robomach_core.robots import custom, registry
from tests.jobs import finished


def test_an_uploaded_arm_survives_a_restart(tmp_path) -> None:
    data = robot_urdf_path("ur5").read_bytes()
    path = tmp_path / "robomach.sqlite"
    first = Session(Store(path), data_dir=tmp_path)
    cell = first.upload_robot(data, "my ur5.urdf")
    assert cell.robot.startswith("urdf_my_ur5_")
    assert first.robot.cell.robot.name == cell.robot
    home = first.robot.snapshot().joints_rad.copy()
    first.close()
    registry.forget(cell.robot)  # as in a new process
    assert not custom.is_custom(cell.robot)
    second = Session(Store(path), data_dir=tmp_path)
    try:
        assert second.project().cell.robot == cell.robot
        assert second.project().robot_urdf == ("my ur5.urdf", data)
        np.testing.assert_allclose(second.robot.snapshot().joints_rad, home, atol=1e-9)
    finally:
        second.close()


def test_choosing_a_builtin_arm_drops_the_uploaded_file(tmp_path) -> None:
    data = robot_urdf_path("ur5").read_bytes()
    s = Session(Store(tmp_path / "db.sqlite"), data_dir=tmp_path)
    try:
        s.upload_robot(data, "arm.urdf")
        assert s.project().robot_urdf is not None
        s.set_cell(robot="ur10")
        assert s.project().robot_urdf is None and s.robot.cell.robot.name == "ur10"
    finally:
        s.close()


def test_the_example_on_an_arm_too_small_for_the_part_says_so() -> None:
    s = Session(real_time=False)
    try:
        s.set_cell(robot="ur3")
        info = finished(s, s.learning.start_example(), 60)
        assert info.status == "failed"
        assert "edge of reach" in info.error and "larger arm" in info.error, info.error
    finally:
        s.close()


def test_a_read_that_finds_the_robot_busy_shows_the_robot_after_the_last_change() -> None:
    """``GET /api/state`` never waits for the robot's lock: while another change holds it, the
    answer is the kept snapshot. That snapshot must follow every change to the robot (here a
    new cell), not only the last read that waited, or a read after a change shows the old pose."""
    import threading

    s = Session(real_time=False)
    try:
        s.set_cell(workpiece="block")
        s.robot.select(["x"], "base")
        pushed = s.teach.push(np.array([20.0, 0, 0, 0, 0, 0]), 0.5).position_m  # kept
        s.set_cell(workpiece="water_pump")  # a new cell: the robot back at its home
        held, release = threading.Event(), threading.Event()

        def holding(project):  # a change that holds the session's lock a while
            held.set()
            release.wait(10)
            return project

        def hold() -> None:
            s.commit(holding)

        holder = threading.Thread(target=hold)
        holder.start()
        try:
            assert held.wait(10)
            seen = s.robot.snapshot(wait=False).position_m
        finally:
            release.set()
            holder.join()
        now = s.robot.snapshot().position_m
        assert np.linalg.norm(now - pushed) > 5e-3  # the new cell's home is not the pushed pose
        np.testing.assert_allclose(seen, now, atol=1e-9)
    finally:
        s.close()
