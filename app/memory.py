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
          A full collection walks every object the collector tracks, and a server's imports
          alone make 165k of them (0.1-0.16 s per collection): ``serve`` freezes them once
          started (``freeze_imports``), so a collection walks only what came after.
SOLUTION  ``give_back()``; ``freeze_imports()`` once, before the session is opened.
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


def freeze_imports() -> None:
    """Move every object alive now (the imported modules, their classes and functions) out of
    the collector's sight (``gc.freeze``): they live as long as the process, and each full
    collection of ``give_back`` walked them all. Call it once, after the imports and before
    the session opens, so that no cell or project of the session is frozen (what is frozen is
    never collected)."""
    gc.collect()  # the imports' own garbage goes first
    gc.freeze()
