"""A placement being tried: the part drawn somewhere else before it is placed there.

PROBLEM   Placing a part is a cell change (the robot goes home, the guide points go), so the
          person must see where the numbers put the part before they apply them, on whichever
          page they type them (the viser workbench or the pendant, whose 3D scene is the
          workbench's).
STRATEGY  The numbers being tried live in the session, beside the project and not in it: not
          saved, dropped by a cell change (their epoch), heard by both pages through the
          ``placement`` topic. The workbench draws the part there; nothing else reads them.
SOLUTION  ``PlacementPreview(session)``, the session's ``preview``: ``set(values)`` (the
          ``--wobj`` numbers: x, y, z mm and rx, ry, rz deg), ``clear()``, ``values()`` and
          ``transform()`` (None when nothing is tried in this cell), ``placed()`` (where the
          part is); ``wobj_values(T)`` turns a frame into those numbers.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .session import Session


def wobj_values(T_base_wobj: np.ndarray) -> tuple[float, ...]:
    """(x, y, z [mm], rx, ry, rz [deg]) of a work-object frame in the ``--wobj`` convention
    (``project.wobj_transform``: R = Rz Ry Rx about the base's fixed axes), to 0.001."""
    from scipy.spatial.transform import Rotation

    T = np.asarray(T_base_wobj, dtype=float)
    angles = Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
    return tuple(round(float(v), 3) + 0.0 for v in (*(T[:3, 3] * 1e3), *angles))


class PlacementPreview:
    """The work-object placement being tried (module docstring)."""

    def __init__(self, session: Session) -> None:
        self._session = session
        self._lock = threading.Lock()
        self._tried: tuple[int, tuple[float, ...]] | None = None

    def set(self, values: Sequence[float]) -> tuple[float, ...]:
        """Try the work object at ``values`` (x, y, z [mm], rx, ry, rz [deg], the numbers of
        ``robomach demo --wobj``; checked against their ranges); both pages draw it."""
        from robomach_core.project import wobj_transform

        wobj_transform(values)  # InvalidInputError naming the number out of range
        v = tuple(float(x) for x in values)
        with self._lock:
            changed = self._tried is None or self._tried[1] != v
            self._tried = (self._session.robot.epoch, v)
        if changed:
            self._session.notify("placement")
        return v

    def clear(self) -> None:
        """Nothing tried: the part is drawn where the cell has it."""
        with self._lock:
            was, self._tried = self._tried, None
        if was is not None:
            self._session.notify("placement")

    def values(self) -> tuple[float, ...] | None:
        """The numbers tried in this cell, or None."""
        with self._lock:
            tried = self._tried
        if tried is None or tried[0] != self._session.robot.epoch:
            return None
        return tried[1]

    def transform(self) -> np.ndarray | None:
        """4x4 work-object frame tried in this cell (base frame, m), or None."""
        from robomach_core.project import wobj_transform

        values = self.values()
        return None if values is None else wobj_transform(values)

    def placed(self) -> tuple[float, ...]:
        """Where the part is placed now (the ``--wobj`` numbers of its work object; its
        placement, not where a calibration registered the CAD)."""
        part = self._session.robot.workpiece
        placed = part.unregistered if part.unregistered is not None else part.cad()
        return wobj_values(placed.T_base_wobj)
