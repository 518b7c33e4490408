"""The viser workbench: the cell's 3D scene and one panel per pipeline stage, over a Session.

PROBLEM   The robot must move on screen at 30 Hz or more while it is pushed (by the spring
          handle, the push buttons, the REST API or a job), and the panels must follow changes
          made through the REST API, without the GUI thread pool blocking on long work.
STRATEGY  One updater thread ticks at ``RATE_HZ``: it lets the spring handle push for the real
          time elapsed, reads the session's snapshot, and redraws the robot when the simulated
          time moved. Session change notifications only mark topics dirty; the same thread
          refreshes the panels for them, so the session's threads never wait on the GUI.
SOLUTION  ``Workbench(server, session)``; ``close()`` stops the thread and unsubscribes.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Protocol

import numpy as np
import viser

from app.session import JobInfo, Session
from robomach_core.errors import RobomachError

from .icons import icons_from_one_zip
from .panels import (
    CellPanel,
    ExportPanel,
    GuidePointsPanel,
    LeadThroughPanel,
    PathLearningPanel,
    PostprocessPanel,
)
from .panels.calibration import CalibrationPanel
from .panels.feedback import notify_error
from .panels.placement import PlacementPanel
from .panels.pointing import PointingPanel
from .panels.robot_wiring import GuideRulesPanel, RobotProgramPanel
from .panels.teach_panel import TeachPanel
from .scene import CellScene

log = logging.getLogger(__name__)

RATE_HZ = 60.0
JOB_DRAW_PERIOD_S = 0.03  # while a job runs, ~30 redraws a second leave it the CPU
POSE_TEXT_PERIOD_S = 0.1  # the pose readout is text: 10 Hz is plenty to read
PLOT_PERIOD_S = 0.25  # live force plot while a job runs
BRAND_COLOR = (29, 53, 87)
JOB_TITLES = {
    "example": "Load the example",
    "path_learning": "Path learning",
    "accept_proposal": "Accepting the proposal",
    "calibration": "Touching the planned features",
}


class JobPanel(Protocol):
    """A panel that shows a robot job's progress (None: no job of its kind)."""

    def show_job(self, job: JobInfo | None) -> None: ...


class Workbench:
    """Builds the scene and the panels on ``server`` and keeps them in step with ``session``.

    Args:
        server: The viser server.
        session: The ``app.session.Session`` shared with the REST API.
        rate_hz: Updater rate (the robot is redrawn at most this often, only when it moved).
    """

    def __init__(
        self,
        server: viser.ViserServer,
        session: Session,
        *,
        rate_hz: float = RATE_HZ,
    ) -> None:
        self.server = server
        self.session = session
        self.study_service = session.studies  # the session's, shared with the API
        self.machining_service = session.machining
        self.period_s = 1.0 / rate_hz
        server.gui.configure_theme(
            control_width="large",
            brand_color=BRAND_COLOR,
            show_share_button=False,
        )
        server.gui.main_panel.dock_right()
        server.initial_camera.position = (1.16, -0.26, 0.46)
        server.initial_camera.look_at = (0.78, 0.15, 0.05)
        server.initial_camera.up = (0.0, 0.0, 1.0)
        with icons_from_one_zip():  # viser reads its icons' zip once, not per icon
            self.scene = CellScene(server)
            self._show_cell()
            self.cell = CellPanel(server, session)
            self.placement = PlacementPanel(server, session)
            self.calibration = CalibrationPanel(server, session, self.scene)
            self.leadthrough = LeadThroughPanel(server, session, self.scene)
            self.teach = TeachPanel(server, session)
            self.guide_points = GuidePointsPanel(server, session, self.scene)
            self.pointing = PointingPanel(server, session, self.scene, self.guide_points)
            self.pointing.on_touch = self.calibration.touch_face
            self.path_learning = PathLearningPanel(server, session, self.scene)
            self.postprocess = PostprocessPanel(server, session, self.scene)
            self.export = ExportPanel(server, session, self.study_service)
            self.robot_program = RobotProgramPanel(server, session)
            self.guide_rules = GuideRulesPanel(server, session, self.path_learning.route_settings)
            self.guide_rules.listeners.append(self.path_learning.show_check)
            self.path_learning.show_check(self.guide_rules.warnings.content)
            self.path_learning.on_route_change(lambda: self._on_change("guide_points"))
            self.studies = self._study_panels(server, session)
            self.studies += self._machining_panel(server, session)
        self._framed = self._part_key()  # the cell the cameras were last framed on
        self._dirty: set[str] = {"job"}
        self._dirty_lock = threading.Lock()
        self._jobs_shown: dict[str, str] = {}  # job kind -> id of the job the panel shows
        self._last_time_s = float("nan")
        self._last_push: np.ndarray | None = None
        self._next_text = 0.0
        self._text_behind = False  # the pose readout is older than the drawn robot
        self._next_draw = 0.0
        self._next_plot = 0.0
        self.frames_drawn = 0  # robot redraws (benchmarks read it)
        self._stop = threading.Event()
        server.on_client_connect(self._show_notice)  # a project opened before the page was
        self._unsubscribe = session.subscribe(self._on_change)
        self._thread = threading.Thread(target=self._run, name="robomach-scene", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop the updater thread and the study panels, and stop listening to the session."""
        self._stop.set()
        self._unsubscribe()
        self._thread.join(timeout=2.0)
        for panel in self.studies:
            panel.close()

    def _study_panels(self, server: viser.ViserServer, session: Session) -> list:
        """The CMRR and compensation study panels (collapsed, below the pipeline's)."""
        try:
            from .panels.cmrr import CmrrPanel
            from .panels.compensation import CompensationPanel

            service = self.study_service
            return [
                CmrrPanel(server, session, service),
                CompensationPanel(server, session, service),
            ]
        except Exception:  # the PbD pipeline's panels stay usable without the studies
            log.exception("the study panels failed to build")
            return []

    def _machining_panel(self, server: viser.ViserServer, session: Session) -> list:
        """The Machining panel (issue 8), closed with the study panels."""
        try:
            from .panels.machining import MachiningPanel

            return [MachiningPanel(server, session, self.machining_service)]
        except Exception:
            log.exception("the machining panel failed to build")
            return []

    # ---------------------------------------------------------------- change notifications

    def _on_change(self, topic: str) -> None:
        with self._dirty_lock:
            self._dirty.add(topic)

    def _take_dirty(self) -> set[str]:
        with self._dirty_lock:
            topics, self._dirty = self._dirty, set()
        if "project" in topics:
            topics |= {"cell", "compliance", "guide_points", "recording", "postprocess", "job"}
        return topics

    # ---------------------------------------------------------------- the updater thread

    def _run(self) -> None:
        next_tick = time.monotonic()
        while not self._stop.is_set():
            try:
                self._tick()
            except RobomachError as exc:  # e.g. the spring pushed out of reach
                for client in self.server.get_clients().values():
                    notify_error(client, "Lead-through", str(exc))
            except Exception:
                log.exception("workbench update failed")
            next_tick = max(next_tick + self.period_s, time.monotonic())
            self._stop.wait(max(0.0, next_tick - time.monotonic()))

    def _show_notice(self, client: viser.ClientHandle) -> None:
        """What the user must know about the open project (its stored arm was refused), as a
        notification that stays until closed; nothing when there is nothing."""
        try:
            notice = self.session.current_project().notice
        except RobomachError:
            return
        if notice:
            client.add_notification("Project", notice, color="yellow", auto_close_seconds=None)

    def _tick(self) -> None:
        topics = self._take_dirty()
        if "project" in topics:
            for client in self.server.get_clients().values():
                self._show_notice(client)
        if "cell" in topics:
            self._show_cell()
            self.cell.refresh()
            framed = self._part_key()
            if framed != self._framed:  # not a calibration: the person's view stays
                self._frame_part()
                self._framed = framed  # now: ``part_framed`` says the cameras were sent
            note = self.session.cell_note()
            for client in self.server.get_clients().values() if note else ():
                client.add_notification(
                    "Machining choice cleared", note, color="yellow", auto_close_seconds=None
                )
        if topics & {"cell", "placement"}:
            self.scene.preview_placement(self.session.preview.transform())
            self.placement.refresh()
        if topics & {"cell", "calibration"}:
            self.calibration.refresh()
        if "compliance" in topics:
            self.leadthrough.refresh_compliance()
        if "guide_points" in topics or "cell" in topics:
            self.guide_points.refresh()
            self.guide_rules.refresh()
            self.pointing.refresh()
            self.path_learning.refresh_wall()
        if topics & {"job", "recording"}:
            self._show_jobs()
        if topics & {"recording", "postprocess", "cell"}:
            self.postprocess.refresh()
            self.export.refresh()
            self.robot_program.refresh()
            self.pointing.show_comparison()
            self._hide_old_cell_paths(topics)
        if topics & {"recording", "postprocess", "cell", "project"}:
            self.path_learning.refresh_stop(old_cell=self.scene.paths.hidden)
        snapshot = self.leadthrough.tick(self.session.robot.snapshot())
        self.teach.tick(snapshot)
        self._draw_robot(snapshot)
        now = time.monotonic()
        if snapshot.busy and now >= self._next_plot:
            self._next_plot = now + PLOT_PERIOD_S
            self.path_learning.refresh_plot()
        elif "recording" in topics:
            self.path_learning.refresh_plot()

    def _draw_robot(self, snapshot) -> None:
        push = self.leadthrough.push_N
        moved = snapshot.time_s != self._last_time_s
        pushed = not _same(push, self._last_push)
        now = time.monotonic()
        if self._text_behind and not (moved or pushed) and now >= self._next_text:
            self._show_pose(snapshot, now)  # the last move's readout was skipped: catch up
        if not (moved or pushed) or (snapshot.busy and now < self._next_draw):
            return
        self._next_draw = now + JOB_DRAW_PERIOD_S
        self._last_time_s, self._last_push = snapshot.time_s, None if push is None else push.copy()
        self.scene.update_robot(snapshot.joints_rad, snapshot.T_base_tcp, snapshot.wrench[:3], push)
        self.frames_drawn += 1
        self._text_behind = now < self._next_text
        if not self._text_behind:
            self._show_pose(snapshot, now)

    def _show_pose(self, snapshot, now: float) -> None:
        """The pose readout, at most every ``POSE_TEXT_PERIOD_S`` (10 Hz is plenty to read)."""
        self._text_behind = False
        self._next_text = now + POSE_TEXT_PERIOD_S
        self.leadthrough.show_pose(snapshot)

    def _show_cell(self) -> None:
        cell = self.session.robot.cell
        self.scene.set_robot(cell.robot.name)
        self.scene.set_tool(cell.tool)
        self.scene.set_workpiece(cell.workpiece)  # drawn as its mesh (``Workpiece.cad``)
        self._last_time_s = float("nan")  # redraw the new robot at once

    def _part_key(self) -> tuple:
        """What the camera frames: the arm, the part and its placement (a calibration moves
        the CAD by millimetres onto the real part: the view the person chose stays)."""
        project = self.session.project()
        cell, mesh = project.cell, project.mesh
        mesh_key = None if mesh is None else (mesh[0], len(mesh[1]))
        return (cell.robot, cell.workpiece, cell.wobj_mm_deg, mesh_key)

    @property
    def part_framed(self) -> bool:
        """The browsers' cameras were sent to the cell's part (after a cell change the tick
        frames it; until then a camera the person moves is moved again)."""
        return self._framed == self._part_key()

    def _frame_part(self) -> None:
        """Every browser's camera on the new part (a cell change: another part, place or
        robot), from beyond it so that the arm is never in the way."""
        clients = list(self.server.get_clients().values())
        if not clients:
            return
        workpiece, pose = self.session.robot.workpiece, self.session.robot.snapshot()
        for client in clients:
            self.scene.part_view(client, workpiece, pose.joints_rad, pose.T_base_tcp)

    def _hide_old_cell_paths(self, topics: set[str]) -> None:
        """A cell change leaves the old cell's recording in the project (stale), but its paths
        are not drawn through the new part: they stay hidden until the next learning."""
        learned = self.session.project().learned
        if "cell" in topics and "project" not in topics:
            self._old_cell_learned = learned
        if learned is not None and learned is getattr(self, "_old_cell_learned", None):
            self.scene.paths.hide()

    def _show_jobs(self) -> None:
        """Progress of the robot jobs, whoever started them; a job that failed says why in
        every browser, until it is closed."""
        kinds = ("example", "path_learning", "accept_proposal", "calibration")
        active = {j.kind: j for j in self.session.jobs.active(kinds)}
        panels: dict[str, JobPanel] = {
            "example": self.guide_points,
            "path_learning": self.path_learning,
            "accept_proposal": self.pointing,
            "calibration": self.calibration,
        }
        for kind, panel in panels.items():
            job = active.get(kind)
            if job is not None:
                self._jobs_shown[kind] = job.id
                panel.show_job(job)
            elif kind in self._jobs_shown:
                finished = self.session.jobs.get(self._jobs_shown.pop(kind))
                panel.show_job(finished if kind == "path_learning" else None)
                if finished.status == "failed":
                    title = JOB_TITLES.get(kind, kind)
                    for client in self.server.get_clients().values():
                        notify_error(client, f"{title} failed", finished.error or "no reason given")
            else:
                panel.show_job(None)


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return bool(np.array_equal(a, b))
