"""Giving memory back to the operating system after the server let go of a large value.

PROBLEM   A cell change drops the old cell (its robot, supervisor, contact model, the part's
          mesh and trees: 50-150 MB for an 80k-triangle upload), a comparison the pool's
          unpickled runs. Python frees them, but (1) the ones held in reference cycles (a
          robot and the supervisor kept on it) wait for a full collection, and (2) glibc keeps
          freed heap pages in its arenas (one per thread that allocated: uvicorn's pool, the
          job worker, the GUI's refresh), so the process's resident memory stayed 150-500 MB
          above its working set and wandered with each change (issue 32, point 2).
STRATEGY  After such a release: collect the cycles, then ask glibc to return the free pages of
          every arena (``malloc_trim``); both take milliseconds to a few tenths of a second,
          next to the seconds a cell change or a comparison takes. Elsewhere (not glibc) the
          collection alone runs.
SOLUTION  ``give_back()``.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import gc
import logging

log = logging.getLogger(__name__)


@functools.cache
def _malloc_trim():  # -> the C function, or None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):  # not glibc (musl, macOS)
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return trim


def give_back() -> None:
    """Collect garbage held in cycles and return free heap pages to the operating system."""
    gc.collect()
    trim = _malloc_trim()
    if trim is not None:
        trim(0)
