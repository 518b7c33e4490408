"""Answers of the part's slow steps kept by a digest of their input, a few at a time.

PROBLEM   A cell change rebuilds the cell from the project. An uploaded part's file was read
          again in an isolated process (about 1.1 s for 80k triangles) although its bytes had
          not changed (a new tool radius, a work-object move), and the supervisor ran qhull
          (0.4 s) on vertices the isolated check had just run it on.
STRATEGY  Both steps are functions of bytes: keep their last few answers keyed by a BLAKE2b
          digest of those bytes (about 1 ms a MB), bounded in count and in bytes, so the
          memory a server gives back after a cell change (``app/memory.py``) stays bounded
          too. An answer is the same whether it was kept or computed: only successes are
          kept, and callers hand out copies of kept arrays.
SOLUTION  ``Memo(max_entries=, max_bytes=)`` with ``get(key)`` and ``put(key, value, nbytes)``;
          ``digest(*parts)`` of bytes, numbers, strings and numpy arrays (their dtype and
          shape included).
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from typing import Any

import numpy as np


def digest(*parts: Any) -> bytes:
    """A 32-byte BLAKE2b digest of ``parts`` (bytes, str, int, float or numpy arrays, an
    array's dtype and shape included), each part delimited so that none runs into the next."""
    h = hashlib.blake2b(digest_size=32)
    for part in parts:
        if isinstance(part, np.ndarray):
            a = np.ascontiguousarray(part.view(np.ndarray))
            h.update(f"array {a.dtype.str} {a.shape};".encode())
            h.update(a.data)
        elif isinstance(part, bytes | bytearray | memoryview):
            h.update(f"bytes {len(part)};".encode())
            h.update(part)
        else:
            h.update(f"{type(part).__name__} {part!r};".encode())
    return h.digest()


class Memo:
    """A thread-safe least-recently-used store of at most ``max_entries`` values holding
    ``max_bytes`` in all (a value larger than that is not kept)."""

    def __init__(self, *, max_entries: int, max_bytes: int) -> None:
        self.max_entries = max_entries
        self.max_bytes = max_bytes
        self._lock = threading.Lock()
        self._values: OrderedDict[bytes, tuple[Any, int]] = OrderedDict()
        self._bytes = 0

    def get(self, key: bytes) -> Any | None:
        """The value kept for ``key`` (now the most recently used), or None."""
        with self._lock:
            kept = self._values.get(key)
            if kept is None:
                return None
            self._values.move_to_end(key)
            return kept[0]

    def put(self, key: bytes, value: Any, nbytes: int) -> None:
        """Keep ``value`` (about ``nbytes`` large) for ``key``, dropping the least recently
        used values beyond the bounds."""
        if nbytes > self.max_bytes:
            return
        with self._lock:
            old = self._values.pop(key, None)
            if old is not None:
                self._bytes -= old[1]
            self._values[key] = (value, nbytes)
            self._bytes += nbytes
            while len(self._values) > self.max_entries or self._bytes > self.max_bytes:
                _, (_, dropped) = self._values.popitem(last=False)
                self._bytes -= dropped

    def clear(self) -> None:
        """Forget every value."""
        with self._lock:
            self._values.clear()
            self._bytes = 0

    def __len__(self) -> int:
        return len(self._values)
