"""The session's robot jobs and post-processing: the example lead-through, path learning, the
post-processing run, going home, and the checks of the guide points before a run.

PROBLEM   The jobs that move the robot and the stages that compute from the project lived in
          the Session and reached into its cell, lead-through state and lock.
STRATEGY  Each reads a ``Session.view()`` and the robot's ``pose()``, computes outside the lock
          (the core's ``project.learn`` and ``process``, the same the CLI runs), and lands its
          result with one core transition through ``Session.commit``, which refuses it when
          the cell changed meanwhile (the view's epoch).
SOLUTION  ``Learning(session)``, the session's ``learning``: ``start_example()``,
          ``start_path_learning(force_N, speed_m_s, closed=, wall_side=, floor_clearance_m=)``
          -> job id; ``run_postprocess(...)`` -> ``ProcessedPath``; ``go_home()``;
          ``force_trace(max_points)``; ``guide_findings``, ``guide_warnings``,
          ``taught_wall_preview``.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from robomach_core import project as core
from robomach_core.cell import (
    CONTROL_PERIOD_S,
    Cell,
    CellState,
    ComplianceSelection,
    GuidePoint,
    LeadThrough,
    LeadThroughState,
)
from robomach_core.errors import (
    ConflictError,
    InvalidInputError,
    NotEnoughGuidePointsError,
    RouteRefusedError,
    SupervisionError,
)
from robomach_core.learning.route import LearningRoute
from robomach_core.learning.settings import PathLearningSettings, WallSideSetting
from robomach_core.part import Workpiece, mesh_query
from robomach_core.project import ProcessedPath, Project

from .jobs import JobContext
from .records import ForceTrace, RobotSnapshot, Topic
from .robot import View, build_live_cell

if TYPE_CHECKING:
    from .session import Session

EXAMPLE_CLEARANCE_M = 0.008  # the example operator lifts the tool this far above the part
RELEASED_BELOW_N = 1.0  # a run's end is released until the contact force is below this ...
RELEASE_MAX_S = 1.0  # ... or for this long at most
DOWNSTREAM_TOPICS: tuple[Topic, ...] = ("recording", "postprocess")


def _example_intents(cell: Cell, seed: int) -> list | None:
    """The example operator's points: its own plan (None), or, on a part that is not where its
    mesh is, the same entered in each groove's middle (``operator.robust_intents``)."""
    if cell.workpiece.nominal is None:
        return None
    from robomach_core.teaching import guide_plan, robust_intents

    plan = guide_plan(cell.workpiece.cad(), cell.tool.radius_m, np.random.default_rng(seed))
    return robust_intents(plan, cell.workpiece, cell.tool.radius_m)


def _squared(lt: LeadThrough, state: LeadThroughState, cad: Workpiece) -> LeadThroughState:
    """The tool lifted clear of the part (when below its top) and turned square to it (tool
    axis down, as the example operator holds it), by supervised jogs of at most 45 degrees."""
    from robomach_core.cell import TOOL_DOWN
    from robomach_core.teaching import move_by, turn_to

    top = float(cad.mesh_in_base().bounds[1, 2]) + EXAMPLE_CLEARANCE_M
    z = float(state.cell.T_base_tcp[2, 3])
    if z < top:
        state = move_by(lt, state, np.array([0.0, 0.0, top - z]), 0.05)
    return turn_to(lt, state, TOOL_DOWN)


def released(lt: LeadThrough, end: CellState, above_N: float) -> CellState:
    """The robot where a run left it, backed off the part when it presses on it harder than
    ``above_N`` (the run's protection limit): admittance on x, y, z with no push, so that the
    wall's own reaction moves the tool out, until the contact force is below
    ``RELEASED_BELOW_N`` or ``RELEASE_MAX_S`` passed (supervised; a limit stops it there).

    A learned run on a part far off its mesh (the realistic part at the top of its ranges)
    ended with the robot pressed into the part at 220-310 N, and it stayed so (issue 32): a
    controller's protection takes the force off; the recording is unchanged."""
    if float(np.linalg.norm(lt.measured_wrench(end)[:3])) <= above_N:
        return end
    state = LeadThroughState(end, end.T_base_tcp.copy(), np.zeros(6))
    free = ComplianceSelection(frozenset({"x", "y", "z"}), "base")
    try:
        for _ in range(int(round(RELEASE_MAX_S / CONTROL_PERIOD_S))):
            state = lt.step(state, np.zeros(6), free)
            if float(np.linalg.norm(lt.measured_wrench(state.cell)[:3])) < RELEASED_BELOW_N:
                break
    except SupervisionError as exc:  # a limit on the way out: it stops there, held
        if isinstance(exc.state, LeadThroughState):  # lt.step's error carries its state
            state = exc.state
    return state.cell


def _same_inputs(a: tuple, b: tuple) -> bool:
    """Whether two ``Learning._checked_route`` inputs are the same: the guide points and the
    part the same objects (a project's values are never changed in place), the rest equal."""
    return a[0] is b[0] and a[1] is b[1] and a[2:] == b[2:]


class Learning:
    """The robot jobs and stages of one session (module docstring)."""

    def __init__(self, session: Session) -> None:
        self._session = session
        self._route_lock = threading.Lock()
        self._checked: tuple[tuple, LearningRoute | RouteRefusedError] | None = None

    def start_example(self) -> str:
        """Job: the scripted operator leads the robot by pushes to the example guide points of
        the built-in workpiece; on success they replace the guide points. Returns the job id."""
        from robomach_core.teaching import scripted_leadthrough

        s, robot = self._session, self._session.robot
        pose = robot.pose()
        robot.require_idle()
        cell, estimator = pose.cell, pose.leadthrough.estimator
        if cell.workpiece.wall is None:
            raise InvalidInputError(
                f"the example lead-through needs a built-in workpiece, not "
                f"{cell.workpiece.name!r}; click its wall to propose guide points, "
                "or lead the robot by pushes"
            )
        start, seed = pose.state, s.project().cell.seed

        def work(ctx: JobContext) -> tuple[LeadThroughState, list[GuidePoint]]:
            lt = LeadThrough(robot.tapped(ctx, cell), estimator=estimator)
            try:
                # Hand teaching may have left the tool turned and in the part: the operator
                # first lifts it clear and turns it square in steps (a jog turns 45 deg at
                # most), as a person would.
                state = _squared(lt, start, cell.workpiece.cad())
                return scripted_leadthrough(
                    lt,
                    state,
                    cell.workpiece.cad(),  # the operator plans on the mesh they see
                    np.random.default_rng(seed),
                    intents=_example_intents(cell, seed),
                    progress=ctx.progress,
                )
            except SupervisionError as exc:
                raise exc.with_cause_note(
                    cell.robot.name, place="the work object's placement"
                ) from None

        def done(result: tuple[LeadThroughState, list[GuidePoint]]) -> None:
            state, guides = result
            self.land_guides(state, guides, pose.epoch, "the example")

        return robot.submit("example", work, done, pose.epoch)

    def land_guides(
        self,
        state: LeadThroughState,
        guides: list[GuidePoint],
        epoch: int,
        what: str,
        *,
        with_project: Callable[[Project], None] | None = None,
    ) -> Project:
        """A job's guide points replace the project's, the robot where the job left it.
        ``with_project(new)`` runs inside the change, under the session's lock: what it marks
        is there before any reader sees the points."""

        def change(p: Project) -> Project:
            self._session.robot.place(state, epoch, what)
            new = core.with_guide_points(p, guides)
            if with_project is not None:
                with_project(new)
            return new

        return self._session.commit(
            change,
            "guides",
            topics=("robot", "guide_points", *DOWNSTREAM_TOPICS),
            with_robot=True,
        )

    def start_path_learning(
        self,
        force_N: float,
        speed_m_s: float,
        *,
        closed: bool = True,
        wall_side: WallSideSetting = "auto",
        floor_clearance_m: float | None = None,
    ) -> str:
        """Job: learn the path through the guide points at ``force_N`` and ``speed_m_s``
        (``project.learn``) along the wall on ``wall_side``; on success the recording replaces
        the last one (``project.with_learned``). "auto" takes the side of guide points taught
        by pointing at the wall (``pointing.learning_side``) when they are still those.
        Returns the job id.

        Raises:
            RouteRefusedError: the route cannot be learned as taught (before any job): the
                side on "auto" cannot be told, an open wall taught as a loop, ...
        """

        s, robot = self._session, self._session.robot
        settings = PathLearningSettings(
            force_N=float(force_N),
            speed_m_s=float(speed_m_s),
            closed=bool(closed),
            wall_side=self._side(wall_side),
            **({} if floor_clearance_m is None else {"floor_clearance_m": floor_clearance_m}),
        )
        project, pose = s.idle_start()
        if len(project.guide_points) < 2:
            raise NotEnoughGuidePointsError(
                f"path learning needs at least 2 guide points, got {len(project.guide_points)}"
            )
        cell, estimator = pose.cell, pose.leadthrough.estimator
        route = core.route_of(project, settings, cell.workpiece.cad())  # refuse now, not in a job

        def work(ctx: JobContext) -> tuple[core.LearnedPath, CellState]:
            path_m = np.array([g.position_m for g in project.guide_points])
            tapped = robot.tapped(ctx, cell, path_m=path_m, closed=settings.closed)
            learned, end = core.learn(
                project,
                tapped,
                pose.state.cell,
                settings,
                estimator,
                progress=ctx.progress,
                cancelled=ctx.cancelled,
                route=route,
            )
            lt = LeadThrough(tapped, estimator=estimator)
            return learned, released(lt, end, settings.force_limit_N)

        def done(result: tuple[core.LearnedPath, CellState]) -> None:
            learned, end = result
            state = LeadThroughState(end, end.T_base_tcp.copy(), np.zeros(6))

            def change(p: Project) -> Project:
                robot.place(state, pose.epoch, "path learning")
                return core.with_learned(p, learned)

            s.commit(
                change, "recording", "post", topics=("robot", *DOWNSTREAM_TOPICS), with_robot=True
            )

        return robot.submit("path_learning", work, done, pose.epoch)

    def run_postprocess(
        self,
        *,
        force_min_N: float | None = None,
        force_max_N: float | None = None,
        tolerance_m: float | None = None,
        arcs: bool | None = None,
        arc_tolerance_m: float | None = None,
    ) -> ProcessedPath:
        """Filter, reduce and score the last recording (``project.process``); None keeps a
        setting. It computes outside the lock from a view of the project, so reads never wait
        for it, and lands the result only if the recording and cell did not change."""
        s = self._session
        view = s.view()
        project = view.project
        settings = core.post_settings_with(
            project,
            force_min_N=force_min_N,
            force_max_N=force_max_N,
            tolerance_m=tolerance_m,
            arcs=arcs,
            arc_tolerance_m=arc_tolerance_m,
        )
        if project.learned is None:
            raise ConflictError("nothing to post-process yet: run path learning first")
        outcome = core.process(
            project.learned,
            settings,
            view.cell.workpiece,
            project.cell.tool_radius_m,
            guides=project.learned_guides(),
        )

        def change(p: Project) -> Project:
            if p.learned is not project.learned or s.robot.epoch != view.epoch:
                raise ConflictError(
                    "the recording or the cell changed while post-processing ran; run it again"
                )
            return core.with_processed(p, outcome)

        s.commit(change, "post", topics=("postprocess",))
        return outcome

    def go_home(self) -> RobotSnapshot:
        """Put the robot back at its home pose (a reset of the simulation, not a move)."""
        robot = self._session.robot

        def home(p: Project) -> Project:  # under the lock: the project's cell, the robot idle
            robot.install(build_live_cell(p.cell, p.mesh))
            robot.save()
            return p  # the project as it was: nothing of it is saved

        self._session.commit(home, topics=("robot",), idle=True)
        return robot.snapshot()

    def force_trace(self, max_points: int = 2000) -> ForceTrace:
        """Force vs time, at most ``max_points`` (>= 2) by stride: live during a job, else the
        last recording's."""
        return self._session.robot.force_trace(self._session.project().recording, max_points)

    # --- checks of the guide points before a run ---------------------------------------------

    def _side(self, wall_side: WallSideSetting) -> WallSideSetting:
        """The side a run, its checks and its wall preview all use: the setting, and on "auto"
        the side of guide points taught by pointing at the wall while they are still those
        (``pointing.learning_side``). The check used to decide "auto" afresh while the
        preview and the run took the proposal's side."""
        if wall_side != "auto":
            return wall_side
        return self._session.pointing.learning_side() or "auto"

    def guide_findings(
        self,
        force_N: float = PathLearningSettings.force_N,
        *,
        closed: bool = True,
        wall_side: WallSideSetting = "auto",
    ) -> tuple:
        """What the operator check finds in the guide points (``project.guide_findings``)."""
        view = self._session.view()
        side = self._side(wall_side)
        settings = PathLearningSettings(force_N=force_N, closed=closed, wall_side=side)
        route = None
        if len(view.project.guide_points) >= 2:  # fewer: no route, as the check has it
            route = self._checked_route(view, settings)
        return core.guide_findings(view.project, view.cell, settings, route=route)

    def _checked_route(
        self, view: View, settings: PathLearningSettings
    ) -> LearningRoute | RouteRefusedError:
        """``core.route_of`` for the checks and the wall preview, or its refusal, planned once
        for the same guide points, part and route settings: the workbench's rules panel and
        wall preview, and GET /api/path-learning/check, each planned it after every change
        (0.4-0.6 s each for 14 points), and a refused route up to three times for one check.
        They only read it; a run plans its own (its height reference changes as the run
        goes)."""
        cad = view.cell.workpiece.cad()
        inputs = (view.project.guide_points, cad, view.project.cell.tool_radius_m,
                  settings.closed, settings.wall_side, settings.floor_clearance_m)  # fmt: skip
        with self._route_lock:
            checked = self._checked
        if checked is not None and _same_inputs(checked[0], inputs):
            return checked[1]
        route: LearningRoute | RouteRefusedError
        try:
            route = core.route_of(view.project, settings, cad)
        except RouteRefusedError as exc:
            route = exc.with_traceback(None)  # kept without the planner's frames (the part)
        with self._route_lock:
            self._checked = (inputs, route)
        return route

    def guide_warnings(
        self, force_N: float, *, closed: bool = True, wall_side: WallSideSetting = "auto"
    ) -> list[str]:
        """The operator check's findings (``guide_findings``) as messages."""
        found = self.guide_findings(force_N, closed=closed, wall_side=wall_side)
        return [w.message for w in found]

    def taught_wall_preview(
        self, wall_side: WallSideSetting = "auto", *, closed: bool = True
    ) -> tuple[list, str]:
        """The wall the next run would follow: its point at each guide point (base frame, None
        where none is near) and one line saying which side and why, or why it cannot tell."""
        from robomach_core.learning.part_walls import PartWalls
        from robomach_core.learning.route import taught_wall_points

        view = self._session.view()
        workpiece = view.cell.workpiece.cad()
        guides, radius = view.project.guide_points, view.project.cell.tool_radius_m
        if len(guides) < 2:
            return [], ""
        settings = PathLearningSettings(closed=closed, wall_side=self._side(wall_side))
        route = self._checked_route(view, settings)
        if isinstance(route, RouteRefusedError):
            return [], f"wall side: {route}"
        with mesh_query.LOCK:
            walls = PartWalls(workpiece, route.axis, radius)
            points = taught_wall_points(
                guides, route.wall_side.side, closed, walls, travel=route.guide_travel
            )
        decision = route.wall_side
        return points, f"follows the wall on the {decision.side}: {decision.detail}"
