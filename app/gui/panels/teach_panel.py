"""Quick-teach panel: jog in mm and degrees in a chosen frame, touch-off, and the tool's view.

The frame is always named beside the numbers. Touch-off is one button per axis direction: the
tool goes along that axis until the wall pushes back with the set force, and stays there, so a
guide point at the wall costs one click (and one "Record"). The gap to the nearest wall and
the contact force are shown live, and the camera can follow the tool tip in close-up.
"""

from __future__ import annotations

import time

import numpy as np
import viser

from app.session import Session
from robomach_core import limits
from robomach_core.choices import JOG_FRAMES

from .feedback import guarded, notify_info
from .inputs import range_number

FRAME_NAMES = {"wobj": "work object", "base": "base", "tool": "tool"}
FOLLOW_DISTANCE_M = 0.12  # the close-up camera, this far from the tool tip
FOLLOW_DIRECTION = np.array([0.55, -0.65, 0.52])  # from the tip, towards the camera
VIEW_PERIOD_S = 0.2


class TeachPanel:
    """Frame, steps and jog buttons; touch-off buttons; live gap, force and follow camera."""

    def __init__(self, server: viser.ViserServer, session: Session) -> None:
        self.server = server
        self.session = session
        self._next_view = 0.0
        with server.gui.add_folder("Quick teach"):
            self.frame = server.gui.add_dropdown(
                "Frame", JOG_FRAMES, initial_value="wobj", hint="Axes of the jog and touch-off"
            )
            self.step_mm = range_number(server, "Step (mm)", limits.JOG_STEP_MM, min=0.1, step=0.1)
            self.step_deg = range_number(
                server, "Step (deg)", limits.JOG_TURN_DEG, min=0.1, step=0.1
            )
            self.speed = range_number(server, "Speed (mm/s)", limits.JOG_SPEED_MM_S, step=0.5)
            self.jog_plus = server.gui.add_button_group("Jog +", ("+X", "+Y", "+Z"))
            self.jog_minus = server.gui.add_button_group("Jog -", ("-X", "-Y", "-Z"))
            self.rot_plus = server.gui.add_button_group("Turn +", ("+Rx", "+Ry", "+Rz"))
            self.rot_minus = server.gui.add_button_group("Turn -", ("-Rx", "-Ry", "-Rz"))
            self.force = range_number(server, "Touch force (N)", limits.TOUCH_OFF_FORCE_N)
            self.travel = range_number(  # min more than the range's 0: a touch must move
                server, "Touch travel (mm)", limits.TOUCH_OFF_TRAVEL_MM, min=1.0
            )
            self.touch_plus = server.gui.add_button_group("Touch +", ("+X", "+Y", "+Z"))
            self.touch_minus = server.gui.add_button_group("Touch -", ("-X", "-Y", "-Z"))
            self.record = server.gui.add_button("Record guide point", color="orange")
            self.follow = server.gui.add_checkbox(
                "Follow the tool", False, hint="Close-up camera on the tool tip"
            )
            self.view = server.gui.add_markdown("")
        for group in (self.jog_plus, self.jog_minus, self.rot_plus, self.rot_minus):
            group.on_click(guarded("Jog", self._jog))
        for group in (self.touch_plus, self.touch_minus):
            group.on_click(guarded("Touch-off", self._touch))
        self.record.on_click(guarded("Record", lambda _: self.session.record_guide_point()))
        self.frame.on_update(lambda _: self._show_labels())
        self._show_labels()

    def _show_labels(self) -> None:
        name = FRAME_NAMES[self.frame.value]
        self.jog_plus.label = f"Jog + ({name})"
        self.jog_minus.label = f"Jog - ({name})"
        self.touch_plus.label = f"Touch + ({name})"
        self.touch_minus.label = f"Touch - ({name})"

    def _jog(self, event) -> None:
        sign, axis = event.target.value[0], event.target.value[1:].lower()
        rotational = axis.startswith("r")
        value = self.step_deg.value if rotational else self.step_mm.value
        step = np.radians(value) if rotational else value * 1e-3
        speed = None if rotational else self.speed.value * 1e-3
        self.session.teach.jog(
            axis, float(step) * (1 if sign == "+" else -1), frame=self.frame.value, speed=speed
        )

    def _touch(self, event) -> None:
        sign, axis = event.target.value[0], event.target.value[1:].lower()
        snapshot = self.session.teach.touch_off(
            axis,
            1 if sign == "+" else -1,
            float(self.force.value),
            float(self.travel.value) * 1e-3,
            frame=self.frame.value,
        )
        force = float(np.linalg.norm(snapshot.wrench[:3]))
        notify_info(
            event.client,
            "Touch-off",
            f"touched the part at {force:.1f} N along {sign}{axis.upper()} "
            f"({FRAME_NAMES[self.frame.value]} frame): record the guide point",
        )

    def tick(self, snapshot) -> None:
        """Live gap and force (a few times a second) and the follow camera."""
        now = time.monotonic()
        if now < self._next_view:
            return
        self._next_view = now + VIEW_PERIOD_S
        try:
            v = self.session.teach.tool_view()
        except Exception:  # a cell being rebuilt: next time
            return
        frame = FRAME_NAMES[self.frame.value]
        wall = (
            f"gap to the wall **{v.wall_gap_m * 1e3:.2f} mm**"
            if v.wall_gap_m is not None
            else "above the part's walls"
        )
        nearest = "" if v.face == "wall" else f" (the {v.face} is nearer: {v.gap_m * 1e3:.2f} mm)"
        self.view.content = (
            f"**Tool tip** ({frame} frame for jogs): {wall}{nearest}, "
            f"force **{np.linalg.norm(v.force_N):.1f} N**, "
            f"{'in contact' if v.in_contact else 'free'}; above table {v.table_gap_m * 1e3:.0f} mm"
        )
        if self.follow.value:
            tip = snapshot.T_base_tcp[:3, 3]
            eye = tip + FOLLOW_DIRECTION / np.linalg.norm(FOLLOW_DIRECTION) * FOLLOW_DISTANCE_M
            for client in self.server.get_clients().values():
                with client.atomic():
                    client.camera.position = tuple(eye)
                    client.camera.look_at = tuple(tip)
