"""Teaching by pointing at the part: click-to-teach, and guide points proposed for a wall.

PROBLEM   The workbench knows the part's mesh, so the user can point at the wall instead of
          jogging to it: one click should put the tool beside the wall and record the point,
          another propose the guide points for the whole wall, shown before anything moves, to
          accept, edit or delete. Both GUIs and the REST API do it, on the same session.
STRATEGY  The core computes (``teaching.pointing.teach_point`` / ``propose_guide_points`` on the
          part's CAD, ``Workpiece.cad()``); the robot moves by ``Teach.move_to`` (paced and
          supervised like a jog, stopped by the real part when it is not where its mesh is);
          accepting a proposal is a job in which the scripted operator leads the robot by
          pushes to each point and touches the wall there (``operator.guide_intents``),
          as "Load the example" does. The pending proposal belongs to the cell it was made
          in (its epoch): a cell change drops it. The wall side of points taught this way is
          known, and path learning uses it unless told otherwise.
SOLUTION  ``Pointing(session)``, the session's ``pointing``: ``pick``, ``teach_at_surface``,
          ``propose``, ``proposal``, ``move_proposed``, ``delete_proposed``, ``discard``,
          ``accept``, ``learning_side``; the settings (gap, height above the floor) in ``settings``.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from robomach_core import project as core
from robomach_core.cell import GuidePoint, LeadThrough, LeadThroughState
from robomach_core.choices import CLICK_MODES, ClickMode
from robomach_core.errors import InvalidInputError, SupervisionError, UnreachableTargetError
from robomach_core.learning.route import WallSide
from robomach_core.learning.walls import WallPick
from robomach_core.part import Workpiece, mesh_query
from robomach_core.teaching import Arrival, guide_intents, robust_intents
from robomach_core.teaching.pointing import (
    GuideProposal,
    ProposalSettings,
    ProposedPoint,
    delete_point,
    move_point,
    propose_guide_points,
    teach_point,
    tool_reach,
)

from .jobs import JobContext
from .records import MAX_GUIDE_POINTS, ConflictError, GuidePointEntry, NotFoundError
from .robot import ROBOT_JOB_KINDS

if TYPE_CHECKING:
    from .session import Session

SAFE_HEIGHT_M = 0.008  # the tool travels this far above the part's top
# Fewest proposed points that make a path: path learning needs two; a closed wall, learned
# round and back to its first point, three (one point "closed" on itself was offered and
# accepted, issue 32).
MIN_PROPOSED_POINTS = {False: 2, True: 3}


def _require_enough(proposal: GuideProposal, what: str) -> None:
    """``InvalidInputError`` when the proposal has too few points to learn from."""
    need = MIN_PROPOSED_POINTS[bool(proposal.closed)]
    have = len(proposal.points)
    if have < need:
        kind = "a closed wall" if proposal.closed else "an open wall"
        raise InvalidInputError(
            f"{what}: {have} guide point{'s' if have != 1 else ''} for {kind}, which needs at "
            f"least {need}; pick a longer wall, or teach points one by one"
        )


def pointing_document(settings: ProposalSettings, click_mode: ClickMode) -> dict[str, object]:
    """The pointing settings as stored (mm, and what a click does)."""
    return {
        "gap_mm": settings.gap_m * 1e3,
        "height_above_floor_mm": settings.height_above_floor_m * 1e3,
        "click_mode": click_mode,
    }


def pointing_from_document(doc: dict | None) -> tuple[ProposalSettings, ClickMode]:
    """The stored pointing settings; the defaults for what is missing or out of range."""
    doc = doc if isinstance(doc, dict) else {}
    try:
        settings = ProposalSettings(
            gap_m=float(doc.get("gap_mm", ProposalSettings.gap_m * 1e3)) * 1e-3,
            height_above_floor_m=float(
                doc.get("height_above_floor_mm", ProposalSettings.height_above_floor_m * 1e3)
            )
            * 1e-3,
        )
    except (TypeError, ValueError):
        settings = ProposalSettings()
    mode = doc.get("click_mode")
    return settings, mode if mode in CLICK_MODES else "propose"


@dataclass(frozen=True)
class TaughtPoint:
    """A guide point taught by pointing at the wall.

    Attributes:
        entry: The recorded guide point and its index.
        planned: Where the tool was sent (beside the wall, at the machining height).
        pick: The picked wall.
        arrival: Where the motion ended (against the part if it is not where its mesh is).
        notice: What the user should know ("" when the tool is there, free).
    """

    entry: GuidePointEntry
    planned: ProposedPoint
    pick: WallPick
    arrival: Arrival
    notice: str


class Pointing:
    """Click-to-teach and proposals of one session (module docstring)."""

    def __init__(self, session: Session) -> None:
        self._session = session
        self._lock = threading.Lock()
        self._proposal: tuple[int, GuideProposal] | None = None
        self._pointed: tuple[str, WallSide] | None = None  # (guides_key, side) of a proposal
        self.settings = ProposalSettings()
        self.click_mode: ClickMode = "propose"  # what a click on the part does (both GUIs)

    # --- settings ------------------------------------------------------------------------

    def set_settings(
        self,
        *,
        gap_m: float | None = None,
        height_above_floor_m: float | None = None,
        click_mode: ClickMode | None = None,
    ) -> ProposalSettings:
        """Change the gap to the wall, the height above the floor or what a click on the part
        does (None keeps one); both GUIs follow."""
        if click_mode is not None and click_mode not in CLICK_MODES:
            raise InvalidInputError(
                f"click mode must be one of {', '.join(CLICK_MODES)}, not {click_mode!r}"
            )
        new = replace(
            self.settings,
            **{k: float(v) for k, v in (("gap_m", gap_m),
                                        ("height_above_floor_m", height_above_floor_m))
               if v is not None},
        )  # fmt: skip
        mode = self.click_mode if click_mode is None else click_mode
        if new == self.settings and mode == self.click_mode:
            return self.settings

        def apply() -> None:
            self.settings, self.click_mode = new, mode

        # Kept with the project's robot document, saved before it applies.
        self._session.robot.keep({"pointing": pointing_document(new, mode)}, apply)
        self._session.notify("guide_points")
        return self.settings

    def document(self) -> dict[str, object]:
        """The settings as the store keeps them (``robot_json["pointing"]``)."""
        return pointing_document(self.settings, self.click_mode)

    # --- click to teach ------------------------------------------------------------------

    def pick(self, point_wobj_m: np.ndarray, normal: np.ndarray | None = None) -> WallPick:
        """The wall a click at ``point_wobj_m`` (work-object frame) picks, at the machining
        height, as teaching and proposing pick it (nothing moves): what the GUIs highlight
        before they act. Raises ``InvalidInputError`` with the reason when nothing is picked
        (a floor, the middle of a narrow groove)."""
        from robomach_core.learning.walls import pick_wall

        cell = self._session.robot.cell
        with mesh_query.LOCK:
            return pick_wall(
                cell.workpiece.cad().mesh,
                np.asarray(point_wobj_m, dtype=float),
                None if normal is None else np.asarray(normal, dtype=float),
                tool_radius_m=cell.tool.radius_m,
                gap_m=self.settings.gap_m,
                height_above_floor_m=self.settings.height_above_floor_m,
                tool_reach_m=tool_reach(cell.tool),
            )

    def teach_at_surface(
        self,
        point_wobj_m: np.ndarray,
        normal: np.ndarray | None = None,
        *,
        replace_index: int | None = None,
    ) -> TaughtPoint:
        """Put the tool beside the wall at a picked point (work-object frame) and record a
        guide point there: appended, or in place of ``replace_index`` (drag to adjust)."""
        s, robot = self._session, self._session.robot
        project, pose = s.idle_start()
        count = len(project.guide_points)
        if replace_index is not None and not 0 <= replace_index < count:
            raise NotFoundError(f"no guide point G{replace_index + 1}; there are {count}")
        if replace_index is None and count >= MAX_GUIDE_POINTS:
            raise ConflictError(f"a project holds at most {MAX_GUIDE_POINTS} guide points")
        cell, lt_state, supervisor = pose.cell, pose.state, pose.leadthrough.supervisor
        cad = cell.workpiece.cad()
        with mesh_query.LOCK:  # the mesh's trees answer one thread at a time
            planned, pick = teach_point(
                cad,
                cell.robot,
                np.asarray(point_wobj_m, dtype=float),
                None if normal is None else np.asarray(normal, dtype=float),
                tool_radius_m=cell.tool.radius_m,
                settings=self.settings,
                q_seed=lt_state.cell.q_motor,
                supervisor=supervisor,
                tool_reach_m=tool_reach(cell.tool),
            )
        if planned.reach == "unreachable":
            x, y, z = planned.position_wobj_m * 1e3
            raise UnreachableTargetError(
                f"the arm cannot stand beside the wall at ({x:.1f}, {y:.1f}, {z:.1f}) mm (work "
                f"object): {planned.message}"
            )
        entry = None
        if cell.workpiece.nominal is not None:  # the real part may be off: enter mid-groove
            from robomach_core.teaching import GuideIntent

            n = pick.loop.free_normal_at(np.array([pick.s_m]))[0]
            towards = -(cad.T_base_wobj[:3, :3] @ np.array([n[0], n[1], 0.0]))
            (robust,) = robust_intents(
                [GuideIntent(planned.T_base_tcp[:3, 3].copy(), towards)],
                cell.workpiece,
                cell.tool.radius_m,
            )
            entry = robust.position_m
        arrival = s.teach.move_to(planned.T_base_tcp, safe_z_m=self._safe_z(cad), entry_m=entry)
        point = robot.record()

        def change(p: core.Project) -> core.Project:
            if replace_index is None:
                return core.with_guide_point_added(p, point)
            return core.with_guide_point_at(p, replace_index, point)

        project = s.commit(change, "guides", topics=("guide_points", "recording", "postprocess"))
        index = len(project.guide_points) - 1 if replace_index is None else replace_index
        notice = arrival.describe()
        if planned.message:
            notice = f"{notice}; {planned.message}" if notice else planned.message
        return TaughtPoint(GuidePointEntry(index, point), planned, pick, arrival, notice)

    def teach_near(
        self, tcp_wobj_m: np.ndarray, *, replace_index: int | None = None
    ) -> TaughtPoint:
        """Teach at the wall nearest a TCP position (work-object frame) at its height above
        the floor: where a dragged marker was dropped."""
        from robomach_core.learning.walls import walls_near

        cad = self._session.robot.workpiece.cad()
        p = np.asarray(tcp_wobj_m, dtype=float).reshape(3)
        with mesh_query.LOCK:
            T, (pf,), loops = walls_near(cad.mesh, p)
        if not loops:
            raise InvalidInputError(
                f"no wall at {p[2] * 1e3:.1f} mm (work object): drop the point beside a wall"
            )
        loop = min(loops, key=lambda lp: abs(lp.signed_distance(pf[None, :2])[0]))
        s = float(loop.project(pf[None, :2])[0])
        foot = loop.point_at(np.array([s]))[0]
        n = loop.free_normal_at(np.array([s]))[0]
        R = T[:3, :3]
        return self.teach_at_surface(
            R @ np.array([foot[0], foot[1], pf[2]]),
            R @ np.array([n[0], n[1], 0.0]),
            replace_index=replace_index,
        )

    @staticmethod
    def _safe_z(cad: Workpiece) -> float:
        """Base-frame height the tool travels at: above the part's highest point."""
        top = cad.mesh_in_base().bounds[1, 2]
        return float(top) + SAFE_HEIGHT_M

    # --- proposals -----------------------------------------------------------------------

    def propose(self, point_wobj_m: np.ndarray, normal: np.ndarray | None = None) -> GuideProposal:
        """Propose the guide points for the wall through a picked point (nothing moves); it
        replaces any pending proposal."""
        s = self._session
        pose = s.robot.pose()
        cell, epoch, q = pose.cell, pose.epoch, pose.state.cell.q_motor
        supervisor = pose.leadthrough.supervisor
        with mesh_query.LOCK:
            proposal = propose_guide_points(
                cell.workpiece.cad(),
                cell.robot,
                np.asarray(point_wobj_m, dtype=float),
                None if normal is None else np.asarray(normal, dtype=float),
                tool_radius_m=cell.tool.radius_m,
                settings=self.settings,
                q_seed=q,
                supervisor=supervisor,
                tool_reach_m=tool_reach(cell.tool),
            )
        _require_enough(proposal, "this wall gives too few points to learn")
        with self._lock:
            if epoch != s.robot.epoch:
                raise ConflictError("the cell changed while the guide points were proposed")
            self._proposal = (epoch, proposal)
        s.notify("guide_points")
        return proposal

    def proposal(self) -> GuideProposal | None:
        """The pending proposal of this cell, or None."""
        with self._lock:
            if self._proposal is None or self._proposal[0] != self._session.robot.epoch:
                return None
            return self._proposal[1]

    def _require(self) -> tuple[int, GuideProposal]:
        with self._lock:
            pending = self._proposal
        if pending is None or pending[0] != self._session.robot.epoch:
            raise NotFoundError("no proposed guide points: click a wall to propose them first")
        return pending

    def _replace(self, epoch: int, proposal: GuideProposal) -> GuideProposal:
        with self._lock:
            if self._proposal is None or self._proposal[0] != epoch:
                raise ConflictError("the proposal changed meanwhile; look at it again")
            self._proposal = (epoch, proposal)
        self._session.notify("guide_points")
        return proposal

    def move_proposed(self, index: int, point_wobj_m: np.ndarray) -> GuideProposal:
        """Drag proposed point ``index`` along the wall to where ``point_wobj_m`` projects."""
        epoch, proposal = self._require()
        pose = self._session.robot.pose()
        cell = pose.cell
        moved = move_point(
            proposal,
            index,
            np.asarray(point_wobj_m, dtype=float),
            cell.robot,
            tool_radius_m=cell.tool.radius_m,
            gap_m=self.settings.gap_m,
            supervisor=pose.leadthrough.supervisor,
        )
        return self._replace(epoch, moved)

    def delete_proposed(self, index: int) -> GuideProposal:
        """Delete proposed point ``index``."""
        epoch, proposal = self._require()
        radius = self._session.robot.cell.tool.radius_m
        return self._replace(epoch, delete_point(proposal, index, tool_radius_m=radius))

    def discard(self) -> None:
        """Drop the pending proposal."""
        with self._lock:
            self._proposal = None
        self._session.notify("guide_points")

    def accept(self) -> str:
        """Job: the operator leads the robot by pushes to each proposed point, touches the
        wall there (not at outside corners) and records it; the points replace the guide
        points, and path learning then follows the proposal's wall side. Returns the job id."""
        from robomach_core.teaching import scripted_leadthrough

        epoch, proposal = self._require()
        _require_enough(proposal, "the proposal cannot be accepted")
        bad = [k + 1 for k, p in enumerate(proposal.points) if p.reach == "unreachable"]
        if bad:
            listed = ", ".join(f"G{k}" for k in bad[:6])
            raise InvalidInputError(
                f"the arm cannot reach {listed}: move or delete them before accepting"
            )
        s, robot = self._session, self._session.robot
        project, pose = s.idle_start()
        rng_seed = project.cell.seed
        if epoch != pose.epoch:
            raise ConflictError("the cell changed since the proposal; propose again")
        cell, estimator, start = pose.cell, pose.leadthrough.estimator, pose.state
        intents = guide_intents(proposal)
        if cell.workpiece.nominal is not None:  # the real part is not where its mesh is
            intents = robust_intents(intents, cell.workpiece, cell.tool.radius_m)

        def work(ctx: JobContext) -> tuple[LeadThroughState, list[GuidePoint]]:
            lt = LeadThrough(robot.tapped(ctx, cell), estimator=estimator)
            try:
                return scripted_leadthrough(
                    lt,
                    start,
                    cell.workpiece.cad(),
                    np.random.default_rng(rng_seed),
                    intents=intents,
                    progress=ctx.progress,
                )
            except SupervisionError as exc:
                raise exc.with_note("move or delete that point and accept again") from None

        def done(result: tuple[LeadThroughState, list[GuidePoint]]) -> None:
            state, guides = result

            def mark(project: core.Project) -> None:  # as a single point's, under the lock
                self._pointed = (project.guides_key, proposal.wall_side)

            s.learning.land_guides(
                state, guides, epoch, "the proposal's acceptance", with_project=mark
            )
            with self._lock:
                self._proposal = None

        return robot.submit(ROBOT_JOB_KINDS[2], work, done, epoch)

    # --- what path learning needs ----------------------------------------------------------

    def learning_side(self) -> WallSide | None:
        """The wall side of an accepted proposal's points ("right": the planner's wall runs
        with the material on its right), while the guide points are still those; None
        otherwise (path learning decides it, from the pushes or the part's mesh:
        ``route.resolve_wall_side``)."""
        pointed = self._pointed
        if pointed is None or pointed[0] != self._session.project().guides_key:
            return None
        return pointed[1]
