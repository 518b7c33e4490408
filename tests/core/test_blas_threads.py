"""The core sets one BLAS thread before numpy loads OpenBLAS (robomach_core/__init__.py), and a
value the user set wins."""

from __future__ import annotations

import os
import subprocess
import sys

SCRIPT = (
    "import os, {first}, numpy, scipy.linalg; "
    "print(len(os.listdir('/proc/self/task')), os.environ['OPENBLAS_NUM_THREADS'])"
)


def _threads(first: str, **env: str) -> tuple[int, str]:
    clean = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT.format(first=first)],
        env={**clean, **env}, capture_output=True, text=True, check=True,
    ).stdout.split()  # fmt: skip
    return int(out[0]), out[1]


def test_importing_the_core_or_the_app_first_leaves_one_blas_thread():
    one = _threads("os", OPENBLAS_NUM_THREADS="1")
    assert _threads("robomach_core") == one
    assert _threads("app.cli") == one


def test_a_thread_count_the_user_set_wins():
    assert _threads("robomach_core", OPENBLAS_NUM_THREADS="2")[1] == "2"
