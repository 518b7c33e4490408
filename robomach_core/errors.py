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


class NotFoundError(RobomachError, KeyError):
    """A guide point, project, job or export with that index or id does not exist."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else "not found"


class ConflictError(RobomachError, RuntimeError):
    """The action does not fit the current state (e.g. post-processing before a recording)."""


class MeshFileError(RobomachError, ValueError):
    """A mesh file cannot be read, is empty, or exceeds the size limits."""


class UnreachableTargetError(RobomachError, ValueError):
    """A pose is outside the robot's workspace or would violate its joint limits."""


class SingularConfigurationError(RobomachError, ValueError):
    """The robot is at or too near a kinematic singularity to follow the motion."""


class NotEnoughGuidePointsError(RobomachError, ValueError):
    """Path learning needs at least two guide points."""


class RouteRefusedError(InvalidInputError):
    """The guide points cannot be learned as taught: refused before any motion, saying why and
    what to do (points on two walls, an open wall taught as a loop, a click between walls)."""


class WallSideError(RouteRefusedError):
    """The side of the wall to follow cannot be told from the guide points: set it."""


class ForceLimitError(RobomachError, RuntimeError):
    """A contact force exceeded the protection limit."""


class CancelledError(RobomachError, RuntimeError):
    """A long-running job was cancelled by the user."""


class SupervisionError(RobomachError, RuntimeError):
    """Supervision refused a motion: a joint limit, a singularity, the edge of reach or a collision.

    Attributes:
        cause: The kind of limit (``"wrist singularity"``, ``"collision"``, ...).
        axis: The axis concerned, 1-based, or None.
        stop: The ``supervision.SupervisionStop`` with the details.
        state: The last safe state (the caller's state type), to continue from.
    """

    def __init__(
        self,
        message: str,
        *,
        cause: str = "supervision",
        axis: int | None = None,
        stop: object | None = None,
        state: object | None = None,
    ) -> None:
        super().__init__(message)
        self.cause = cause
        self.axis = axis
        self.stop = stop
        self.state = state

    def with_note(self, note: str) -> SupervisionError:
        """The same refusal with ``note`` appended to its message (what the user can do)."""
        return SupervisionError(
            f"{self}; {note}", cause=self.cause, axis=self.axis, stop=self.stop, state=self.state
        )

    def with_cause_note(self, arm: str, *, place: str = "the work object") -> SupervisionError:
        """The refusal with what to do about its own cause (issue 31: a wound-up axis 6 was
        reported as the part beyond the arm's reach): ``place`` says how the part is moved."""
        if self.cause == "joint limit" and self.axis == 6:
            note = (
                "axis 6 is wound to the end of its range (the tool turned about its own axis): "
                "press Home or jog axis 6 back a turn, and keep the tool's turn about its axis "
                "the same at every point"
            )
        elif self.cause in ("edge of reach", "elbow singularity"):
            note = (
                f"the part may be beyond the {arm} arm's reach: place it nearer with {place}, or "
                "choose a larger arm"
            )
        elif self.cause == "collision":
            note = (
                f"the arm or the tool would meet what the message names: move the part with "
                f"{place}, or lift the tool clear first"
            )
        elif self.cause == "joint limit":
            note = (
                f"axis {self.axis} is at the end of its range: press Home, or place the part "
                f"elsewhere with {place}"
            )
        elif self.cause in ("wrist singularity", "shoulder singularity"):
            note = (
                f"the arm passes a {self.cause}: place the part elsewhere with {place}, or turn "
                "or tilt the tool"
            )
        else:
            return self
        return self.with_note(note)


class NoContactError(RobomachError, RuntimeError):
    """A guarded move travelled its whole distance without touching anything.

    Attributes:
        state: Where the move ended, to continue from.
    """

    def __init__(self, message: str, *, state: object | None = None) -> None:
        super().__init__(message)
        self.state = state


class ContactStopError(RobomachError, RuntimeError):
    """A motion was stopped by contact with the part before it reached its goal.

    Attributes:
        state: Where the motion ended, in contact, to continue from.
    """

    def __init__(self, message: str, *, state: object | None = None) -> None:
        super().__init__(message)
        self.state = state
