"""Machining panel: stock, process, force limit, controller and compensation, the cell's options
and the variations; run and compare with progress and cancel; the comparison table (sortable,
the rule's pick and its reason, what the cell cannot run greyed; open large with the figure);
live uPlot plots of force and feed along the path; the stock (translucent ribbon) and the path
coloured by the finished-wall error.

It works through ``app.session.machining.MachiningService`` (the same the REST API and the
pendant use) and follows the session's events from its own thread, so a run started from the
REST API shows here too, and a change of the guide points marks the result out of date.
"""

from __future__ import annotations

import logging
import threading
from typing import TypedDict

import numpy as np
import viser

from app.session import Session
from app.session.machining import JobKind, MachiningService
from robomach_core.limits import (
    MACHINING_DEPTH_EXPONENT,
    MACHINING_FEED_EXPONENT,
    MACHINING_FORCE_LIMIT_N,
    MACHINING_PROCESS_GAIN_N,
    MACHINING_VARIATIONS,
    Range,
)
from robomach_core.machining import MACHINING_CONTROLLERS, STAGE_PLANS
from robomach_core.machining.choice import OPTION_NAMES, OPTION_TEXT, RULE_TEXT
from robomach_core.project import STOCK_SOURCES
from robomach_core.stiffness import COMPENSATIONS

from ..colors import deviation_colors
from .feedback import guarded, upload_handled
from .inputs import set_value
from .large import open_large, png_html
from .machining_table import SORT_KEYS, table_html

log = logging.getLogger(__name__)
OUT_OF_DATE = "\u26a0 Out of date"
JOB_KINDS = ("machining_run", "machining_compare")
REFRESH_HZ = 4.0
PLOT_POINTS = 800
WALL_SCALE_MM = 0.2  # red at and above this finished-wall error
STOCK_COLOR = (200, 140, 60)
FORCE_TITLE = "Force along the path"
FEED_TITLE = "Feed along the path"
EVENTS = ("job", "machining", "postprocess", "recording", "guide_points", "cell", "project")


class MachiningPanel:
    """The Machining folder of the sidebar (module docstring)."""

    def __init__(
        self, server: viser.ViserServer, session: Session, service: MachiningService
    ) -> None:
        self.server = server
        self.session = session
        self.service = service  # the session's MachiningService
        s = self.service.settings_document()
        with server.gui.add_folder("Machining", expand_by_default=False):
            self.stock = server.gui.add_dropdown(
                "Stock",
                STOCK_SOURCES,
                initial_value=s["stock_source"],
                hint="builtin: allowance 0.3-3 mm with burrs from the cell's seed",
            )
            self.profile = server.gui.add_text(
                "Profile s:a (mm)",
                "",
                hint="allowance profile along the path, e.g. 0:0.5, 100:2, 300:1",
            )
            self.upload = server.gui.add_upload_button(
                "Upload stock mesh", icon=viser.Icon.UPLOAD, mime_type="*/*"
            )
            self.gain = server.gui.add_number(
                "K (N)", s["process_gain_N"], **_limits(MACHINING_PROCESS_GAIN_N), step=0.1
            )
            self.alpha = server.gui.add_number(
                "alpha", s["depth_exponent"], **_limits(MACHINING_DEPTH_EXPONENT), step=0.01
            )
            self.beta = server.gui.add_number(
                "beta", s["feed_exponent"], **_limits(MACHINING_FEED_EXPONENT), step=0.01
            )
            self.limit = server.gui.add_number(
                "Force limit (N)", s["force_limit_N"], **_limits(MACHINING_FORCE_LIMIT_N), step=1.0
            )
            self.controller = server.gui.add_dropdown(
                "Controller", MACHINING_CONTROLLERS, initial_value=s["controller"]
            )
            self.compensation = server.gui.add_dropdown(
                "Compensation", COMPENSATIONS, initial_value=s["compensation"]
            )
            self.stages = server.gui.add_dropdown(
                "Stages",
                STAGE_PLANS,
                initial_value=s["stages"],
                hint="under offline compensation, how fuzzy and two-stage pick their stage: "
                "online (switching in the cell by the force) or planned (the program's speeds, "
                "no feed control in the cell: a casting with burrs elsewhere meets them at the "
                "planned speeds; run variations to see it)",
            )
            with server.gui.add_folder("Cell options", expand_by_default=False):
                self.options = {
                    name: server.gui.add_checkbox(
                        OPTION_TEXT[name].split(" (")[0],
                        name in s["cell_options"],
                        hint=OPTION_TEXT[name] + ": decides which configurations are choosable",
                    )
                    for name in OPTION_NAMES
                }
                self.options_default = server.gui.add_button(
                    "Defaults of the arm's language", hint="RAPID: FC SpeedChange; UR: force mode"
                )
            self.variations = server.gui.add_number(
                "Variations",
                s["variations"],
                min=int(MACHINING_VARIATIONS.min),
                max=int(MACHINING_VARIATIONS.max),
                step=1,
                hint="also cut each configuration on N castings drawn from the part's variation; "
                "the rule then reads the 95th percentiles",
            )
            self.run = server.gui.add_button("Run", icon=viser.Icon.PLAYER_PLAY, color="green")
            self.compare = server.gui.add_button(
                "Compare all", icon=viser.Icon.TABLE, hint="6 feed controls x 3 compensations"
            )
            self.cancel = server.gui.add_button(
                "Cancel", icon=viser.Icon.PLAYER_STOP, color="red", disabled=True
            )
            self.progress = server.gui.add_progress_bar(0.0)
            self.status = server.gui.add_markdown("")
            self.choose_best = server.gui.add_button(
                "Choose the rule's pick", disabled=True, hint=RULE_TEXT
            )
            self.sort = server.gui.add_dropdown(
                "Sort by", tuple(SORT_KEYS), initial_value="configuration"
            )
            self.table = server.gui.add_html("")
            self.enlarge = server.gui.add_button(
                "Open the table and figure large", icon=viser.Icon.ARROWS_MAXIMIZE, disabled=True
            )
            self.force_plot = server.gui.add_uplot(
                *_empty_force(), title=FORCE_TITLE, aspect=1.6,
                scales={"x": viser.uplot.Scale(time=False, auto=True)},
                legend=viser.uplot.Legend(show=True),
            )  # fmt: skip
            self.feed_plot = server.gui.add_uplot(
                (np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2)),
                (
                    viser.uplot.Series(label="path (mm)"),
                    viser.uplot.Series(label="feed (mm/s)", stroke="#1d3557", width=1.5),
                    viser.uplot.Series(label="min", stroke="#a8dadc", width=0.8),
                    viser.uplot.Series(label="max", stroke="#a8dadc", width=0.8),
                ),
                title=FEED_TITLE,
                scales={"x": viser.uplot.Scale(time=False, auto=True)},
                legend=viser.uplot.Legend(show=True),
                aspect=1.6,
            )
        self._wire()
        self.job_id: str | None = None
        self._shown_result: object = None
        self._shown_key: object = None
        self._result_epoch = session.robot.epoch
        self._nodes: dict[str, viser.SceneNodeHandle] = {}
        self._dirty = threading.Event()
        self._stop = threading.Event()
        self._unsubscribe = session.subscribe(self._on_event)
        self._thread = threading.Thread(target=self._loop, name="panel-machining", daemon=True)
        self._dirty.set()
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._dirty.set()
        self._unsubscribe()
        self._thread.join(timeout=2.0)

    # --- controls ----------------------------------------------------------------------------

    def _wire(self) -> None:
        def settings(_e) -> None:
            self.service.set_settings(
                process_gain_N=float(self.gain.value),
                depth_exponent=float(self.alpha.value),
                feed_exponent=float(self.beta.value),
                force_limit_N=float(self.limit.value),
            )

        for control in (self.gain, self.alpha, self.beta, self.limit):
            control.on_update(guarded("Machining", settings))
        choice = guarded(
            "Machining",
            lambda e: self.service.choose(self.controller.value, self.compensation.value),
        )
        self.controller.on_update(choice)
        self.compensation.on_update(choice)
        self.stock.on_update(guarded("Machining stock", lambda e: self._set_stock()))
        self.profile.on_update(guarded("Machining stock", lambda e: self._set_stock()))

        @self.upload.on_upload
        def _(event) -> None:
            f = self.upload.value
            upload = lambda e: self.service.upload_stock(f.content, f.name)  # noqa: E731
            upload_handled(self.server, "Stock mesh", upload)(event)

        def options(_e) -> None:
            chosen = [n for n, box in self.options.items() if box.value]
            self.service.set_settings(cell_options=chosen)

        for box in self.options.values():
            box.on_update(guarded("Cell options", options))
        self.options_default.on_click(
            guarded("Cell options", lambda e: self.service.set_settings(cell_options_default=True))
        )
        self.stages.on_update(
            guarded("Machining", lambda e: self.service.set_settings(stages=self.stages.value))
        )
        self.variations.on_update(
            guarded(
                "Machining",
                lambda e: self.service.set_settings(variations=int(self.variations.value)),
            )
        )
        self.sort.on_update(guarded("Machining", lambda e: self._show_table()))
        self.enlarge.on_click(guarded("Machining", self._open_large))
        self.run.on_click(guarded("Machining", lambda e: self._start("run")))
        self.compare.on_click(guarded("Machining", lambda e: self._start("compare")))
        self.cancel.on_click(guarded("Cancel", lambda e: self._cancel()))
        self.choose_best.on_click(guarded("Machining", lambda e: self._choose_best()))

    def _set_stock(self) -> None:
        source = self.stock.value
        if source == "profile" and self.profile.value.strip():
            pairs = []
            for item in self.profile.value.split(","):
                s_mm, a_mm = item.split(":")
                pairs.append((float(s_mm), float(a_mm)))
            self.service.set_stock_profile(pairs)
        elif source == "builtin":
            self.service.set_settings(stock_source="builtin")

    def _start(self, kind: JobKind) -> None:
        self.job_id = self.service.start(kind)
        self._dirty.set()

    def _cancel(self) -> None:
        if self.job_id is not None:
            self.session.jobs.cancel(self.job_id)

    def _choose_best(self) -> None:
        from app.session.records import ConflictError

        result = self.service.require_result()
        if result.chosen is None:
            raise ConflictError(f"nothing to choose: {result.reason}")
        row = result.rows[result.chosen]
        self.service.choose(row["controller"], row["compensation"])

    def _open_large(self, event) -> None:
        """The whole table (every column) and the figure of the chosen run, window-wide."""
        result = self.service.require_result()
        parts = [table_html(list(result.rows), result.chosen, result.reason,
                            sort_by=self.sort.value, wide=True)]  # fmt: skip
        png = self._figure_png(result)
        if png is not None:
            parts.append(png_html(png, alt="force, feed and wall error along the path"))
        open_large(
            event.client,
            "Machining comparison",
            "".join(parts),
            download=None if png is None else ("machining.png", png),
        )

    def _figure_png(self, result) -> bytes | None:
        import tempfile
        from pathlib import Path

        from robomach_core.machining import plot_runs

        setup = self.service.setup().settings
        runs = [r for r in result.runs if r.compensation == "off"][:3]
        own = result.run_for(setup.controller, setup.compensation)
        if own is not None and own not in runs:
            runs.append(own)
        if not runs:
            return None
        with tempfile.TemporaryDirectory() as folder:
            chosen = f"{setup.controller} / {setup.compensation}"
            title = f"machining runs of this result (chosen: {chosen})"
            path = plot_runs(runs, Path(folder) / "machining.png", title=title)
            return path.read_bytes()

    # --- refresh -----------------------------------------------------------------------------

    def _on_event(self, topic: str) -> None:
        if topic in EVENTS:
            self._dirty.set()

    def _loop(self) -> None:
        while not self._stop.is_set():
            self._dirty.wait()
            if self._stop.is_set():
                return
            self._dirty.clear()
            try:
                self.refresh()
            except Exception:
                log.exception("machining panel refresh failed")
            self._stop.wait(1.0 / REFRESH_HZ)

    def refresh(self) -> None:
        """Mirror the settings, the job, the result and the scene."""
        s = self.service.settings_document()
        set_value(self.controller, s["controller"])
        set_value(self.compensation, s["compensation"])
        set_value(self.stages, s["stages"])
        set_value(self.stock, s["stock_source"])
        for name, box in self.options.items():
            set_value(box, name in s["cell_options"])
        set_value(self.variations, s["variations"])
        job = self._job()
        running = job is not None and job.status in ("queued", "running")
        self.run.disabled = self.compare.disabled = running
        self.cancel.disabled = not running
        self.progress.animated = running
        if running:
            set_value(self.progress, round(job.progress * 100.0, 1))
            self.status.content = f"{job.kind.replace('_', ' ')}: {job.progress:.0%}"
            self._dirty.set()  # keep polling the progress while it runs
        else:
            self.status.content = self._summary(job)
        self._show_result()

    def _job(self):
        active = self.session.jobs.active(JOB_KINDS)
        if active:
            self.job_id = active[0].id
            return active[0]
        if self.job_id is None:
            return None
        try:
            return self.session.jobs.get(self.job_id)
        except KeyError:
            return None

    def _summary(self, job) -> str:
        lines = []
        if job is not None and job.status not in ("done", "queued", "running"):
            lines.append(f"**{job.status}**: {job.error or ''}")
        s = self.service.settings_document()
        for reason in s["stale_settings"].values():
            lines.append(f"*Stale*: {reason}.")
        if s["program_needs"]:
            lines.append(f"Program: {s['program_needs']}.")
        status = self.service.status()
        if status == "none":
            lines.append("*No machining result yet: run or compare.*")
        elif status == "stale":
            reason = self.session.project().stale_reasons().get("machining", "")
            lines.append(f"**{OUT_OF_DATE}**: {reason}.")
        return "\n\n".join(lines)

    def _show_table(self) -> None:
        result = self.service.result()
        self.table.content = (
            ""
            if result is None
            else table_html(
                list(result.rows), result.chosen, result.reason, sort_by=self.sort.value
            )
        )

    def _show_result(self) -> None:
        result = self.service.result()
        self.choose_best.disabled = result is None or result.chosen is None
        self.enlarge.disabled = result is None
        epoch = self.session.robot.epoch
        if result is not self._shown_result:
            self._result_epoch = epoch  # the cell the result was first shown in
        # A result of a cell no longer there (another robot, part or place) is not drawn over
        # the new one: its path stood on the old cell's table.
        old_cell = result is not None and self._result_epoch != epoch
        # The plots show the chosen configuration's run: a choice redraws them.
        s = self.service.setup().settings
        key = (result, old_cell, self.service.status(), s.controller, s.compensation)
        if key == self._shown_key:
            return
        self._shown_result, self._shown_key = result, key
        self._show_table()
        if result is None or old_cell:
            self.force_plot.data = _empty_force()[0]
            self.force_plot.title = self.feed_plot.title = (
                FORCE_TITLE
                if result is None
                else f"{FORCE_TITLE}: the last run was in another cell"
            )
            self.feed_plot.title = FEED_TITLE
            for node in self._nodes.values():
                node.remove()
            self._nodes.clear()
            return
        if result.runs:
            d = self.service.plot_data(max_points=PLOT_POINTS)
            x = np.asarray(d["path_mm"])
            n = len(x)
            self.force_plot.data = (
                x,
                np.asarray(d["force_N"]),
                np.asarray(d["force_max_N"]),
                np.full(n, d["reference_N"]),
                np.full(n, d["limit_N"]),
            )
            self.feed_plot.data = (
                x,
                np.asarray(d["feed_mm_s"]),
                np.asarray(d["feed_min_mm_s"]),
                np.asarray(d["feed_max_mm_s"]),
            )
            which = self._which_run(d["controller"], d["compensation"])
            self.force_plot.title = f"{FORCE_TITLE}: {which}"
            self.feed_plot.title = f"{FEED_TITLE}: {which}"
        self._show_scene()

    def _which_run(self, controller: str, compensation: str) -> str:
        """Which run a plot shows, in words: its configuration, whether it is the chosen one,
        and whether it is out of date."""
        s = self.service.setup().settings
        chosen = (controller, compensation) == (s.controller, s.compensation)
        note = "the chosen configuration" if chosen else "the chosen one was not run"
        if self.service.status() == "stale":
            note += ", out of date"
        return f"{controller} / {compensation} ({note})"

    def _show_scene(self) -> None:
        ribbon = self.service.stock_ribbon()
        if ribbon is not None:
            vertices, faces = ribbon
            self._nodes["stock"] = self.server.scene.add_mesh_simple(
                "/machining/stock",
                vertices,
                faces,
                color=STOCK_COLOR,
                opacity=0.45,
                side="double",
                cast_shadow=False,
            )
        wall = self.service.wall_error_points()
        if wall is not None:
            points, error_mm = wall
            step = max(1, len(points) // 4000)
            self._nodes["wall"] = self.server.scene.add_point_cloud(
                "/machining/wall_error",
                points[::step],
                deviation_colors(np.abs(error_mm[::step]) * 1e-3, WALL_SCALE_MM * 1e-3),
                point_size=0.0015,
            )


class _Bounds(TypedDict):
    min: float
    max: float


def _limits(rng: Range) -> _Bounds:
    """An input's ``min`` and ``max`` keywords from a ``limits`` range."""
    return {"min": float(rng.min), "max": float(rng.max)}


def _empty_force():
    z = np.zeros(2)
    return (z, z, z, z, z), (
        viser.uplot.Series(label="path (mm)"),
        viser.uplot.Series(label="force (N)", stroke="#d62728", width=1.2),
        viser.uplot.Series(label="max (N)", stroke="#f4a261", width=0.8),
        viser.uplot.Series(label="reference (N)", stroke="#1d3557", width=2.0, dash=(8, 4)),
        viser.uplot.Series(label="limit (N)", stroke="#000000", width=1.5, dash=(3, 3)),
    )
