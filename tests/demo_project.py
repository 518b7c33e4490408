"""One ``robomach demo --workpiece block`` output folder per test process, shared by the machining
tests of the CLI and the API (the demo run is the slow part: about a minute)."""

from __future__ import annotations

import atexit
import functools
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@functools.cache
def block_demo_dir() -> Path:
    """The folder of a block demo run (seed 0), with its project.npz."""
    folder = Path(tempfile.mkdtemp(prefix="robomach-block-demo-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    done = subprocess.run(
        [sys.executable, "-m", "app.cli", "demo", "--out", str(folder), "--workpiece", "block"]
        + ["--no-plot"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stderr
    assert (folder / "project.npz").is_file()
    return folder
