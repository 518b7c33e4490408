"""Helper processes that end when the process they work for ends, however it ends.

PROBLEM   The machining pool's workers (forked by multiprocessing's forkserver) and the
          isolation helper's children outlived a server killed with SIGKILL: the workers
          waited forever on a queue whose write end they hold themselves, the forkserver
          waited for them, 2.9 GB idle under init (issue 32, point 5). Nothing in the dead
          process can tell them.
STRATEGY  A worker watches the process it works for: a daemon thread waits on a pidfd of it
          (Linux 5.3+: readable when the process ends, immune to pid reuse) and ends the worker
          with ``os._exit`` at once; where pidfds are missing it polls the pid every
          ``POLL_S``. A direct child of a long-lived thread (the isolation helper's forked
          task) also asks the kernel for SIGKILL when its parent dies (``PR_SET_PDEATHSIG``);
          that signal follows the thread that forked, so it is not used for processes started
          from a server's short-lived worker threads.
SOLUTION  ``end_with(pid)`` in the worker (a pool initializer); ``die_with_parent()`` in a
          forked child.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import select
import signal
import threading
import time

POLL_S = 0.5
EXIT_CODE = 1
_PR_SET_PDEATHSIG = 1


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, owned by someone else
        return True
    return True


def _wait_for_end(pid: int) -> None:
    try:
        fd = os.pidfd_open(pid)
    except ProcessLookupError:
        return  # already gone
    except (AttributeError, OSError):  # no pidfd here: poll
        while _alive(pid):
            time.sleep(POLL_S)
        return
    try:
        select.select([fd], [], [])
    finally:
        os.close(fd)


def end_with(pid: int) -> None:
    """End this process (``os._exit``) as soon as process ``pid`` ends (module docstring)."""

    def watch() -> None:
        _wait_for_end(pid)
        os._exit(EXIT_CODE)

    threading.Thread(target=watch, name=f"end-with-{pid}", daemon=True).start()


def die_with_parent(parent_pid: int) -> bool:
    """Ask the kernel to SIGKILL this process when the thread that forked it ends (Linux);
    False where it cannot. Call it in the child right after ``fork`` with the parent's pid
    (read before the fork): a parent that died before the request ends the child here."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        ok = libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False
    if os.getppid() != parent_pid:  # orphaned already: no signal will come
        os._exit(EXIT_CODE)
    return ok
