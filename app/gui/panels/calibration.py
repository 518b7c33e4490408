"""Calibrate by touch panel: touch faces of the real part, see each touch and the CAD the fit
places on them with its residual, accept it or undo.

A real part stands a few millimetres and a degree or two off its CAD (the realistic preset, a
fixture); as on a pendant (ABB's 3-point user frame, KUKA's base measurement) its work object
is measured by touching it. With *Click on the part* set to "touch the face (calibration)", a
click on a face makes the robot touch it, as many times as the three-two-one still needs from
a face of that kind (``teaching.face_touches``: four on the top, three and two on two sides),
each a guarded move at the touch force from off the face. The session's ``calibration`` (the
same the REST API and the pendant use) keeps the touches and fits the CAD to them
(``registration.fit_wobj``, point-to-plane least squares); the scene shows the touches and,
until it is accepted, the CAD where the fit puts it.
"""

from __future__ import annotations

import numpy as np
import viser

from app.session import JobInfo, Session
from robomach_core import limits
from robomach_core.teaching import MIN_TOUCHES, UP_COS, face_touch_points, touches_for_face

from ..scene import CellScene
from .feedback import guarded, notify_error
from .inputs import set_value

REACH_ABOVE_M = 0.015  # a face's touch starts about this far off it
INTRO = (
    "The part in the cell may stand a few mm and a degree or two off its CAD. Set *Click on "
    "the part* to **touch the face (calibration)** (or press *Touch faces*), then click three "
    "faces: the top, a side and a side across it. The robot touches each where the frame "
    "needs it (4, 3 and 2 touches), the CAD is fitted to the touches (green: where it really "
    "is) and you accept it."
)


class CalibrationPanel:
    """The "Calibrate by touch" folder (module docstring).

    Args:
        server: The viser server.
        session: The workbench session (its ``calibration`` and ``pointing``).
        scene: The cell's scene (the touches and the fitted CAD).
    """

    def __init__(self, server: viser.ViserServer, session: Session, scene: CellScene) -> None:
        self.session = session
        self.scene = scene
        state = session.calibration.state()
        with server.gui.add_folder("Calibrate by touch", expand_by_default=False):
            server.gui.add_markdown(INTRO)
            self.force = server.gui.add_number(
                "Touch force (N)", state.force_N, min=limits.TOUCH_OFF_FORCE_N.min,
                max=limits.TOUCH_OFF_FORCE_N.max, step=0.5,
                hint="Each touch moves until the part pushes back this hard",
            )  # fmt: skip
            self.touch_mode = server.gui.add_button(
                "Touch faces", icon=viser.Icon.HAND_FINGER,
                hint="A click on the part then touches the face clicked",
            )  # fmt: skip
            self.auto = server.gui.add_button(
                "Touch the planned features", icon=viser.Icon.ROBOT,
                hint="The example operator touches 3 points of the top face and 3 and 2 of two "
                "sides facing across each other (a job)",
            )  # fmt: skip
            self.progress = server.gui.add_progress_bar(0.0, visible=False, animated=True)
            self.touches = server.gui.add_markdown("")
            self.fit = server.gui.add_markdown("")
            self.accept = server.gui.add_button(
                "Accept the calibration", icon=viser.Icon.CHECK, color="green", disabled=True,
                hint="The CAD is placed where the touches found the part: teaching, the "
                "checks, learning's route and the CAD-only program use it",
            )  # fmt: skip
            self.undo = server.gui.add_button("Undo last touch", icon=viser.Icon.ARROW_BACK_UP)
            self.clear = server.gui.add_button("Clear the touches", icon=viser.Icon.TRASH)
            self.remove = server.gui.add_button(
                "Back to the placement", icon=viser.Icon.X, disabled=True,
                hint="Forget the accepted calibration: the CAD goes back where it is placed",
            )  # fmt: skip
        calibration = session.calibration  # the force goes with each touch (``touch_face``)
        self.touch_mode.on_click(
            guarded("Touch faces", lambda e: session.pointing.set_settings(click_mode="touch"))
        )
        self.auto.on_click(
            guarded("Calibration", lambda e: calibration.start_auto(float(self.force.value)))
        )
        self.accept.on_click(guarded("Calibration", lambda e: self._accept()))
        self.undo.on_click(guarded("Calibration", lambda e: calibration.undo()))
        self.clear.on_click(
            guarded("Calibration", lambda e: calibration.clear(force_N=float(self.force.value)))
        )
        self.remove.on_click(guarded("Calibration", lambda e: calibration.remove()))
        self.last_touches: np.ndarray = np.zeros((0, 3))  # the points the last click touched
        self.refresh()

    def _accept(self) -> None:
        """The fit becomes the work object; a click on the part proposes the wall again (the
        touching is done)."""
        self.session.calibration.accept()
        if self.session.pointing.click_mode == "touch":
            self.session.pointing.set_settings(click_mode="propose")

    # --- a click in the touch mode -----------------------------------------------------------

    def touch_face(
        self, point_wobj_m: np.ndarray, normal: np.ndarray, client: viser.ClientHandle
    ) -> None:
        """Touch the face clicked, as many times as it should take (module docstring); an
        error (nothing met, busy, a limit) goes to the user who clicked."""
        try:
            self._touch_face(point_wobj_m, normal)
        except Exception as exc:  # the user's click: say why, keep the touches made
            from robomach_core.errors import RobomachError

            if not isinstance(exc, RobomachError):
                raise
            notify_error(client, "Touch", str(exc))

    def _touch_face(self, point_wobj_m: np.ndarray, normal: np.ndarray) -> None:
        calibration = self.session.calibration
        cad = self.session.robot.workpiece.cad()
        up_wobj = abs(float(np.asarray(normal, dtype=float)[2])) > UP_COS
        up_base = cad.T_base_wobj[:3, 2]
        made = [t.direction for t in calibration.state().touches]
        count = touches_for_face(up_wobj, made, up_axis=up_base)
        points = face_touch_points(cad, point_wobj_m, count, reachable=self._reachable(cad))
        self.last_touches = points
        for p in points:
            calibration.touch(at_wobj_m=p, force_N=float(self.force.value))

    def _reachable(self, cad):
        """(point_wobj) -> whether the arm stands over it with the tool down, a little above
        (where a touch of that face starts)."""
        from robomach_core.cell import TOOL_DOWN
        from robomach_core.errors import RobomachError

        robot = self.session.robot.cell.robot
        T_wobj = cad.T_base_wobj

        def reachable(point_wobj: np.ndarray) -> bool:
            T = np.eye(4)
            T[:3, :3] = TOOL_DOWN
            T[:3, 3] = T_wobj[:3, :3] @ point_wobj + T_wobj[:3, 3] + T_wobj[:3, 2] * REACH_ABOVE_M
            try:
                robot.ik(T, robot.home_rad)
            except RobomachError:
                return False
            return True

        return reachable

    # --- mirroring the session -----------------------------------------------------------

    def refresh(self) -> None:
        """The touches (scene and list), the fit or what it lacks, the buttons."""
        state = self.session.calibration.state()
        fit = state.fit
        self.scene.set_calibration(
            state.touches,
            None if fit is None else fit.residuals_m,
            None if fit is None or state.registration is not None else fit.T_base_wobj,
            labelled=state.registration is None,
        )
        self.touches.content = touches_markdown(state)
        self.fit.content = fit_markdown(state)
        self.accept.disabled = fit is None
        self.remove.disabled = state.registration is None
        if abs(float(self.force.value) - state.force_N) > 1e-9:
            set_value(self.force, state.force_N)

    def show_job(self, job: JobInfo | None) -> None:
        """Progress of the example operator's touches (None hides the bar)."""
        self.progress.visible = job is not None
        self.auto.disabled = job is not None
        if job is not None:
            set_value(self.progress, round(job.progress * 100.0, 1))


def touches_markdown(state) -> str:
    """The touches as a table: the face each met and its residual once fitted."""
    if not state.touches:
        return f"*No touch yet: {MIN_TOUCHES} at least fix the frame.*"
    fit = state.fit
    rows = ["| touch | face | force (N) | residual (mm) |", "|---|---|---:|---:|"]
    for k, t in enumerate(state.touches):
        face = t.feature or "-"
        if fit is not None and k < len(fit.faces):
            face = fit.faces[k]
        residual = "-" if fit is None else f"{fit.residuals_m[k] * 1e3:+.3f}"
        rows.append(f"| T{k + 1} | {face} | {t.force_N:.1f} | {residual} |")
    return "\n".join(rows)


def fit_markdown(state) -> str:
    """The fit in one paragraph (or what the touches still lack), and what is accepted."""
    lines = []
    if state.fit is not None:
        lines.append(f"**Fit**: {state.fit.describe()}.")
    elif state.touches:
        lines.append(f"*No fit yet*: {state.fit_error}")
    reg = state.registration
    if reg is not None:
        x, y, z, rx, ry, rz = reg.wobj_mm_deg
        lines.append(
            f"**Accepted**: the CAD stands at ({x:.2f}, {y:.2f}, {z:.2f}) mm, turned ({rx:.2f}, "
            f"{ry:.2f}, {rz:.2f}) deg; residual RMS {reg.rms_mm:.3f} mm, max {reg.max_mm:.3f} mm."
        )
    return "\n\n".join(lines)
