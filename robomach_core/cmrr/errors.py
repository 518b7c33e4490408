"""Errors of the CMRR library, each a subclass of the robomach hierarchy."""

from __future__ import annotations

from robomach_core.errors import CancelledError, InvalidInputError, UnknownNameError

__all__ = [
    "CancelledError",
    "CmrrSettingsError",
    "MeshDepthError",
    "UnknownControllerError",
    "UnknownScenarioError",
]


class CmrrSettingsError(InvalidInputError):
    """A CMRR controller, process or scenario setting is out of range or malformed."""


class UnknownControllerError(UnknownNameError):
    """The named CMRR controller does not exist."""


class UnknownScenarioError(UnknownNameError):
    """The named CMRR scenario does not exist."""


class MeshDepthError(InvalidInputError):
    """The depth of cut along a path cannot be computed from the given meshes."""
