"""Cell panel: robot, tool radius, workpiece choice and mesh upload."""

from __future__ import annotations

import viser

from app.session import Session
from robomach_core.cell import ROBOT_NAMES, TOOL_RADIUS_RANGE_M
from robomach_core.part import MAX_MESH_BYTES, MAX_MESH_TRIANGLES, WORKPIECE_NAMES, PartDeviation

from .feedback import guarded, notify_info, upload_handled
from .inputs import set_value

_PRESET = PartDeviation.realistic()  # the preset's ranges, for the hint
MESH_MIME_TYPES = ".stl,.obj,.ply,model/stl,model/obj,application/octet-stream"


class CellPanel:
    """Choose the robot, the ball-cutter radius and the workpiece (built-in or uploaded).

    "Apply" rebuilds the cell: the robot goes home and the guide points and results are
    cleared, because they belong to the old cell. An upload applies at once.
    """

    def __init__(self, server: viser.ViserServer, session: Session) -> None:
        self.session = session
        s = session.project().cell
        lo, hi = (r * 1e3 for r in TOOL_RADIUS_RANGE_M)
        max_mb = getattr(session, "max_upload_bytes", MAX_MESH_BYTES) / 1e6
        max_triangles = getattr(session, "max_triangles", MAX_MESH_TRIANGLES)
        with server.gui.add_folder("Cell"):
            self.robot = server.gui.add_dropdown(
                "Robot", self._robot_options(s), initial_value=s.robot
            )
            self.tool_radius = server.gui.add_slider(
                "Tool radius (mm)",
                lo,
                hi,
                0.1,
                s.tool_radius_m * 1e3,
                hint="Ball cutter radius",
            )
            self.workpiece = server.gui.add_dropdown(
                "Workpiece", self._workpiece_options(s), initial_value=s.workpiece
            )
            self.realistic = server.gui.add_checkbox(
                "Realistic part",
                s.part_deviation is not None,
                hint=f"The part in the cell differs from its mesh by a fixture error "
                f"({_PRESET.fixture_shift_mm / 2:g}-{_PRESET.fixture_shift_mm:g} mm, "
                f"{_PRESET.fixture_rotation_deg / 2:g}-{_PRESET.fixture_rotation_deg:g} deg) and "
                f"casting deviations (+-{_PRESET.wall_offset_mm:g} mm, burrs), from the cell's "
                "seed: calibrate the work object by touch (Calibrate by touch), then teach on "
                "the mesh; learning meets the real part",
            )
            self.apply = server.gui.add_button(
                "Apply cell",
                icon=viser.Icon.CHECK,
                hint="Rebuild the cell: the robot goes home; guide points and results are cleared",
            )
            self.upload = server.gui.add_upload_button(
                "Upload mesh (STL/OBJ/PLY, mm)",
                icon=viser.Icon.UPLOAD,
                mime_type=MESH_MIME_TYPES,
                hint=f"At most {max_mb:g} MB and {max_triangles:,} triangles, in mm; "
                "placed on the table in front of the robot",
            )
            self.info = server.gui.add_markdown("")
        self.apply.on_click(
            guarded(
                "Cell",
                lambda e: self.session.set_cell(
                    robot=self.robot.value,
                    tool_radius_m=self.tool_radius.value * 1e-3,
                    workpiece=self.workpiece.value,
                    part_deviation=PartDeviation.realistic(self.session.project().cell.seed)
                    if self.realistic.value
                    else None,
                ),
            )
        )
        self.upload.on_upload(upload_handled(server, "Mesh upload", self._uploaded))
        self.refresh()

    def _uploaded(self, event) -> None:
        """Use the uploaded mesh and say so, or say why not (viser's own "uploaded" note only
        means the bytes arrived)."""
        name = event.target.value.name
        self.session.upload_workpiece(event.target.value.content, name)
        wp = self.session.robot.workpiece.cad()
        x, y, z = wp.T_base_wobj[:3, 3] * 1e3
        e = wp.mesh.extents * 1e3
        notify_info(
            event.client,
            f"{name} is the workpiece",
            f"{len(wp.mesh.faces):,} triangles, {e[0]:.0f} x {e[1]:.0f} x {e[2]:.0f} mm; its "
            f"origin is at the work object, ({x:.0f}, {y:.0f}, {z:.0f}) mm in the base frame. "
            "Click a wall to propose guide points.",
        )

    @staticmethod
    def _robot_options(settings) -> tuple[str, ...]:
        """The built-in arms, and the user's uploaded one when the cell has it."""
        mine = () if settings.robot in ROBOT_NAMES else (settings.robot,)
        return (*ROBOT_NAMES, *mine)

    @staticmethod
    def _workpiece_options(settings) -> tuple[str, ...]:
        names = tuple(WORKPIECE_NAMES)
        return names if settings.workpiece_builtin else (*names, settings.workpiece)

    def refresh(self) -> None:
        """Mirror the session's cell (after a change from here, the API or a project load)."""
        s = self.session.project().cell
        wp = self.session.robot.workpiece
        self.robot.options = self._robot_options(s)
        set_value(self.robot, s.robot)
        set_value(self.tool_radius, round(s.tool_radius_m * 1e3, 3))
        self.workpiece.options = self._workpiece_options(s)
        set_value(self.workpiece, s.workpiece)
        set_value(self.realistic, s.part_deviation is not None)
        cad = wp.cad()
        extents = cad.mesh.extents * 1e3
        kind = "built-in" if s.workpiece_builtin else "uploaded mesh"
        truth = "scored against its true wall" if wp.wall is not None else "no ground truth"
        x, y, z = cad.T_base_wobj[:3, 3] * 1e3
        real = f" The part in the cell differs: {wp.deviation_note}." if wp.deviation_note else ""
        self.info.content = (
            f"**{cad.name}** ({kind}): {len(cad.mesh.faces):,} triangles, "
            f"{extents[0]:.0f} x {extents[1]:.0f} x {extents[2]:.0f} mm, work object at "
            f"({x:.0f}, {y:.0f}, {z:.0f}) mm (base frame); {truth}.{real}"
        )
