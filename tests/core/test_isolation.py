"""Native steps run in an isolated process: a crash, a memory blow-up or a hang there is an
error here, and the helper survives it (issue 19, "What to build" 1)."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest
import trimesh

from robomach_core.isolation import IsolatedError, helper_pid, run_isolated


def test_a_crash_in_the_child_is_an_error_and_the_helper_lives_on():
    assert run_isolated("echo", {"value": 1}) == {"echo": 1}
    pid = helper_pid()
    with pytest.raises(IsolatedError, match="SIGSEGV") as info:
        run_isolated("echo", {"crash": True})
    assert info.value.kind == "crash"
    assert run_isolated("echo", {"value": 2}) == {"echo": 2}
    assert helper_pid() == pid  # the same helper: only its child died


def test_the_child_s_memory_is_bounded():
    with pytest.raises(IsolatedError, match="more than 256 MiB") as info:
        run_isolated("echo", {"allocate_bytes": 1 << 30}, memory_bytes=256 << 20)
    assert info.value.kind == "memory"
    assert run_isolated("echo", {"allocate_bytes": 64 << 20}, memory_bytes=256 << 20) == {
        "allocated": 64 << 20
    }


def test_a_hang_is_cut_at_the_timeout():
    started = time.monotonic()
    with pytest.raises(IsolatedError, match="longer than 0.5 s") as info:
        run_isolated("echo", {"sleep_s": 30}, timeout_s=0.5)
    assert info.value.kind == "timeout"
    assert time.monotonic() - started < 30  # cut: it did not wait for the child's 30 s sleep


def test_a_killed_helper_is_started_again():
    run_isolated("echo", {"value": 0})
    os.kill(helper_pid(), signal.SIGKILL)
    time.sleep(0.1)
    assert run_isolated("echo", {"value": 3}) == {"echo": 3}


def test_the_mesh_task_builds_what_the_server_builds():
    box = trimesh.creation.box(extents=(0.1, 0.05, 0.02))
    answer = run_isolated("mesh", {"vertices": box.vertices, "faces": box.faces})
    assert answer["hull_vertices"] == 8
    assert answer["hull_volume_m3"] == pytest.approx(1e-4)
    expected = np.linalg.norm([0.01, 0.01, 0.01]) - 0.001  # sphere 10 mm past the corner
    assert answer["distance_m"] == pytest.approx(expected, abs=1e-9)
