"""Panels for issue 11: the user's own arm, arcs and the URScript program, the mesh score, and
the operator's guide-point rules with the warnings before learning."""

from __future__ import annotations

import viser

from robomach_core.guide_check import guide_point_warnings
from robomach_core.path_learning import PathLearningSettings
from robomach_core.project import result_extras
from robomach_core.robots.custom import MAX_ROBOT_FILE_BYTES

from .feedback import guarded

ROBOT_MIME_TYPES = ".urdf,.zip,application/xml,application/zip,application/octet-stream"
SCRIPT_FILES = ("program.script", "program_fc.script")
GUIDE_HINT = (
    "A guide point: **1-3 mm from the wall** or touching it lightly, the tool as it should "
    "machine (Y towards the wall). Bracket each corner with a point on each side; an **outside "
    "corner** gets its own point off its middle with **no wall push**; never record in heavy "
    "contact. See docs/guide_points.md."
)


class RobotProgramPanel:
    """Upload a URDF arm; arcs on or off; download the URScript; the program's mesh score."""

    def __init__(self, server: viser.ViserServer, session) -> None:
        self.session = session
        s = session.postprocess_settings()
        with server.gui.add_folder("Robot & program", expand_by_default=False):
            self.upload = server.gui.add_upload_button(
                "Upload robot (URDF or zip)",
                icon=viser.Icon.UPLOAD,
                mime_type=ROBOT_MIME_TYPES,
                hint=f"A serial arm of 6 revolute joints with limits, at most "
                f"{MAX_ROBOT_FILE_BYTES / 1e6:g} MB; a zip holds the URDF and its meshes",
            )
            self.arcs = server.gui.add_checkbox(
                "Arcs (MoveC / movec)",
                s.arcs,
                hint="Circular moves where the contour is an arc within the tolerance",
            )
            self.download = server.gui.add_button_group("URScript", SCRIPT_FILES)
            self.summary = server.gui.add_markdown("")
        self.upload.on_upload(
            guarded(
                "Robot upload",
                lambda e: self.session.upload_robot(e.target.value.content, e.target.value.name),
            )
        )
        self.arcs.on_update(
            guarded("Arcs", lambda e: self.session.run_postprocess(arcs=self.arcs.value))
        )
        self.download.on_click(
            guarded(
                "URScript",
                lambda e: e.client.send_file_download(
                    e.target.value,
                    self.session.urscript_program(
                        force_control=e.target.value == "program_fc.script"
                    ).encode("utf-8"),
                    save_immediately=True,
                ),
            )
        )
        self.refresh()

    def refresh(self) -> None:
        """The arm and its language, the arcs setting, the moves and the mesh score."""
        robot = self.session.cell.robot
        lines = [f"Arm **{robot.name}**, program language **{robot.program_language}**."]
        self.arcs.value = self.session.postprocess_settings().arcs
        outcome = self.session.postprocess_outcome()
        if outcome is not None:
            x = result_extras(outcome)
            lines.append(
                f"{x['moves']} moves ({x['circular_moves']} circular; the straight program "
                f"has {x['straight_moves']})."
            )
            if x["mesh_max_deviation_mm"] is not None:
                lines.append(
                    f"Against the part's mesh: max **{x['mesh_max_deviation_mm']:.3f} mm**, "
                    f"RMS **{x['mesh_rms_deviation_mm']:.3f} mm** (minus the tool radius)."
                )
        self.summary.content = "\n\n".join(lines)


class GuideRulesPanel:
    """The operator's rules as a hint, and the guide points that break them."""

    def __init__(self, server: viser.ViserServer, session) -> None:
        self.session = session
        with server.gui.add_folder("Guide-point rules", expand_by_default=False):
            server.gui.add_markdown(GUIDE_HINT)
            self.warnings = server.gui.add_markdown("")
        self.refresh()

    def refresh(self) -> None:
        """Check the current guide points (``guide_check``) and list the warnings."""
        project = self.session.project()
        found = guide_point_warnings(
            project.guide_points,
            PathLearningSettings(),
            workpiece=self.session.cad_workpiece,
            tool_radius_m=project.cell.tool_radius_m,
        )
        self.warnings.content = (
            "\n".join(f"- \u26a0 {w.message}" for w in found)
            if found
            else "*No guide point breaks a rule.*"
        )
