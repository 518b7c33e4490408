"""The error hierarchy of robomach_core.

Every error a user can cause subclasses a builtin and ``RobomachError``, so the CLI can print a
one-line message and the API can map it to a 4xx response. Sub-packages (``cmrr``, ``stiffness``)
keep their own errors in their own ``errors`` module, subclassing these.
"""

from __future__ import annotations


class RobomachError(Exception):
    """Base class of every error robomach reports to a user."""


class InvalidInputError(RobomachError, ValueError):
    """A parameter or setting is outside its allowed range or of the wrong form."""


class UnknownNameError(RobomachError, KeyError):
    """A robot, workpiece, tool or other named item does not exist."""

    def __str__(self) -> str:  # KeyError quotes its message; users should see it plain.
        return str(self.args[0]) if self.args else "unknown name"


class MeshFileError(RobomachError, ValueError):
    """A mesh file cannot be read, is empty, or exceeds the size limits."""


class UnreachableTargetError(RobomachError, ValueError):
    """A pose is outside the robot's workspace or would violate its joint limits."""


class SingularConfigurationError(RobomachError, ValueError):
    """The robot is at or too near a kinematic singularity to follow the motion."""


class NotEnoughGuidePointsError(RobomachError, ValueError):
    """Path learning needs at least two guide points."""


class ForceLimitError(RobomachError, RuntimeError):
    """A contact force exceeded the protection limit."""


class CancelledError(RobomachError, RuntimeError):
    """A long-running job was cancelled by the user."""
