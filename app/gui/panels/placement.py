"""Place the part panel: the work object's x, y, z and three angles, the part moving in the
scene as the numbers change (nothing applied), then placed (a cell change) or put back.

The numbers are those of ``robomach demo --wobj`` and ``PUT /api/cell`` (``wobj_mm_deg``):
x, y, z in mm and rx, ry, rz in degrees about the base's fixed x, then y, then z axes. What
is being tried is the session's ``preview`` (shared with the pendant, whose 3D scene is this
one); placing it is the session's cell change.
"""

from __future__ import annotations

import numpy as np
import viser

from app.session import Session
from robomach_core.limits import WOBJ_POSITION_MM

from .feedback import guarded
from .inputs import set_value

ANGLE_RANGE_DEG = (-180.0, 180.0)
AXES = ("x", "y", "z")


class PlacementPanel:
    """The "Place the part" folder (module docstring).

    Args:
        server: The viser server.
        session: The workbench session (its ``preview`` and its cell change).
    """

    def __init__(self, server: viser.ViserServer, session: Session) -> None:
        self.session = session
        self._mirrored: tuple[float, ...] | None = None  # what refresh last wrote
        placed = self._placed()
        lo, hi = WOBJ_POSITION_MM.min, WOBJ_POSITION_MM.max
        with server.gui.add_folder("Place the part", expand_by_default=False):
            self.position = [
                server.gui.add_number(
                    f"{a} (mm)",
                    placed[i],
                    min=lo,
                    max=hi,
                    step=1.0,
                    hint=f"The work object's origin along the base's {a} axis",
                )  # fmt: skip
                for i, a in enumerate(AXES)
            ]
            self.angles = [
                server.gui.add_number(
                    f"r{a} (deg)",
                    placed[3 + i],
                    min=ANGLE_RANGE_DEG[0],
                    max=ANGLE_RANGE_DEG[1],
                    step=0.5,
                    hint=f"Turn about the base's fixed {a} axis (applied x, then y, then z)",
                )
                for i, a in enumerate(AXES)
            ]
            self.note = server.gui.add_markdown("")
            self.place = server.gui.add_button(
                "Place the part here", icon=viser.Icon.CHECK, color="green", disabled=True,
                hint="A cell change: the robot goes home, the guide points and the proposal "
                "are cleared (the recording stays in the project, out of date)",
            )  # fmt: skip
            self.back = server.gui.add_button(
                "Put it back", icon=viser.Icon.ARROW_BACK_UP, disabled=True,
                hint="Forget the numbers tried: the part is drawn where it is placed",
            )  # fmt: skip
        for control in (*self.position, *self.angles):
            control.on_update(guarded("Place the part", lambda e: self._try()))
        self.place.on_click(guarded("Place the part", lambda e: self._place()))
        self.back.on_click(guarded("Place the part", lambda e: self.session.preview.clear()))
        self.refresh()

    def values(self) -> tuple[float, ...]:
        """The numbers in the panel: x, y, z [mm], rx, ry, rz [deg]."""
        return tuple(float(c.value) for c in (*self.position, *self.angles))

    def _placed(self) -> tuple[float, ...]:
        return self.session.preview.placed()

    def _try(self) -> None:
        values = self.values()
        if np.allclose(values, self._placed(), atol=1e-6):
            self.session.preview.clear()
        else:
            self.session.preview.set(values)

    def _place(self) -> None:
        values = self.values()
        self.session.set_cell(wobj_mm_deg=values)
        self.session.preview.clear()

    def refresh(self) -> None:
        """Mirror the placement: what is being tried (from here or the pendant), else where
        the part is; written into the inputs only when that changed since the last mirror,
        so a refresh for another cause (the cell after an upload, on a later tick) does not
        overwrite a number the person is typing before it reaches the preview."""
        tried = self.session.preview.values()
        shown = tried if tried is not None else self._placed()
        if shown != self._mirrored:
            self._mirrored = shown
            for control, value in zip((*self.position, *self.angles), shown, strict=True):
                if abs(float(control.value) - value) > 1e-6:
                    set_value(control, value)
        self.place.disabled = self.back.disabled = tried is None
        x, y, z, rx, ry, rz = self._placed()
        where = (
            f"Placed at ({x:.1f}, {y:.1f}, {z:.1f}) mm, turned ({rx:.1f}, {ry:.1f}, {rz:.1f}) "
            "deg (base frame)."
        )
        self.note.content = (
            f"{where}\n\n**Trying the numbers above**: the part is drawn there; *Place the "
            "part here* to use them."
            if tried is not None
            else where
        )
