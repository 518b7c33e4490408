"""``robomach demo`` output folders shared by the whole test run: each set of arguments runs once
(the demo is the slow part: about a minute on an idle machine) and every test that needs that
demo reads the same folder, in whichever test process (pytest-xdist worker) asks first.

The folders live under ``ROBOMACH_TEST_DEMOS``, a temporary folder that tests/conftest.py makes
when the run starts (inherited by the workers) and removes when it ends; a lock file per demo
lets one process run it while the others wait.
"""

from __future__ import annotations

import fcntl
import functools
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDER_VARIABLE = "ROBOMACH_TEST_DEMOS"
DEMO_TIMEOUT_S = 900


@dataclass(frozen=True)
class DemoRun:
    """A finished ``robomach demo``: its output folder and what it printed."""

    folder: Path
    stdout: str

    @property
    def summary(self) -> dict:
        return json.loads((self.folder / "summary.json").read_text())


def demos_root() -> Path:
    """The run's folder of shared demos (a private one when no conftest made it)."""
    root = os.environ.get(FOLDER_VARIABLE)
    if not root:
        root = tempfile.mkdtemp(prefix="robomach-test-demos-")
        os.environ[FOLDER_VARIABLE] = root
    return Path(root)


def remove_demos_root() -> None:
    root = os.environ.pop(FOLDER_VARIABLE, None)
    if root:
        shutil.rmtree(root, ignore_errors=True)


@functools.cache
def demo_run(*args: str) -> DemoRun:
    """``robomach demo --out FOLDER *args``, run once per test run for these arguments."""
    key = hashlib.sha256("\0".join(args).encode()).hexdigest()[:16]
    folder = demos_root() / key
    stdout_file = folder.with_suffix(".stdout")
    with open(folder.with_suffix(".lock"), "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # another worker may be running this demo: wait
        if not stdout_file.is_file():
            shutil.rmtree(folder, ignore_errors=True)
            done = subprocess.run(
                [sys.executable, "-m", "app.cli", "demo", "--out", str(folder), *args],
                cwd=ROOT,
                capture_output=True,
                text=True,
                timeout=DEMO_TIMEOUT_S,
            )
            assert done.returncode == 0, done.stderr[-3000:]
            stdout_file.write_text(done.stdout)  # written last: the demo is complete
    return DemoRun(folder, stdout_file.read_text())


def block_demo_dir() -> Path:
    """The folder of a block demo run (seed 0, no plot), with its project.npz."""
    folder = demo_run("--workpiece", "block", "--no-plot").folder
    assert (folder / "project.npz").is_file()
    return folder


def pump_demo() -> DemoRun:
    """The README's demo: the water pump on the UR10 (the default arm), seed 0, demo.png."""
    return demo_run()


def arm_demo(robot: str) -> DemoRun:
    """The pump demo on another arm (seed 0, no plot); the UR10's is ``pump_demo``."""
    if robot == "ur10":
        return pump_demo()
    return demo_run("--robot", robot, "--no-plot")
