"""Errors of the stiffness package: identification, equilibrium, settings and studies."""

from __future__ import annotations

from ..errors import InvalidInputError, RobomachError, UnknownNameError


class IdentificationError(InvalidInputError):
    """The measurements cannot determine the joint stiffness (too few or degenerate poses)."""


class ConvergenceError(RobomachError, RuntimeError):
    """A non-linear equilibrium or target correction did not converge."""


class SettingsFileError(InvalidInputError):
    """A compensation settings file is missing, unreadable or malformed."""


class UnknownStudyError(UnknownNameError):
    """The requested compensation study does not exist."""
