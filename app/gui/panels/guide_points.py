"""Guide points panel: record, list, select, delete, clear, and the scripted example."""

from __future__ import annotations

import numpy as np
import viser

from app.session import JobInfo, Session
from robomach_core.errors import InvalidInputError

from ..scene import CellScene
from .feedback import guarded
from .inputs import set_value

NO_SELECTION = "none"
LIST_ROWS_MAX = 40  # the table shows the first rows; the scene shows them all


def guide_table(guides: list) -> str:
    """Markdown table of guide points: position in mm, contact force in N."""
    if not guides:
        return "*No guide points yet: lead the tool to the wall and press Record.*"
    rows = ["| # | X mm | Y mm | Z mm | F N |", "|---|---:|---:|---:|---:|"]
    for k, g in enumerate(guides[:LIST_ROWS_MAX]):
        p = g.position_m * 1e3
        rows.append(
            f"| G{k + 1} | {p[0]:.1f} | {p[1]:.1f} | {p[2]:.1f} | {np.linalg.norm(g.force_N):.1f} |"
        )
    if len(guides) > LIST_ROWS_MAX:
        rows.append(f"| ... | {len(guides) - LIST_ROWS_MAX} more | | | |")
    return "\n".join(rows)


class GuidePointsPanel:
    """Record the pose as a guide point, pick one to delete, clear, or load the example.

    "Load the example" runs the demo's scripted operator: it leads the robot by pushes to the
    built-in workpiece's example guide points (a job; progress below the button).
    """

    def __init__(self, server: viser.ViserServer, session: Session, scene: CellScene) -> None:
        self.session = session
        self.scene = scene
        with server.gui.add_folder("Guide points"):
            self.record = server.gui.add_button(
                "Record guide point",
                icon=viser.Icon.PLAYER_RECORD,
                color="orange",
                hint="1-3 mm from the wall or a light touch, tool as it should machine; a point "
                "each side of a corner; outside corners: own point, no wall push "
                "(docs/guide_points.md)",
            )
            self.example = server.gui.add_button(
                "Load the example",
                icon=viser.Icon.WAND,
                hint="The scripted operator pushes the robot to the example guide points "
                "(built-in workpieces); replaces the list",
            )
            self.progress = server.gui.add_progress_bar(0.0, visible=False, animated=True)
            self.selected = server.gui.add_dropdown("Selected", (NO_SELECTION,))
            self.delete = server.gui.add_button("Delete selected", icon=viser.Icon.TRASH)
            self.clear = server.gui.add_button("Clear all", icon=viser.Icon.CLEAR_ALL)
            self.table = server.gui.add_markdown("")
        self.record.on_click(guarded("Record", lambda e: self.session.record_guide_point()))
        self.example.on_click(guarded("Example", lambda e: self.session.learning.start_example()))
        self.delete.on_click(guarded("Delete", lambda e: self._delete_selected()))
        self.clear.on_click(guarded("Clear", lambda e: self.session.clear_guide_points()))
        self.selected.on_update(lambda e: self.show_in_scene())
        self.refresh()

    def _delete_selected(self) -> None:
        index = self.selected_index()
        if index < 0:
            raise InvalidInputError("select a guide point in the list first, then delete it")
        self.session.delete_guide_point(index)

    def selected_index(self) -> int:
        """0-based index of the selected guide point (-1 when none, which the session refuses)."""
        value = self.selected.value
        return int(value[1:]) - 1 if value.startswith("G") else -1

    def refresh(self) -> None:
        """Mirror the session's guide points in the list, the dropdown and the scene."""
        guides = list(self.session.project().guide_points)
        options = (NO_SELECTION, *(f"G{k + 1}" for k in range(len(guides))))
        keep = self.selected.value if self.selected.value in options else NO_SELECTION
        self.selected.options = options
        set_value(self.selected, keep)
        self.table.content = guide_table(guides)
        self.show_in_scene(guides)

    def show_in_scene(self, guides: list | None = None) -> None:
        guides = list(self.session.project().guide_points) if guides is None else guides
        index = self.selected_index()
        self.scene.paths.set_guide_points(
            [g.T_base_tcp for g in guides], selected=index if index >= 0 else None
        )

    def show_job(self, job: JobInfo | None) -> None:
        """Progress of a running example job (None hides the bar)."""
        self.progress.visible = job is not None
        self.example.disabled = job is not None
        if job is not None:
            set_value(self.progress, round(job.progress * 100.0, 1))
