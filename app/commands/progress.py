"""The commands' progress on stderr: a tqdm bar per stage on a terminal (its time when it ends),
a ``stage: N %`` line at every ``step`` otherwise (a log, CI), or nothing (``--quiet``)."""

from __future__ import annotations

import sys
from typing import TextIO

from tqdm import tqdm

BAR_FORMAT = "{desc:<16} [{bar:30}] {percentage:5.1f} %  {elapsed}"


class StageProgress:
    """``progress(stage, fraction)``: a stage's bar closes when the next begins or at
    ``close()``; ``for_stage(label)`` is the one-stage ``progress(fraction)`` of a study."""

    def __init__(
        self, stream: TextIO | None = None, *, step: float = 0.25, quiet: bool = False
    ) -> None:
        # sys.stderr now, not at import (a caller may have replaced it since).
        self.stream = sys.stderr if stream is None else stream
        self.tty = self.stream.isatty()
        self.step = step
        self.quiet = quiet
        self.stage: str | None = None
        self.bar: tqdm | None = None
        self.last_step = -1

    def __call__(self, stage: str, fraction: float) -> None:
        if self.quiet:
            return
        if stage != self.stage:
            self.close()
            self.stage, self.last_step = stage, -1
            if self.tty:
                self.bar = tqdm(total=100.0, desc=stage, file=self.stream, bar_format=BAR_FORMAT)
        if self.bar is not None:
            self.bar.update(100.0 * fraction - self.bar.n)
            return
        reached = int(fraction / self.step + 1e-9)
        if reached > self.last_step:
            self.last_step = reached
            self.stream.write(f"{stage}: {reached * self.step * 100:g} %\n")
            self.stream.flush()

    def for_stage(self, label: str):
        return lambda fraction: self(label, fraction)

    def close(self) -> None:
        """End the current bar's line (before an error message, too)."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None
