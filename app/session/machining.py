"""The workbench's machining: settings, runs and comparisons as jobs, the result, the choice.

One ``MachiningService`` per session, built at start-up and injected into the viser panel,
the REST routes (and so the pendant). It acts on the session's ``Project`` through the core's stage
(``robomach_core.project.machine``, ``choose``), so the CLI and the workbench compute and export
the same way. A run computes from a snapshot of the project outside the lock and is swapped in
only if the project's machining inputs did not change meanwhile. The traces of the last run
live in memory (the store keeps the settings, the choice and the result's figures).

Public API (thread-safe):
    setup() -> MachiningSetup; settings_document() -> dict
    set_settings(process_gain_N=, depth_exponent=, feed_exponent=, force_limit_N=,
                 controller=, compensation=, stock_source=, cell_options=,
                 cell_options_default=, variations=) -> MachiningSetup
    set_stock_profile(profile_mm) / upload_stock(data, filename) -> MachiningSetup
    start(kind: "run" | "compare") -> job_id   progress and cancel through session.jobs
    result() -> MachiningResult | None; status() -> none | current | stale
    plot_data(controller=None, compensation=None, max_points=) -> dict   decimated trace
    choose(controller, compensation) -> MachiningSetup
"""

from __future__ import annotations

import base64
import os
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from robomach_core import project as core
from robomach_core.errors import InvalidInputError
from robomach_core.machining import MACHINING_CONTROLLERS
from robomach_core.machining.retained import bucket_trace, retained_result
from robomach_core.stiffness import COMPENSATIONS

from ..memory import give_back
from .records import ConflictError, log

if TYPE_CHECKING:
    from .session import Session

MM = 1e-3
JobKind = Literal["run", "compare"]
# Points of a plotted trace: each bucket gives its mean, min and max (the envelope).
PLOT_POINTS = 1500
MAX_STOCK_BYTES = 20_000_000
# The Dask scheduler the workbench runs its machining cuts on (unset: the local cores).
CLUSTER_ENV = "ROBOMACH_CLUSTER"


class MachiningService:
    """Machining of the session's open project (module docstring)."""

    def __init__(self, session: Session) -> None:
        self.session = session

    # --- reading -----------------------------------------------------------------------------

    def setup(self) -> core.MachiningSetup:
        return core.machining_setup_of(self.session.project())

    def settings_document(self) -> dict[str, Any]:
        """The settings (units in the keys), the stock source and the chosen configuration."""
        project = self.session.project()
        setup = core.machining_setup_of(project)
        s = setup.settings
        caps = core.capabilities_of(project)
        result = self.result()
        return {
            "cell_options": sorted(caps.options),
            "cell_options_default": setup.cell_options is None,
            "variations": setup.variations,
            "choice_reason": None if result is None else result.reason,
            "stale_settings": core.stale_settings(project),
            "program_needs": core.machining_note(project),
            "process_gain_N": s.process_gain_N,
            "depth_exponent": s.depth_exponent,
            "feed_exponent": s.feed_exponent,
            "force_limit_N": s.force_limit_N,
            "reference_force_N": s.reference_N,
            "controller": s.controller,
            "compensation": s.compensation,
            "stages": s.stages,
            "stock_source": setup.stock_source,
            "stock_profile_mm": None
            if setup.stock_profile_mm is None
            else [list(p) for p in setup.stock_profile_mm],
            "stock_mesh": None if setup.stock_mesh is None else setup.stock_mesh[0],
        }

    def result(self) -> core.MachiningResult | None:
        result = self.session.project().machining
        return result if isinstance(result, core.MachiningResult) else None

    def status(self) -> core.StageStatus:
        return self.session.project().status()["machining"]

    def require_result(self) -> core.MachiningResult:
        result = self.result()
        if result is None:
            raise ConflictError("no machining result yet: run the machining or the comparison")
        return result

    def stock_ribbon(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(vertices, faces) of the last run's stock for the 3D scene, or None."""
        result = self.result()
        if result is None or result.stock is None:
            return None
        return result.stock.ribbon_mesh()

    def plot_data(
        self,
        controller: str | None = None,
        compensation: str | None = None,
        *,
        max_points: int = PLOT_POINTS,
    ) -> dict[str, Any]:
        """A run's trace for plots, decimated to ``max_points`` buckets along the path with the
        min/max envelope of force and feed, and the finished-wall error along the path.
        Defaults to the chosen configuration, else the result's first run. The session keeps
        ``retained.RETAINED_POINTS`` buckets of each run: no more points than that."""
        result = self.require_result()
        setup = self.setup()
        c = controller or setup.settings.controller
        m = compensation or setup.settings.compensation
        run = result.run_for(c, m)
        if run is None and controller is None and compensation is None and result.runs:
            run = result.runs[0]
        if run is None:
            raise ConflictError(
                f"no trace of {c} / {m} in memory: run it (traces are not kept across restarts)"
            )
        tr = bucket_trace(run.trace, max_points)  # buckets of the kept trace (``retained``)
        w_idx = np.linspace(0, len(run.wall.s_m) - 1, min(max_points, len(run.wall.s_m))).astype(
            int
        )
        return {
            "controller": run.controller,
            "compensation": run.compensation,
            "samples": tr.samples_total,
            "path_mm": (tr.path_m / MM).tolist(),
            "time_s": tr.time_s.tolist(),
            "force_N": tr.force_N.tolist(),
            "force_min_N": tr.force_min_N.tolist(),
            "force_max_N": tr.force_max_N.tolist(),
            "reference_N": float(run.trace.reference_N[0]),
            "limit_N": float(run.trace.limit_N[0]),
            "feed_mm_s": (tr.feed_m_s / MM).tolist(),
            "feed_min_mm_s": (tr.feed_min_m_s / MM).tolist(),
            "feed_max_mm_s": (tr.feed_max_m_s / MM).tolist(),
            "depth_mm": (tr.depth_m / MM).tolist(),
            "wall_s_mm": (run.wall.s_m[w_idx] / MM).tolist(),
            "wall_error_mm": (run.wall.error_m[w_idx] / MM).tolist(),
        }

    def wall_error_points(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(points (k, 3) m, wall error (k,) mm) along the chosen run's path, or None."""
        result = self.result()
        if result is None or result.stock is None:
            return None
        setup = self.setup()
        run = result.run_for(setup.settings.controller, setup.settings.compensation)
        run = run or (result.runs[0] if result.runs else None)
        if run is None:
            return None
        from robomach_core.transforms import arc_length_m

        stock = result.stock
        s_path = arc_length_m(stock.path_points_m)
        s = run.wall.s_m
        points = np.stack(
            [np.interp(s, s_path, stock.path_points_m[:, i]) for i in range(3)], axis=1
        )
        return points, run.wall.error_m / MM

    # --- acting ------------------------------------------------------------------------------

    def set_settings(
        self,
        *,
        process_gain_N: float | None = None,
        depth_exponent: float | None = None,
        feed_exponent: float | None = None,
        force_limit_N: float | None = None,
        controller: str | None = None,
        compensation: str | None = None,
        stages: str | None = None,
        stock_source: str | None = None,
        cell_options: list[str] | tuple[str, ...] | None = None,
        cell_options_default: bool | None = None,
        variations: int | None = None,
    ) -> core.MachiningSetup:
        """Change settings (None keeps one). A process, limit, stages or variations change dates
        the result; a controller or compensation change is a choice (``choose``) and does not, nor
        do the cell's options (``cell_options``; ``cell_options_default`` back to the program
        language's): the result is re-chosen for them."""
        values = {
            k: v
            for k, v in {
                "process_gain_N": process_gain_N,
                "depth_exponent": depth_exponent,
                "feed_exponent": feed_exponent,
                "force_limit_N": force_limit_N,
                "controller": controller,
                "compensation": compensation,
                "stages": stages,
            }.items()
            if v is not None
        }

        def change(setup: core.MachiningSetup) -> core.MachiningSetup:
            s = replace(setup.settings, **values)
            if s.reference_force_N is not None and s.reference_force_N > s.force_limit_N:
                s = replace(s, reference_force_N=None)
            source = setup.stock_source if stock_source is None else stock_source
            out = replace(setup, settings=s, stock_source=source)
            if cell_options_default:
                out = replace(out, cell_options=None)
            elif cell_options is not None:
                out = replace(out, cell_options=tuple(cell_options))
            if variations is not None:
                out = replace(out, variations=int(variations))
            return out

        return self._update(change)

    def set_stock_profile(self, profile_mm: list[tuple[float, float]]) -> core.MachiningSetup:
        """Use an allowance profile [(s_mm, allowance_mm), ...] as the stock (checked against
        the program's path when the machining runs)."""
        table = tuple((float(a), float(b)) for a, b in profile_mm)
        if not table:
            raise InvalidInputError("the allowance profile needs at least one (s_mm, mm) pair")
        return self._update(
            lambda setup: replace(setup, stock_source="profile", stock_profile_mm=table)
        )

    def upload_stock(self, data: bytes, filename: str) -> core.MachiningSetup:
        """Use a stock mesh (STL/OBJ/PLY, mm, the workpiece's frame) as the stock."""
        from robomach_core.part import mesh_from_bytes

        if len(data) > MAX_STOCK_BYTES:
            raise InvalidInputError(
                f"{filename}: {len(data) / 1e6:.1f} MB exceeds {MAX_STOCK_BYTES / 1e6:.0f} MB"
            )
        name = Path(filename).name or "stock.stl"
        mesh_from_bytes(data, Path(name).suffix.lower(), name=Path(name).stem)  # parse check
        return self._update(
            lambda setup: replace(setup, stock_source="mesh", stock_mesh=(name, bytes(data)))
        )

    def choose(self, controller: str, compensation: str) -> core.MachiningSetup:
        """Save the configuration the exports carry (``project.choose``)."""
        change = lambda p: core.choose(p, controller, compensation)  # noqa: E731
        project = self.session.commit(change, "post", topics=("postprocess", "machining"))
        return core.machining_setup_of(project)

    def start(self, kind: JobKind) -> str:
        """Job: run the chosen configuration (``"run"``) or the matrix (``"compare"``), on the
        setup's stock and its variations; on every local core, or on the Dask cluster named
        by ``ROBOMACH_CLUSTER`` when the server runs (the operator's choice: no request can
        point the server at an address)."""
        cluster = os.environ.get(CLUSTER_ENV) or None
        if kind not in ("run", "compare"):
            raise InvalidInputError(f"machining job kind must be run or compare, got {kind!r}")
        s = self.session
        view = s.view()
        project, workpiece, robot = view.project, view.cell.workpiece, view.cell.robot
        core.require_processed(project)
        if project.machining_settings is None:  # from the CMRR / compensation slots
            project = core.with_machining_setup(project, core.machining_setup_of(project))
        controllers = MACHINING_CONTROLLERS if kind == "compare" else None
        compensations = COMPENSATIONS if kind == "compare" else None

        def work(ctx: Any) -> core.MachiningResult:
            return core.machine(
                project,
                workpiece,
                robot,
                controllers=controllers,
                compensations=compensations,
                progress=ctx.progress,
                cancel=ctx.cancelled,
                workers=None,
                cluster=cluster,
            )

        def done(result: core.MachiningResult) -> None:
            def change(current: core.Project) -> core.Project:
                if current.machining_settings is None:
                    current = core.with_machining_setup(current, core.machining_setup_of(current))
                if core.machining_inputs_key(current) != result.inputs:
                    raise ConflictError(
                        "the program or the machining settings changed while it ran; run it again"
                    )
                return core.with_machining_result(current, kept)

            # What the views show of it, not every control period (issue 32: a comparison
            # kept 54-86 MB of traces).
            kept = retained_result(result)
            s.commit(change, "post", topics=("machining",))

        # Once the job let go of the runs' full traces (and of the result it replaced).
        return s.jobs.submit(
            f"machining_{kind}", work, on_done=done, on_end=lambda info: give_back()
        )

    # --- internals ---------------------------------------------------------------------------

    def _update(
        self, change: Callable[[core.MachiningSetup], core.MachiningSetup]
    ) -> core.MachiningSetup:
        def transition(project: core.Project) -> core.Project:
            project = core.with_machining_setup(project, change(core.machining_setup_of(project)))
            result = project.machining
            if isinstance(result, core.MachiningResult):
                # The cell's options decide what is choosable: the same figures, re-chosen.
                caps = core.capabilities_of(project)
                if tuple(sorted(caps.options)) != tuple(result.capabilities):
                    project = replace(project, machining=result.for_cell(caps))
            return project

        project = self.session.commit(transition, "post", topics=("postprocess", "machining"))
        return core.machining_setup_of(project)


# --- persistence (the project's post_json gets "machining") ----------------------------------


def machining_document(project: core.Project) -> dict[str, Any] | None:
    """What the store keeps of the machining: settings (stock mesh as base64), the result's
    figures and offline programs, and the fingerprint it was computed from."""
    setup = project.machining_settings
    if not isinstance(setup, core.MachiningSetup):
        return None
    doc: dict[str, Any] = {"setup": core.machining_setup_document(setup)}
    if setup.stock_mesh is not None:
        doc["stock_mesh_b64"] = base64.b64encode(setup.stock_mesh[1]).decode()
    result = project.machining
    if isinstance(result, core.MachiningResult):
        doc["result"] = core.machining_result_document(result)
    return doc


def machining_from_document(project: core.Project, doc: dict[str, Any] | None) -> core.Project:
    """The project with the stored machining (an unreadable one is dropped and logged)."""
    if not doc:
        return project
    try:
        mesh = None
        if doc.get("stock_mesh_b64"):
            name = (doc["setup"] or {}).get("stock_mesh") or "stock.stl"
            mesh = (name, base64.b64decode(doc["stock_mesh_b64"]))
        setup = core.machining_setup_from_document(doc["setup"], mesh)
        project = replace(project, machining_settings=setup)
        if doc.get("result"):
            project = core.with_machining_result(
                project, core.machining_result_from_document(doc["result"])
            )
    except (KeyError, TypeError, ValueError, InvalidInputError) as exc:
        log.error("stored machining settings unreadable (%s); dropped", exc)
    return project


def markdown_table(text: str) -> str:
    """The fixed-width comparison table as markdown (columns split on runs of two spaces)."""
    import re

    table = text.split("\n\n")[0]  # what the cell lacks is said below the table
    lines = [re.split(r"\s{2,}", line.strip()) for line in table.splitlines() if line.strip()]
    if not lines:
        return ""
    out = ["| " + " | ".join(lines[0]) + " |", "|" + "---|" * len(lines[0])]
    out += ["| " + " | ".join(cells) + " |" for cells in lines[1:]]
    return "\n".join(out)
