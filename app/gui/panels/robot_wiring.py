"""Panels for issue 11: the user's own arm and its controller, arcs, the mesh score, and the
operator's guide-point rules with the warnings before learning. The programs themselves, in
every language the arm runs, are downloaded from the Export panel."""

from __future__ import annotations

from collections.abc import Callable

import viser

from app.session import Session
from robomach_core.choices import TEXTS
from robomach_core.learning.settings import WallSideSetting
from robomach_core.project import result_extras
from robomach_core.robots import ARM_FAMILIES
from robomach_core.robots.custom import MAX_ROBOT_FILE_BYTES

from .feedback import guarded, upload_handled
from .inputs import set_value

ROBOT_MIME_TYPES = ".urdf,.zip,application/xml,application/zip,application/octet-stream"
FAMILY_CHOICES = ("auto", *ARM_FAMILIES)
GUIDE_HINT = TEXTS["guide_point_advice"]
SEVERITY_ICON = TEXTS["severity_icon"]
SEVERITY_WORDS = TEXTS["severity"]


class RobotProgramPanel:
    """Upload a URDF arm (its controller recognised or chosen); arcs on or off; the arm's
    languages and the program's mesh score."""

    def __init__(self, server: viser.ViserServer, session: Session) -> None:
        self.session = session
        s = session.project().post_settings
        with server.gui.add_folder("Robot & program", expand_by_default=False):
            self.family = server.gui.add_dropdown(
                "Controller",
                FAMILY_CHOICES,
                hint="The uploaded arm's controller, which decides its program language: auto "
                "recognises a built-in arm's kinematics (a UR5 URDF is a UR), else ABB",
            )
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
            self.summary = server.gui.add_markdown("")
        self.upload.on_upload(
            upload_handled(
                server,
                "Robot upload",
                lambda e: self.session.upload_robot(
                    e.target.value.content, e.target.value.name, family=self.family.value
                ),
            )
        )
        self.arcs.on_update(
            guarded("Arcs", lambda e: self.session.learning.run_postprocess(arcs=self.arcs.value))
        )
        self.refresh()

    def refresh(self) -> None:
        """The arm and its language, the arcs setting, the moves and the mesh score."""
        robot = self.session.robot.cell.robot
        offered = ", ".join(self.session.programs.program_languages()) or "none"
        lines = [
            f"Arm **{robot.name}** ({robot.family} controller), program languages "
            f"**{offered}** (downloads in the Export panel)."
        ]
        set_value(self.arcs, self.session.project().post_settings.arcs)
        outcome = self.session.project().processed
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

    def __init__(
        self,
        server: viser.ViserServer,
        session: Session,
        settings: Callable[[], tuple[WallSideSetting, bool]] | None = None,
    ) -> None:
        self.session = session
        self.settings = settings  # () -> (wall_side, closed) of the path-learning panel
        self.listeners: list = []  # called with the findings' markdown after each check
        with server.gui.add_folder("Guide-point rules", expand_by_default=False):
            server.gui.add_markdown(GUIDE_HINT)
            self.warnings = server.gui.add_markdown("")
        self.refresh()

    def refresh(self) -> None:
        """Check the current guide points (``guide_check``) with the path-learning panel's
        wall side, and list the findings, refusals first."""
        wall_side, closed = self.settings() if self.settings is not None else ("auto", True)
        found = self.session.learning.guide_findings(closed=closed, wall_side=wall_side)
        self.warnings.content = findings_markdown(found)
        for listener in self.listeners:
            listener(self.warnings.content)


def findings_markdown(found) -> str:
    """The check's findings, one line per rule (``app.findings``: its other points
    named), refusals first, each marked by its severity in the words every page uses
    (``choices.TEXTS``): a refusal in bold (learning will not start), a warning, a note."""
    from app.findings import grouped_findings

    if not found:
        return "*No guide point breaks a rule.*"
    lines = []
    for group in grouped_findings(found):
        words = SEVERITY_WORDS[group.severity]
        label = f"**{words}**" if group.severity == "refusal" else f"*{words}*"
        lines.append(f"- {SEVERITY_ICON[group.severity]} {label}: {group.text()}")
    return "\n".join(lines)
