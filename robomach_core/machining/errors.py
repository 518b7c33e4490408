"""Errors of the machining simulation, each a subclass of the robomach hierarchy."""

from __future__ import annotations

from robomach_core.errors import CancelledError, InvalidInputError

__all__ = ["CancelledError", "MachiningSettingsError", "SampleLimitError", "StockError"]


class MachiningSettingsError(InvalidInputError):
    """A machining setting is outside its physical range or malformed."""


class StockError(InvalidInputError):
    """The stock (allowance profile, stock mesh or path) cannot describe the part before cutting."""


class SampleLimitError(InvalidInputError):
    """The run would record more samples than the configured cap allows."""
