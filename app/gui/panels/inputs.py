"""Number inputs over a ``limits`` range: the range's default, bounds and label in one place;
``set_value``, the typed write of an input's value."""

from __future__ import annotations

from typing import TYPE_CHECKING, TypeVar

import viser

from robomach_core.limits import Range

if TYPE_CHECKING:
    from viser._gui_handles import _GuiInputHandle  # the base of every input handle

T = TypeVar("T")


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


def set_value(handle: _GuiInputHandle[T], value: T) -> None:
    """``handle.value = value``, type-checked against the input's value type.

    viser 1.1 defines the ``value`` setter apart from its getter (another method between them),
    so mypy reads the property as read-only and refuses every assignment; this is the one place
    that says so."""
    handle.value = value  # type: ignore[misc]  # viser's setter, not seen by mypy (above)
