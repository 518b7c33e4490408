"""``robomach`` for the tests: as a user runs it (a process of its own), or its ``main`` in this
process for the many argument checks, which then skip the 3-5 s of imports a process pays."""

from __future__ import annotations

import contextlib
import io
import subprocess
import sys


def robomach(*args: str, timeout: float = 900) -> subprocess.CompletedProcess:
    """``python -m app.cli ARGS`` in a process of its own: exit code, stdout, stderr."""
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=timeout
    )


def robomach_here(*args: str) -> subprocess.CompletedProcess:
    """``app.cli.main(ARGS)`` in this process, with what it prints and the code it exits with
    (argparse's refusals exit through ``SystemExit``, as they do in a process)."""
    from app.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    return subprocess.CompletedProcess(["robomach", *args], code, out.getvalue(), err.getvalue())
