"""Work-object calibration in the workbench: touches of the real part, the fit, its acceptance.

PROBLEM   The part in the cell may stand a few mm and a degree or two off where its CAD is
          placed (the realistic preset, or a real fixture). As on a pendant (ABB's 3-point user
          frame, KUKA's base measurement), the person touches features of the part, sees the
          CAD registered to the touches with its residual, and accepts it, or touches more, or
          undoes a touch; a script does the same over REST; the example operator can do it all.
STRATEGY  The touches are live state of the session, kept with the robot's document in the
          store (they survive a restart) and tied to the part they touched (the cell without
          its registration and tool radius: another arm, part, placement or deviation drops
          them). A touch is a paced guarded move (``Teach.touch_along``) from where the robot
          stands, or from the start the core plans for a picked face (``touch_at``), backed off
          afterwards. The fit is the core's (``registration.fit_wobj``, point-to-plane), always
          from the CAD at its placement, so it says how far the part is from there. Accepting
          commits ``project.with_registration`` and rebuilds the cell, the robot staying where
          it stands; proposals, checks, learning's route and the CAD-only program then use the
          registered CAD (``Workpiece.cad()``).
SOLUTION  ``Calibration(session)``, the session's ``calibration``: ``state()``, ``plan()``,
          ``touch(...)``, ``undo()``, ``clear()``, ``fit()``, ``accept()``, ``remove()``,
          ``start_auto()`` (a robot job: the example operator's touches), ``document()`` /
          ``restore()`` for the store.
"""

from __future__ import annotations

import hashlib
import json
import threading
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from robomach_core import limits
from robomach_core import project as core
from robomach_core.cell import LeadThrough, LeadThroughState
from robomach_core.errors import InvalidInputError, RobomachError
from robomach_core.part import Workpiece, mesh_query
from robomach_core.project import CellSettings, Project
from robomach_core.teaching import (
    MIN_TOUCHES,
    TOUCH_FORCE_N,
    CalibrationError,
    PlannedTouch,
    Touch,
    TouchPlan,
    WobjFit,
    WobjRegistration,
    fit_wobj,
    plan_touches,
    scripted_touches,
    touch_at,
)
from robomach_core.transforms import unit_vector

from .jobs import JobContext
from .records import ConflictError, NotFoundError

if TYPE_CHECKING:
    from .robot import Pose
    from .session import Session

MAX_TOUCHES = 50
SAFE_ABOVE_M = 0.03  # a picked face's touch: the tool comes over at this height above the part


@dataclass(frozen=True)
class CalibrationState:
    """What the calibration panel shows.

    Attributes:
        touches: The touches made so far, in order.
        force_N: The touch force.
        fit: The CAD registered to the touches, when they fix a frame (None otherwise).
        fit_error: Why there is no fit yet ("" when there is one).
        registration: The accepted calibration of the project's cell (None: none).
    """

    touches: tuple[Touch, ...]
    force_N: float
    fit: WobjFit | None
    fit_error: str
    registration: WobjRegistration | None


def part_key(cell: CellSettings, mesh: tuple[str, bytes] | None) -> str:
    """Fingerprint of the part the touches touched: the cell without its registration and
    tool radius (another arm, part, placement or deviation moves or changes the part)."""
    doc = asdict(replace(cell, registration=None, tool_radius_m=0.0))
    h = hashlib.blake2b(json.dumps(doc, sort_keys=True, default=str).encode(), digest_size=12)
    if mesh is not None:
        h.update(mesh[1])
    return h.hexdigest()


def unregistered_cad(part: Workpiece) -> Workpiece:
    """The CAD at the cell's placement (before any calibration moved it)."""
    return part.unregistered if part.unregistered is not None else part.cad()


class Calibration:
    """Work-object calibration of one session (module docstring)."""

    def __init__(self, session: Session) -> None:
        self._session = session
        self._lock = threading.Lock()
        self._touches: tuple[Touch, ...] = ()
        self._key: str | None = None  # the part they touched
        self._force_N = TOUCH_FORCE_N
        self._fit: tuple[tuple[Touch, ...], str, WobjFit | None, str] | None = None
        self._plan: tuple[int, TouchPlan] | None = None

    # --- reading -------------------------------------------------------------------------

    def state(self) -> CalibrationState:
        """The touches, the fit of them (or why there is none) and the accepted calibration."""
        project = self._session.project()
        touches = self._current(project)
        fit, error = self._fitted(touches)
        return CalibrationState(touches, self._force_N, fit, error, project.cell.registration)

    def plan(self) -> TouchPlan:
        """The touches the example operator would make on this part (``plan_touches``): the
        features to touch, for the GUIs to show. Kept per cell."""
        pose = self._session.robot.pose()
        kept = self._plan
        if kept is not None and kept[0] == pose.epoch:
            return kept[1]
        cell = pose.cell
        with mesh_query.LOCK:
            plan = plan_touches(unregistered_cad(cell.workpiece), cell.tool.radius_m,
                                robot=cell.robot)  # fmt: skip
        self._plan = (pose.epoch, plan)
        return plan

    def fit(self) -> WobjFit:
        """The CAD registered to the touches.

        Raises:
            CalibrationError: too few touches, or touches that leave a direction free.
        """
        fit, error = self._fitted(self._current(self._session.project()))
        if fit is None:
            raise CalibrationError(error)
        return fit

    # --- touching ------------------------------------------------------------------------

    def touch(
        self,
        *,
        direction: np.ndarray | None = None,
        frame: str = "base",
        at_wobj_m: np.ndarray | None = None,
        force_N: float | None = None,
        max_travel_m: float | None = None,
        feature: str = "",
    ) -> Touch:
        """Touch the part: from where the robot stands along ``direction`` (of ``frame``:
        "base", "wobj" (the CAD's work object, as the scene shows it) or "tool"), or, with
        ``at_wobj_m`` (a point picked on the CAD, work-object frame), from the start the core
        plans for that
        face (off it along its normal; ``touch_at``). A guarded move at ``force_N`` (default
        the last one, 10 N at first) over ``max_travel_m`` at most (default 20 mm, or the
        planned travel), recorded, then back to where it started."""
        s, robot = self._session, self._session.robot
        force = self._force_N if force_N is None else float(force_N)
        limits.TOUCH_OFF_FORCE_N.check(force, "touch force [N]")
        project = s.project()
        if len(self._current(project)) >= MAX_TOUCHES:
            raise ConflictError(f"a calibration holds at most {MAX_TOUCHES} touches")
        pose = robot.pose()
        cell = pose.cell
        cad = cell.workpiece.cad()  # the mesh the person sees and picks on
        if at_wobj_m is not None:
            with mesh_query.LOCK:
                planned = touch_at(cad, np.asarray(at_wobj_m, dtype=float), cell.tool.radius_m)
            self._go_to_start(planned, cad)
            d, travel = planned.direction, planned.travel_m
            feature = feature or planned.feature
        else:
            if direction is None:
                raise InvalidInputError("give the touch's direction, or a point of the part")
            d = _in_base(np.asarray(direction, dtype=float), frame, pose, cad)
            travel = 0.02 if max_travel_m is None else float(max_travel_m)
        if max_travel_m is not None:
            travel = float(max_travel_m)
        contact, wrench = s.teach.touch_along(d, force, travel)
        u = d / np.linalg.norm(d)
        touch = Touch(
            tuple(contact.T_base_tcp[:3, 3]), tuple(u), max(-float(wrench[:3] @ u), 0.0),
            cell.tool.radius_m, feature,
        )  # fmt: skip
        self._set(project, (*self._current(project), touch), force)
        return touch

    def _go_to_start(self, planned: PlannedTouch, cad: Workpiece) -> None:
        from robomach_core.cell import TOOL_DOWN

        T = np.eye(4)
        T[:3, :3], T[:3, 3] = TOOL_DOWN, planned.start_m
        top = float(cad.mesh_in_base().bounds[1, 2])
        arrival = self._session.teach.move_to(T, safe_z_m=top + SAFE_ABOVE_M)
        if not arrival.reached:
            raise CalibrationError(
                f"the tool stopped short of where the touch of {planned.feature} starts "
                f"({arrival.describe()}); the part stands there: jog the tool clear of it and "
                "touch from there along the face's normal"
            )

    def undo(self) -> Touch:
        """Delete the last touch (returned)."""
        project = self._session.project()
        touches = self._current(project)
        if not touches:
            raise NotFoundError("no touch to undo")
        self._set(project, touches[:-1], self._force_N)
        return touches[-1]

    def delete(self, index: int) -> Touch:
        """Delete touch ``index`` (from 0); later ones move down by one."""
        project = self._session.project()
        touches = self._current(project)
        if not 0 <= index < len(touches):
            raise NotFoundError(f"no touch {index}; there are {len(touches)} (indexes from 0)")
        self._set(project, touches[:index] + touches[index + 1 :], self._force_N)
        return touches[index]

    def clear(self, *, force_N: float | None = None) -> None:
        """Start again: no touches (the accepted calibration stays), and the touch force."""
        force = self._force_N if force_N is None else float(force_N)
        limits.TOUCH_OFF_FORCE_N.check(force, "touch force [N]")
        self._set(self._session.project(), (), force)

    def start_auto(self, force_N: float | None = None) -> str:
        """Job: the example operator touches the features of ``plan()`` (four on the top face,
        three and two on two sides); the touches replace the ones made so far. Returns the job
        id; the robot is busy until it ends."""
        from .robot import ROBOT_JOB_KINDS

        s, robot = self._session, self._session.robot
        force = self._force_N if force_N is None else float(force_N)
        limits.TOUCH_OFF_FORCE_N.check(force, "touch force [N]")
        plan = self.plan()
        project, pose = s.idle_start()
        cell, estimator, start = pose.cell, pose.leadthrough.estimator, pose.state

        def work(ctx: JobContext) -> tuple[LeadThroughState, list[Touch]]:
            lt = LeadThrough(robot.tapped(ctx, cell), estimator=estimator)
            return scripted_touches(lt, start, plan, force_N=force, progress=ctx.progress)

        def done(result: tuple[LeadThroughState, list[Touch]]) -> None:
            state, touches = result
            robot.place(state, pose.epoch, "the calibration's touches", save=True)
            self._set(project, tuple(touches), force)

        return robot.submit(ROBOT_JOB_KINDS[3], work, done, pose.epoch)

    # --- the project's calibration -------------------------------------------------------

    def accept(self) -> CellSettings:
        """The fit becomes the project's work object (``project.with_registration``): the cell
        is rebuilt with the CAD where the touches found it, the robot staying where it is."""
        fit = self.fit()
        return self._change(lambda p: core.with_registration(p, fit.registration()))

    def remove(self) -> CellSettings:
        """Back to the placement: the accepted calibration is dropped (the touches stay)."""
        return self._change(lambda p: core.with_registration(p, None))

    def _change(self, change: Callable[[Project], Project]) -> CellSettings:
        s, robot = self._session, self._session.robot
        joints = robot.snapshot().joints_rad
        project = s.change_cell(change, joints=joints)
        with self._lock:
            self._plan = None
        s.notify("calibration")
        return project.cell

    # --- the store ------------------------------------------------------------------------

    def document(self) -> dict[str, Any]:
        """What the store keeps with the robot (``robot_json["calibration"]``)."""
        with self._lock:
            return {
                "part": self._key,
                "force_N": self._force_N,
                "touches": [asdict(t) for t in self._touches],
            }

    def restore(self, doc: Any, project: Project) -> None:
        """The stored touches (dropped when unreadable or of another part)."""
        touches: tuple[Touch, ...] = ()
        force = TOUCH_FORCE_N
        key = part_key(project.cell, project.mesh)
        if isinstance(doc, dict) and doc.get("part") == key:
            try:
                touches = tuple(Touch.from_value(t) for t in doc.get("touches") or ())[:MAX_TOUCHES]
                force = limits.TOUCH_OFF_FORCE_N.check(doc.get("force_N", force))
            except (RobomachError, TypeError, ValueError):
                touches, force = (), TOUCH_FORCE_N
        with self._lock:
            self._touches, self._key, self._force_N = touches, key, float(force)
            self._fit, self._plan = None, None

    # --- internals -----------------------------------------------------------------------

    def _current(self, project: Project) -> tuple[Touch, ...]:
        """The touches of the project's part (none after the part changed)."""
        key = part_key(project.cell, project.mesh)
        with self._lock:
            if self._key != key:
                self._touches, self._key, self._fit = (), key, None
            return self._touches

    def _set(self, project: Project, touches: tuple[Touch, ...], force_N: float) -> None:
        key = part_key(project.cell, project.mesh)
        doc = {"part": key, "force_N": force_N, "touches": [asdict(t) for t in touches]}

        def apply() -> None:
            with self._lock:
                self._touches, self._key, self._force_N = touches, key, float(force_N)

        self._session.robot.keep({"calibration": doc}, apply)  # saved first: a 503 keeps all
        self._session.notify("calibration")

    def _fitted(self, touches: tuple[Touch, ...]) -> tuple[WobjFit | None, str]:
        view = self._session.view()
        cad = unregistered_cad(view.cell.workpiece)
        stiffness = view.project.post_settings.contact_stiffness_N_m
        key = f"{view.epoch}:{stiffness}"
        with self._lock:
            kept = self._fit
        if kept is not None and kept[0] == touches and kept[1] == key:
            return kept[2], kept[3]
        if len(touches) < MIN_TOUCHES:
            fit, error = (
                None,
                (
                    f"{len(touches)} of at least {MIN_TOUCHES} touches: three on a top face, two "
                    "on a side, one on a side across it"
                ),
            )
        else:
            try:
                with mesh_query.LOCK:
                    fit, error = fit_wobj(cad, touches, contact_stiffness_N_m=stiffness), ""
            except CalibrationError as exc:
                fit, error = None, str(exc)
        with self._lock:
            self._fit = (touches, key, fit, error)
        return fit, error


def _in_base(direction: np.ndarray, frame: str, pose: Pose, cad: Workpiece) -> np.ndarray:
    """A direction given in ``frame`` ("base", "wobj", "tool") in the base frame."""
    direction = unit_vector(direction, "a touch direction")  # any length, 1e-200 to 1e300
    if frame == "base":
        return direction
    if frame == "wobj":
        return cad.T_base_wobj[:3, :3] @ direction
    if frame == "tool":
        return pose.state.cell.T_base_tcp[:3, :3] @ direction
    raise InvalidInputError(f"a touch frame is base, wobj or tool, not {frame!r}")
