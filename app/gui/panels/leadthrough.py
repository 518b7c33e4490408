"""Lead-through panel: compliance, the spring handle, push and orientation-jog buttons, pose.

The handle on the tool is a virtual spring: once the user drags it, its offset from the TCP
pushes the tool with ``F = k * offset`` (capped), on the compliant axes, until the tool reaches
the handle or the wall pushes back as hard. Any move the spring did not make (a jog, a push
button, the API, a job) snaps the handle back onto the tool, so a stale offset never pulls.
"""

from __future__ import annotations

import math
import time

import numpy as np
import viser

from app.session import Session
from robomach_core import limits
from robomach_core.cell import AXES
from robomach_core.choices import COMPLIANCE_FRAMES

from ..scene import CellScene
from .feedback import guarded
from .inputs import range_number, set_value

# Three buttons a row: six do not fit the sidebar.
PUSH_ROWS = (("Push +", ("+X", "+Y", "+Z")), ("Push -", ("-X", "-Y", "-Z")))
JOG_ROWS = (("Jog tool +", ("+Rx", "+Ry", "+Rz")), ("Jog tool -", ("-Rx", "-Ry", "-Rz")))
SPRING_DEADBAND_M = 0.0005  # offsets below this push nothing (the handle sits on the tool)
SPRING_MAX_N = 40.0
SPRING_MAX_STEP_S = 0.1  # a late tick never integrates more than this at once
AXIS_LABELS = {"x": "X", "y": "Y", "z": "Z", "rx": "Rx", "ry": "Ry", "rz": "Rz"}


def euler_zyx_deg(T: np.ndarray) -> np.ndarray:
    """ABB EulerZYX angles [rx, ry, rz] in degrees of a rotation (R = Rz Ry Rx)."""
    R = T[:3, :3]
    ry = math.asin(max(-1.0, min(1.0, -R[2, 0])))
    rx = math.atan2(R[2, 1], R[2, 2])
    rz = math.atan2(R[1, 0], R[0, 0])
    return np.degrees([rx, ry, rz])


def pose_markdown(snapshot, push_N: np.ndarray | None) -> str:
    """The live pose readout: position in mm, orientation in degrees, forces in N."""
    p = snapshot.T_base_tcp[:3, 3] * 1e3
    r = euler_zyx_deg(snapshot.T_base_tcp)
    f = snapshot.wrench[:3]
    push = 0.0 if push_N is None else float(np.linalg.norm(push_N))
    contact = "**in contact**" if snapshot.in_contact else "free"
    busy = " - *a job moves the robot*" if snapshot.busy else ""
    return (
        "| | X | Y | Z |\n|---|---:|---:|---:|\n"
        f"| mm | {p[0]:.2f} | {p[1]:.2f} | {p[2]:.2f} |\n"
        f"| deg | {r[0]:.2f} | {r[1]:.2f} | {r[2]:.2f} |\n"
        f"| F (N) | {f[0]:.1f} | {f[1]:.1f} | {f[2]:.1f} |\n\n"
        f"Contact {np.linalg.norm(f):.1f} N, {contact}; push {push:.1f} N{busy}"
    )


class LeadThroughPanel:
    """Compliance toggles, the spring handle, push buttons, orientation jogs, the live pose."""

    def __init__(self, server: viser.ViserServer, session: Session, scene: CellScene) -> None:
        self.session = session
        self.scene = scene
        sel = session.robot.selection
        with server.gui.add_folder("Lead-through"):
            self.axes = {
                a: server.gui.add_checkbox(
                    f"Compliant {AXIS_LABELS[a]}",
                    a in sel.axes,
                    hint="Compliant axes follow the push; the others stay stiff",
                )
                for a in AXES
            }
            self.frame = server.gui.add_dropdown(
                "Compliance frame", COMPLIANCE_FRAMES, initial_value=sel.frame
            )
            # Off by default: the handle's gizmo stands on the tool, and a gizmo takes every
            # click on it, so it took the clicks meant for the wall beside the tool (3 of 22,
            # issue 31). The rest of the robot lets clicks through to the part.
            self.show_handle = server.gui.add_checkbox(
                "Show push handle",
                False,
                hint="Drag the handle to push the tool. While it shows, it takes the clicks on "
                "the part near the tool; and it is heavy to draw without a GPU",
            )
            self.spring = server.gui.add_slider(
                "Handle spring (N/mm)",
                limits.HANDLE_SPRING_N_MM.min,
                limits.HANDLE_SPRING_N_MM.max,
                0.1,
                0.5,
                hint="Drag the handle on the tool: its offset from the TCP times this pushes",
            )
            self.release = server.gui.add_button(
                "Release handle", icon=viser.Icon.HAND_STOP, hint="Put the handle back on the tool"
            )
            self.push_force = range_number(server, "Push force (N)", limits.PUSH_FORCE_N)
            self.push_time = server.gui.add_number("Push time (s)", 0.5, min=0.05, max=10.0)
            self.push = [server.gui.add_button_group(label, d) for label, d in PUSH_ROWS]
            self.jog_step = range_number(server, "Jog step (deg)", limits.JOG_TURN_DEG, min=0.1)
            self.jog = [server.gui.add_button_group(label, d) for label, d in JOG_ROWS]
            self.home = server.gui.add_button("Home", icon=viser.Icon.HOME)
            self.pose = server.gui.add_markdown("")
        select = guarded(
            "Compliance",
            lambda e: self.session.robot.select(
                [a for a, b in self.axes.items() if b.value], self.frame.value
            ),
        )
        for box in self.axes.values():
            box.on_update(select)
        self.frame.on_update(select)
        for group in self.push:
            group.on_click(
                guarded(
                    "Push",
                    lambda e: self.session.teach.push(
                        self._push_wrench(e.target.value), float(self.push_time.value)
                    ),
                )
            )
        for group in self.jog:
            group.on_click(
                guarded(
                    "Jog",
                    lambda e: self.session.teach.jog(
                        e.target.value[1:].lower(),
                        math.radians(self.jog_step.value) * _sign(e.target.value),
                    ),
                )
            )
        self.home.on_click(guarded("Home", lambda e: self.session.learning.go_home()))
        self.release.on_click(lambda e: self.disarm())
        self.show_handle.on_update(lambda e: self.set_handle_visible(self.show_handle.value))
        scene.handle.on_update(lambda e: self.arm())
        self._armed = False
        self._last_tick = time.monotonic()
        self._spring_time_s: float | None = None  # sim time after the spring's last push
        self.push_N: np.ndarray | None = None
        self._tool_followed_m = np.zeros(3)  # the TCP the handle was last put on
        self.disarm()  # the handle starts on the tool
        self.scene.handle.visible = self.show_handle.value

    def _push_wrench(self, direction: str) -> np.ndarray:
        w = np.zeros(6)
        w["XYZ".index(direction[1])] = _sign(direction) * float(self.push_force.value)
        return w

    # ---------------------------------------------------------------- the spring handle

    def arm(self) -> None:
        """The user dragged the handle: its offset now pushes."""
        self._armed = True
        self._last_tick = time.monotonic()

    def disarm(self) -> None:
        """Stop pushing and put the handle back on the tool."""
        self._armed = False
        self.push_N = None
        self._tool_followed_m = self.session.robot.snapshot().T_base_tcp[:3, 3].copy()
        self.scene.handle_to(self._tool_followed_m)

    def _follow_tool(self, tcp_m: np.ndarray) -> None:
        """Put the disarmed handle back on the tool when the tool has moved: never while it
        stands still, so a drag the user has begun (its position set, ``arm`` not yet called)
        is not undone between the two."""
        if not np.allclose(tcp_m, self._tool_followed_m, rtol=0.0, atol=1e-6):
            self._tool_followed_m = np.array(tcp_m, dtype=float)
            self.scene.handle_to(self._tool_followed_m)

    def set_handle_visible(self, visible: bool) -> None:
        """Show or hide the handle (a hidden handle does not push)."""
        self.disarm()
        self.scene.handle.visible = visible

    def spring_force(self, snapshot) -> np.ndarray | None:
        """(3,) push force of the handle's offset from the TCP [N], or None when disarmed."""
        if not self._armed:
            return None
        offset = np.asarray(self.scene.handle.position, dtype=float) - snapshot.T_base_tcp[:3, 3]
        distance = float(np.linalg.norm(offset))
        if distance < SPRING_DEADBAND_M:
            return np.zeros(3)
        force = offset * float(self.spring.value) * 1e3  # N/mm -> N/m
        norm = float(np.linalg.norm(force))
        return force if norm <= SPRING_MAX_N else force * (SPRING_MAX_N / norm)

    def tick(self, snapshot):
        """One scene tick: push by the spring for the real time elapsed; returns the snapshot
        after the push (or the given one). Called by the workbench's updater thread."""
        now = time.monotonic()
        elapsed = min(now - self._last_tick, SPRING_MAX_STEP_S)
        self._last_tick = now
        if snapshot.busy:
            self._armed, self.push_N = False, None
            self._follow_tool(snapshot.T_base_tcp[:3, 3])
            return snapshot
        if (
            self._armed
            and self._spring_time_s is not None
            and not math.isclose(snapshot.time_s, self._spring_time_s, abs_tol=1e-9)
        ):
            self._armed = False  # someone else moved the robot since the spring's last push
        force = self.spring_force(snapshot)
        self.push_N = force
        if force is None:
            self._spring_time_s = None
            self._follow_tool(snapshot.T_base_tcp[:3, 3])
            return snapshot
        if not np.any(force) or elapsed <= 0:
            self._spring_time_s = snapshot.time_s
            return snapshot
        try:
            snapshot = self.session.teach.push(np.concatenate([force, np.zeros(3)]), elapsed)
        except Exception:  # busy or out of reach: stop pushing, keep the GUI alive
            self.disarm()
            raise
        self._spring_time_s = snapshot.time_s
        return snapshot

    def refresh_compliance(self) -> None:
        """Mirror the session's compliance selection (after an API change)."""
        sel = self.session.robot.selection
        for a, box in self.axes.items():
            set_value(box, a in sel.axes)
        set_value(self.frame, sel.frame)

    def show_pose(self, snapshot) -> None:
        self.pose.content = pose_markdown(snapshot, self.push_N)


def _sign(direction: str) -> float:
    return -1.0 if direction.startswith("-") else 1.0
