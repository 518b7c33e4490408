"""Teach by pointing panel: a click on the part's wall teaches a point or proposes the wall's
guide points; the proposal is drawn before anything moves (reachability colours), edited,
accepted or discarded; a selected point is dragged along the wall; the CAD-only program is
drawn beside the learned one; top view and part view.

The click's ray meets the part's mesh in the scene (``CellScene.hit_part``), which gives the
point and normal in the work-object frame; the session's ``pointing`` does the rest.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import viser

from app.session import JobInfo, Session
from robomach_core.choices import CLICK_MODES, LABELS
from robomach_core.errors import InvalidInputError
from robomach_core.learning.walls import WallPick
from robomach_core.limits import MACHINING_HEIGHT_MM, WALL_GAP_MM

from ..colors import COMPARISON_COLORS
from ..scene import CellScene
from .feedback import guarded, notify_error, notify_info
from .inputs import set_value

# What a click on the part does, in the words every page uses (``choices.LABELS``).
MODE_OF = {mode: LABELS["click_mode"][mode] for mode in CLICK_MODES}
MODE_TEACH, MODE_PROPOSE, MODE_MOVE = MODE_OF["teach"], MODE_OF["propose"], MODE_OF["move"]
MODE_TOUCH, MODE_OFF = MODE_OF["touch"], MODE_OF["off"]
MODES = tuple(MODE_OF.values())
SESSION_MODE = {label: key for key, label in MODE_OF.items()}
NO_SELECTION = "none"
GROOVE_WIDTH_SHOWN_M = 0.03  # a wall this near across the click is named in the label


class PointingPanel:
    """The "Teach by pointing" folder and the part's click handler (module docstring).

    Args:
        server: The viser server.
        session: The workbench session.
        scene: The cell's scene (the part's clicks, the drawings).
        guide_points: The guide-points panel (its selected point is the one dragged).
    """

    def __init__(
        self, server: viser.ViserServer, session: Session, scene: CellScene, guide_points
    ) -> None:
        self.server = server
        self.session = session
        self.scene = scene
        self.guide_points = guide_points
        s = session.pointing.settings
        with server.gui.add_folder("Teach by pointing"):
            self.mode = server.gui.add_dropdown(
                "Click on the part",
                MODES,
                initial_value=MODE_OF[session.pointing.click_mode],
                hint="propose: guide points for the whole wall you click (nothing moves); "
                "teach: the robot goes beside the wall where you click and records a point; "
                "move: the selected point goes where you click; touch: the robot touches the "
                "face you click, to calibrate the work object (Calibrate by touch)",
            )
            self.gap = server.gui.add_number(
                "Gap to wall (mm)", round(s.gap_m * 1e3, 3), min=WALL_GAP_MM.min,
                max=WALL_GAP_MM.max, step=0.1,
            )  # fmt: skip
            self.height = server.gui.add_number(
                "Height above floor (mm)", round(s.height_above_floor_m * 1e3, 3),
                min=MACHINING_HEIGHT_MM.min, max=MACHINING_HEIGHT_MM.max, step=0.5,
            )  # fmt: skip
            self.undo = server.gui.add_button("Undo last point", icon=viser.Icon.ARROW_BACK_UP)
            self.selected = server.gui.add_dropdown("Proposed point", (NO_SELECTION,))
            self.delete = server.gui.add_button("Delete proposed point", icon=viser.Icon.TRASH)
            self.accept = server.gui.add_button(
                "Accept proposal", icon=viser.Icon.CHECK, color="green",
                hint="The robot goes to each point by pushes and touches the wall there; the "
                "points replace the guide points",
            )  # fmt: skip
            self.discard = server.gui.add_button("Discard proposal", icon=viser.Icon.X)
            self.progress = server.gui.add_progress_bar(0.0, visible=False, animated=True)
            self.status = server.gui.add_markdown("")
            self.top = server.gui.add_button("Top view", icon=viser.Icon.ARROW_DOWN)
            self.part = server.gui.add_button("View the part", icon=viser.Icon.CAMERA)
            self.rich = server.gui.add_checkbox(
                "Shadows and reflections",
                False,
                hint="Off: the scene draws several times faster without a GPU (software WebGL), "
                "so clicks on the part answer at once",
            )
            self.compare = server.gui.add_markdown("")
            self.legend = server.gui.add_html(comparison_legend_html(), visible=False)
            self.show_learned = server.gui.add_checkbox(
                "Show the learned program", True, visible=False,
                hint="The program path learning made, drawn in the scene (legend above)",
            )  # fmt: skip
            self.show_cad_only = server.gui.add_checkbox(
                "Show the CAD-only program", True, visible=False,
                hint="The program a CAD/CAM tool would make from the mesh alone (legend above)",
            )  # fmt: skip
        self.handle = server.scene.add_transform_controls(
            "/path/adjust",
            scale=0.03,
            disable_rotations=True,
            active_axes=(True, True, False),
            depth_test=False,
            visible=False,
        )
        self.handle.on_update(self._dragged)
        self.mode.on_update(guarded("Click mode", lambda e: self._settings()))
        self.gap.on_update(guarded("Gap", lambda e: self._settings()))
        self.height.on_update(guarded("Height", lambda e: self._settings()))
        self.undo.on_click(guarded("Undo", lambda e: self._undo()))
        self.delete.on_click(guarded("Delete", lambda e: self._delete()))
        self.accept.on_click(guarded("Accept", lambda e: self.session.pointing.accept()))
        self.discard.on_click(guarded("Discard", lambda e: self.session.pointing.discard()))
        self.selected.on_update(lambda e: self.refresh())
        self.rich.on_update(lambda e: self._rendering(server))
        self.show_learned.on_update(lambda e: self.show_comparison())
        self.show_cad_only.on_update(lambda e: self.show_comparison())
        self._rendering(server)
        self.top.on_click(lambda e: self._view_top(e.client))
        self.part.on_click(lambda e: self._view_part(e.client))
        scene.on_part_click(self._clicked)
        self.last_click_s = float("nan")  # how long the last click took (tests read it)
        self.picked: WallPick | None = None  # the wall the last click picked
        # (point_wobj_m, normal, client) of a click in the touch mode
        self.on_touch: Callable[[np.ndarray, np.ndarray, viser.ClientHandle], None] | None = None
        self.refresh()

    # --- the user's actions ----------------------------------------------------------------

    def _view_top(self, client: viser.ClientHandle | None) -> None:
        """The whole part from straight above (in the browser that asked; none: nothing)."""
        if client is not None:
            self.scene.top_view(client, self.session.robot.workpiece)

    def _view_part(self, client: viser.ClientHandle | None) -> None:
        """The whole part, from where the arm does not stand in the way (in the browser that
        asked; none: nothing)."""
        if client is None:
            return
        pose = self.session.robot.snapshot()
        self.scene.part_view(client, self.session.robot.workpiece, pose.joints_rad,
                             pose.T_base_tcp)  # fmt: skip

    def _rendering(self, server: viser.ViserServer) -> None:
        """Shadows and the environment's reflections on or off (for every browser)."""
        rich = bool(self.rich.value)
        server.scene.configure_default_lights(cast_shadow=rich)
        server.scene.configure_environment_map(hdri="warehouse" if rich else None)

    def _settings(self) -> None:
        self.session.pointing.set_settings(
            gap_m=self.gap.value * 1e-3,
            height_above_floor_m=self.height.value * 1e-3,
            click_mode=SESSION_MODE[self.mode.value],
        )

    def _undo(self) -> None:
        n = len(self.session.project().guide_points)
        if n == 0:
            raise InvalidInputError("no guide point to undo")
        self.session.delete_guide_point(n - 1)

    def _selected_proposed(self) -> int:
        value = self.selected.value
        return int(value[1:]) - 1 if value.startswith("P") else -1

    def _delete(self) -> None:
        index = self._selected_proposed()
        if index < 0:
            raise InvalidInputError("select a proposed point first (P1, P2, ...)")
        self.session.pointing.delete_proposed(index)
        set_value(self.selected, NO_SELECTION)

    def _clicked(
        self, point_wobj_m: np.ndarray, normal: np.ndarray, client: viser.ClientHandle
    ) -> None:
        """A click on the part, as the mode says (errors go to the user who clicked)."""
        mode = MODE_OF[self.session.pointing.click_mode]
        if mode == MODE_OFF:
            return
        started = time.monotonic()
        if mode == MODE_TOUCH:
            if self.on_touch is not None:
                self.on_touch(point_wobj_m, normal, client)
            self.last_click_s = time.monotonic() - started
            return
        title = {MODE_TEACH: "Teach", MODE_PROPOSE: "Propose", MODE_MOVE: "Move"}[mode]
        if mode != MODE_MOVE:  # the wall it picked, drawn before anything moves
            guarded(title, lambda e: self._show_pick(point_wobj_m, normal))(_Event(client))
            if self.picked is None:
                return
        guarded(title, lambda e: self._act(mode, point_wobj_m, normal, client))(_Event(client))
        self.last_click_s = time.monotonic() - started

    def _show_pick(self, point_wobj_m: np.ndarray, normal: np.ndarray) -> None:
        """Highlight the wall the click picked (the same pick the teaching or the proposal
        then makes), before anything moves; a refused pick (a floor, the middle of a narrow
        groove) raises with the reason and highlights nothing."""
        self.picked = None
        self.scene.set_picked_wall(None)
        pick = self.session.pointing.pick(point_wobj_m, normal)
        self.picked = pick
        self.scene.set_picked_wall(pick, picked_wall_text(pick))

    def _act(self, mode: str, point: np.ndarray, normal: np.ndarray, client) -> None:
        pointing = self.session.pointing
        if mode == MODE_PROPOSE:
            proposal = pointing.propose(point, normal)
            set_value(self.selected, NO_SELECTION)
            shape = "closed" if proposal.closed else "open"
            notes = "".join(f"; {note}" for note in proposal.notes)  # e.g. a changed height
            notify_info(
                client,
                "Proposed",
                f"{len(proposal.points)} guide points along the {shape} wall, "
                f"{proposal.height_above_floor_m * 1e3:.1f} mm above the floor{notes}; check "
                "them, then Accept proposal",
            )
        elif mode == MODE_TEACH:
            taught = pointing.teach_at_surface(point, normal)
            if taught.notice:
                notify_error(client, f"G{taught.entry.index + 1} recorded", taught.notice)
        elif mode == MODE_MOVE:
            self._move_selected(point, normal)

    def _move_selected(self, point_wobj_m: np.ndarray, normal: np.ndarray | None) -> None:
        """The selected proposed point slides along the wall there; else the selected guide
        point is taught again there."""
        proposed = self._selected_proposed()
        if proposed >= 0:
            self.session.pointing.move_proposed(proposed, point_wobj_m)
            return
        index = self.guide_points.selected_index()
        if index < 0:
            raise InvalidInputError("select a guide point (G1, ...) or a proposed point first")
        self.session.pointing.teach_at_surface(point_wobj_m, normal, replace_index=index)

    def _dragged(self, event) -> None:
        """The drag handle released: move the selected point to where it was dropped."""
        if getattr(event, "phase", "end") != "end" or event.client is None:
            return
        T = self.session.robot.workpiece.cad().T_base_wobj
        p = (np.asarray(self.handle.position) - T[:3, 3]) @ T[:3, :3]
        guarded("Drag", lambda e: self._move_dropped(p))(event)

    def _move_dropped(self, tcp_wobj_m: np.ndarray) -> None:
        proposed = self._selected_proposed()
        if proposed >= 0:
            self.session.pointing.move_proposed(proposed, tcp_wobj_m)
        else:
            index = self.guide_points.selected_index()
            if index >= 0:
                self.session.pointing.teach_near(tcp_wobj_m, replace_index=index)

    # --- mirroring the session -------------------------------------------------------------

    def refresh(self) -> None:
        """The settings, the proposal (list, drawing, status) and the drag handle on the
        selected point."""
        pointing = self.session.pointing
        set_value(self.mode, MODE_OF[pointing.click_mode])
        set_value(self.gap, round(pointing.settings.gap_m * 1e3, 3))
        set_value(self.height, round(pointing.settings.height_above_floor_m * 1e3, 3))
        proposal = pointing.proposal()
        options: tuple[str, ...] = (NO_SELECTION,)
        if proposal is not None:
            options += tuple(f"P{k + 1}" for k in range(len(proposal.points)))
        keep = self.selected.value if self.selected.value in options else NO_SELECTION
        self.selected.options = options
        set_value(self.selected, keep)
        selected = self._selected_proposed()
        if proposal is None:
            self.scene.paths.set_proposal(None)
            self.status.content = (
                "*Click a wall of the part: **propose** shows guide points for the whole wall; "
                "**teach** sends the robot beside the wall and records a point.*"
            )
        else:
            T = proposal.T_base_wobj
            wall = proposal.wall_wobj_m()
            if proposal.closed:
                wall = np.vstack([wall, wall[:1]])
            self.scene.paths.set_proposal(
                np.array([p.T_base_tcp[:3, 3] for p in proposal.points]),
                [p.reach for p in proposal.points],
                closed=proposal.closed,
                wall_base_m=wall @ T[:3, :3].T + T[:3, 3],
                selected=selected if selected >= 0 else None,
            )
            self.status.content = proposal_markdown(proposal)
        self.accept.disabled = proposal is None
        self.discard.disabled = proposal is None
        self._place_handle(proposal, selected)

    def _place_handle(self, proposal, selected: int) -> None:
        T = self.session.robot.workpiece.cad().T_base_wobj
        position = None
        if proposal is not None and selected >= 0:
            position = proposal.points[selected].T_base_tcp[:3, 3]
        else:
            index = self.guide_points.selected_index()
            guides = list(self.session.project().guide_points)
            if 0 <= index < len(guides):
                position = guides[index].position_m
        if position is None:
            self.handle.visible = False
            return
        from robomach_core.transforms import quaternion_from_matrix

        self.handle.wxyz = quaternion_from_matrix(T[:3, :3])
        self.handle.position = position
        self.handle.visible = True

    def show_comparison(self) -> None:
        """The CAD-only and learned programs against the real wall, drawn (two colours, a
        legend, a toggle each) and tabled."""
        outcome = self.session.project().processed
        current = self.session.project().status()["postprocess"] == "current"
        comparison = getattr(outcome, "cad_comparison", None) if current else None
        self.scene.paths.set_comparison(
            comparison,
            show_learned=self.show_learned.value,
            show_cad_only=self.show_cad_only.value,
        )
        self.compare.content = comparison_markdown(comparison)
        for control in (self.legend, self.show_learned, self.show_cad_only):
            control.visible = comparison is not None

    def show_job(self, job: JobInfo | None) -> None:
        """Progress of a running accept job (None hides the bar)."""
        self.progress.visible = job is not None
        self.accept.disabled = job is not None or self.session.pointing.proposal() is None
        if job is not None:
            set_value(self.progress, round(job.progress * 100.0, 1))


class _Event:
    """The bits of a GUI event ``guarded`` reads, for a click forwarded from the scene."""

    def __init__(self, client) -> None:
        self.client = client


def proposal_markdown(proposal) -> str:
    """The proposal in a few lines: counts, reachability, notes."""
    n = len(proposal.points)
    reach = {r: sum(p.reach == r for p in proposal.points) for r in ("ok", "near", "unreachable")}
    kinds = {k: sum(p.kind == k for p in proposal.points) for k in ("outside corner", "added")}
    lines = [
        f"**{n} proposed points** along the {'closed' if proposal.closed else 'open'} wall "
        f"({proposal.wall.length_m * 1e3:.0f} mm), "
        f"{proposal.height_above_floor_m * 1e3:.1f} mm above the floor (G1 at z = "
        f"{proposal.points[0].position_wobj_m[2] * 1e3:.1f} mm, work object); wall side "
        f"{proposal.wall_side}.",
        f"Reach: {reach['ok']} ok (green), {reach['near']} near a limit (orange), "
        f"{reach['unreachable']} unreachable (red); {kinds['outside corner']} at outside "
        f"corners, {kinds['added']} added where a leg would leave the wall.",
    ]
    for k, p in enumerate(proposal.points):
        if p.message:
            lines.append(f"- P{k + 1}: {p.message}")
    lines += [f"- {note}" for note in proposal.notes]
    return "\n\n".join(lines[:2]) + ("\n\n" + "\n".join(lines[2:]) if lines[2:] else "")


def comparison_markdown(comparison) -> str:
    """The two programs against the (real) wall, as a table."""
    if comparison is None:
        return ""
    title = "the real wall" if comparison.part_deviates else "the wall"
    rows = [
        f"**What learning buys** (against {title}, mm):",
        "",
        "| program | max | RMS | overcut | air | worst at (x, y) |",
        "|---|---:|---:|---:|---:|---|",
    ]
    programs = [("learned", comparison.learned), ("CAD-only", comparison.cad_only)]
    if comparison.cad_only_unregistered is not None:  # what the calibration bought
        programs.append(("CAD-only, as placed (not calibrated)", comparison.cad_only_unregistered))
    for name, s in programs:
        x, y, _ = s.worst_wobj_m * 1e3
        rows.append(
            f"| {name} | {s.max_m * 1e3:.2f} | {s.rms_m * 1e3:.2f} | {s.overcut_m * 1e3:.2f} | "
            f"{s.air_m * 1e3:.2f} | ({x:.0f}, {y:.0f}) |"
        )
    if comparison.deviation_note:
        rows += ["", f"*Real part: {comparison.deviation_note}.*"]
    return "\n".join(rows)


def picked_wall_text(pick) -> str:
    """The label at the wall a click picked: which wall, and how far the one across is (in a
    groove, the two walls the click could have meant)."""
    s = np.array([pick.s_m])
    foot = pick.loop.point_at(s)[0]
    across = [abs(float(o.signed_distance(foot[None])[0])) for o in pick.others]
    near = min(across, default=float("inf"))
    if near < GROOVE_WIDTH_SHOWN_M:
        return f"this wall (the other one is {near * 1e3:.1f} mm across)"
    return "this wall"


def comparison_legend_html() -> str:
    """The legend of the two programs drawn in the scene (their colours, ``COMPARISON_COLORS``)."""

    def swatch(name: str, text: str) -> str:
        r, g, b = COMPARISON_COLORS[name]
        return (
            f'<span style="display:inline-block;width:1.6em;height:0.35em;margin:0 0.4em '
            f'0.2em 0;background:rgb({r},{g},{b});vertical-align:middle"></span>{text}'
        )

    return (
        '<div style="font-size:0.85em;line-height:1.6;padding:0 0.5em">'
        + swatch("learned", "learned program (what path learning met)")
        + "<br>"
        + swatch("cad_only", "CAD-only program (from the mesh alone)")
        + "</div>"
    )
