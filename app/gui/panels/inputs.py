"""Number inputs over a ``limits`` range: the range's default, bounds and label in one place."""

from __future__ import annotations

import viser

from robomach_core.limits import Range


def range_number(
    server: viser.ViserServer,
    label: str,
    limits_range: Range,
    *,
    min: float | None = None,
    step: float | None = None,
    hint: str | None = None,
) -> viser.GuiNumberHandle[float]:
    """A number input starting at ``limits_range``'s default, bounded by it (``min`` when a
    panel needs a higher floor than the range's, e.g. a step that must move)."""
    return server.gui.add_number(
        label,
        limits_range.default_value(),
        min=limits_range.min if min is None else min,
        max=limits_range.max,
        step=step,
        hint=hint,
    )
