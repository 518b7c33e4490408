"""The machining stage: the project's program cut on the simulated compliant arm (issue 8).

PROBLEM   The program a project holds is learned from a recording; what it does to the part (how
          long the cut takes, where the force peaks, how far the finished wall ends from the
          nominal one) depends on the stock, the process, the feed controller and the
          deflection compensation, and the configuration the user picks must reach the exports.
STRATEGY  ``MachiningSetup`` (the project's ``machining_settings`` slot) holds the run settings
          (``machining.MachiningSettings``: process K, alpha, beta, force limit, and the CHOSEN
          controller and compensation) and the stock source. ``machine`` cuts the post-processed
          targets (the nominal program: the run applies its own compensation) along the stock,
          one configuration or the matrix, with the project's identified stiffness when it
          holds compensation settings, else ``machining.identify_stiffness``. Its result is
          stamped with ``machining_inputs_key``, which leaves the controller and compensation
          out (a comparison covers them all), so choosing never makes a result stale.
SOLUTION  ``choose`` saves the configuration: it sets the machining settings' controller and
          compensation AND the project's ``cmrr`` slot (the FC SpeedChange block, from the same
          reference, speed cap and minimum ratio; None for constant feed) and the
          ``compensation`` slot's mode, so the CMRR settings and the machining choice are one
          thing. ``program_targets`` then exports the run's corrected program when offline
          compensation is chosen and the machining result holding it is current.

Choice rule (``best_row``): among completed runs whose peak force stays within 10 % of the
limit, those within 5 % of the fastest cycle time; of these the smallest finished-wall max error.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np

from ..errors import InvalidInputError
from ..postprocess import Targets
from ..robot import Robot
from ..workpiece import Workpiece
from ._stages import require_processed
from ._value import Project, machining_inputs_key

MM = 1e-3
STOCK_SOURCES = ("builtin", "profile", "mesh")
# The choice: peak force within this share above the limit, cycle within this of the fastest.
PEAK_MARGIN = 0.10
CYCLE_MARGIN = 0.05
# compensation choice -> the compensation settings' mode of the exported program.
EXPORT_COMPENSATION_MODES = {"off": "off", "offline": "offline_linear", "online": "online"}
EXPORT_MODE_CHOICES = {
    "off": "off",
    "offline_linear": "offline",
    "offline_nonlinear": "offline",
    "online": "online",
}


@dataclass(frozen=True)
class MachiningSetup:
    """The project's machining settings (its ``machining_settings`` slot).

    Attributes:
        settings: ``machining.MachiningSettings``; its ``controller`` and ``compensation`` are
            the chosen configuration.
        stock_source: ``"builtin"`` (from the cell's seed), ``"profile"`` or ``"mesh"``.
        stock_profile_mm: ((s_mm, allowance_mm), ...) for ``"profile"``.
        stock_mesh: (filename, bytes) of a stock mesh (mm, base frame) for ``"mesh"``.
    """

    settings: Any = None
    stock_source: str = "builtin"
    stock_profile_mm: tuple[tuple[float, float], ...] | None = None
    stock_mesh: tuple[str, bytes] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.settings is None:
            from ..machining import MachiningSettings

            object.__setattr__(self, "settings", MachiningSettings())
        if self.stock_source not in STOCK_SOURCES:
            raise InvalidInputError(
                f"stock source must be one of {', '.join(STOCK_SOURCES)}, got {self.stock_source!r}"
            )
        if self.stock_source == "profile" and not self.stock_profile_mm:
            raise InvalidInputError("a profile stock needs its allowance profile (s_mm, mm)")
        if self.stock_source == "mesh" and self.stock_mesh is None:
            raise InvalidInputError("a mesh stock needs its mesh file")

    def key(self) -> str:
        """Fingerprint of what a result depends on: everything but the chosen controller and
        compensation (a comparison covers every configuration)."""
        return self._key

    @cached_property
    def _key(self) -> str:
        from ..machining import settings_to_dict

        doc = settings_to_dict(self.settings)
        doc.pop("controller", None)
        doc.pop("compensation", None)
        doc.pop("controller_settings", None)
        h = hashlib.blake2b(digest_size=12)
        h.update(json.dumps(doc, sort_keys=True, default=str).encode())
        h.update(self.stock_source.encode())
        h.update(json.dumps(self.stock_profile_mm).encode())
        if self.stock_mesh is not None:
            h.update(self.stock_mesh[0].encode())
            h.update(self.stock_mesh[1])
        return h.hexdigest()

    def inputs_key(self, project: Project) -> str:
        """``key`` and the identified stiffness the compensated runs use (the project's, or the
        simulated campaign's: the same values whether or not ``choose`` copied them in)."""
        model = compensation_model(project, project.cell.robot)
        return f"{self.key()}:{json.dumps([float(k) for k in model.stiffness_Nm_rad])}"


@dataclass(frozen=True, eq=False)
class MachiningResult:
    """The machining stage's result (the project's ``machining`` slot).

    Attributes:
        rows: One dict per run (``machining.comparison_rows``: units in the keys).
        table_text: The side-by-side table.
        chosen: Index into ``rows`` of the configuration ``best_row`` picks.
        programs: "controller/compensation" -> corrected program of each offline run.
        runs: The ``MachiningRun`` values (traces), when computed in this process.
        stock: The ``machining.Stock`` cut (None when read back from a store).
        inputs: ``machining_inputs_key`` of the project it was computed from.
    """

    rows: tuple[dict[str, Any], ...]
    table_text: str
    chosen: int
    programs: dict[str, Targets]
    runs: tuple[Any, ...] = ()
    stock: Any = None
    inputs: str = ""

    def summary(self) -> dict[str, Any]:
        """``machining_summary.json``: the runs and which one the rule chose."""
        chosen = self.rows[self.chosen]
        return {
            "runs": [dict(r, chosen=i == self.chosen) for i, r in enumerate(self.rows)],
            "chosen": {"controller": chosen["controller"], "compensation": chosen["compensation"]},
            "choice_rule": (
                f"completed runs with peak force within {PEAK_MARGIN:.0%} of the limit; of those "
                f"within {CYCLE_MARGIN:.0%} of the fastest cycle, the smallest wall max error"
            ),
        }

    def run_for(self, controller: str, compensation: str) -> Any:
        """The ``MachiningRun`` of a configuration, or None."""
        for run in self.runs:
            if run.controller == controller and run.compensation == compensation:
                return run
        return None


def machining_setup_of(project: Project) -> MachiningSetup:
    """The project's machining setup (defaults when it holds none), its controller and
    compensation read from the project's CMRR and compensation slots: those are what the
    exports carry, so the machining choice and the CMRR settings cannot disagree (a CMRR
    controller set another way, e.g. from a study, is the machining controller)."""
    setup = project.machining_settings
    if not isinstance(setup, MachiningSetup):
        setup = MachiningSetup()
        if project.cmrr is None and project.compensation is None:
            return setup
    controller = "constant" if project.cmrr is None else project.cmrr.controller.kind
    comp = project.compensation
    compensation = "off" if comp is None else EXPORT_MODE_CHOICES.get(comp.mode, "off")
    s = setup.settings
    if (s.controller, s.compensation) == (controller, compensation):
        return setup
    own = s.controller_settings
    s = replace(
        s,
        controller=controller,
        compensation=compensation,
        controller_settings=own if own is not None and own.kind == controller else None,
    )
    return replace(setup, settings=s)


def wall_normals_for_project(
    project: Project, workpiece: Workpiece, targets: Targets
) -> np.ndarray:
    """(m, 3) wall normals at the targets, pointing at the tool: from a built-in part's known
    wall, else from the contact force learned at each target (the wall pushes the tool away
    from it), made perpendicular to the path and the work object's z."""
    from ..machining import wall_normals_for_workpiece
    from ..machining.path import path_tangents
    from ..transforms import matrix_from_quaternion

    if workpiece.wall is not None:
        return wall_normals_for_workpiece(workpiece, targets.position_m)
    rec = project.learned.recording
    forces = np.array(
        [
            matrix_from_quaternion(rec.quaternion_wxyz[i]) @ rec.wrench_tool[i, :3]
            for i in targets.sample_index
        ]
    )
    up = workpiece.T_base_wobj[:3, 2]
    t = path_tangents(targets.position_m)
    side = np.cross(up, t)
    side /= np.maximum(np.linalg.norm(side, axis=1, keepdims=True), 1e-12)
    sign = np.sign(np.einsum("ij,ij->i", side, forces))
    sign = np.where(sign == 0.0, 1.0, sign)
    # One side for the whole contour (the wall does not change sides): the majority's.
    return side * (1.0 if np.sum(sign) >= 0 else -1.0)


def build_stock(
    project: Project, workpiece: Workpiece, targets: Targets, normals: np.ndarray
) -> Any:
    """The stock along the program: built-in from the cell's seed, a profile, or a mesh."""
    from ..machining import builtin_stock, stock_from_mesh, stock_from_profile

    setup = machining_setup_of(project)
    r = project.cell.tool_radius_m
    p = targets.position_m
    if setup.stock_source == "profile":
        return stock_from_profile(
            p, setup.stock_profile_mm, wall_normals_m=normals, tool_radius_m=r
        )
    if setup.stock_source == "mesh":
        from pathlib import Path

        from ..workpiece import mesh_from_bytes

        name, data = setup.stock_mesh
        mesh = mesh_from_bytes(data, Path(name).suffix.lower(), name=Path(name).stem).mesh
        mesh = mesh.copy()
        mesh.apply_transform(workpiece.T_base_wobj)
        return stock_from_mesh(mesh, p, normals, tool_radius_m=r)
    return builtin_stock(p, project.cell.seed, wall_normals_m=normals, tool_radius_m=r)


def compensation_model(project: Project, robot_name: str) -> Any:
    """The identified stiffness: the project's compensation settings when it holds some (on this
    robot), else the simulated CMM campaign of ``machining.identify_stiffness``."""
    from ..joint_compliance import JointCompliance
    from ..machining import identify_stiffness

    comp = project.compensation
    if comp is not None and comp.robot == robot_name:
        return JointCompliance(tuple(comp.joint_stiffness_Nm_rad))
    s = machining_setup_of(project).settings
    return identify_stiffness(
        robot_name, seed=s.seed, poses=s.identification_poses, cmm_noise_m=s.cmm_noise_m
    ).model


def machine(
    project: Project,
    workpiece: Workpiece,
    robot: Robot,
    *,
    controllers: tuple[str, ...] | None = None,
    compensations: tuple[str, ...] | None = None,
    progress: Callable[[float], None] | None = None,
    cancel: Any = None,
) -> MachiningResult:
    """Cut the project's current program (``machining.compare_configurations``).

    ``controllers`` / ``compensations`` None run the chosen one of the project's settings; give
    tuples for the matrix. ``cancel`` (flag or callable) raises ``CancelledError``. The result
    is stamped with ``machining_inputs_key(project)``; store it with ``with_machining_result``.

    Raises:
        MissingResultError / StaleResultError: no current post-processed program.
    """
    from ..machining import compare_configurations

    processed = require_processed(project)
    targets = processed.result.targets
    setup = machining_setup_of(project)
    s = setup.settings
    normals = wall_normals_for_project(project, workpiece, targets)
    stock = build_stock(project, workpiece, targets, normals)
    ctrls = (s.controller,) if controllers is None else tuple(controllers)
    comps = (s.compensation,) if compensations is None else tuple(compensations)
    model = compensation_model(project, robot.name) if any(m != "off" for m in comps) else None
    comparison = compare_configurations(
        robot,
        targets,
        normals,
        stock,
        s,
        controllers=ctrls,
        compensations=comps,
        compensation_model=model,
        progress=progress,
        cancel=cancel,
    )
    # Each run's full summary, with the table's comparison figures.
    rows = tuple(
        _plain_row({**run.summary, **row})
        for run, row in zip(comparison.runs, comparison.rows, strict=True)
    )
    programs = {
        f"{r.controller}/{r.compensation}": r.program
        for r in comparison.runs
        if r.compensation == "offline" and r.program is not None
    }
    return MachiningResult(
        rows=rows,
        table_text=comparison.table_text,
        chosen=best_row(rows),
        programs=programs,
        runs=tuple(comparison.runs),
        stock=stock,
        inputs=machining_inputs_key(project),
    )


def _plain_row(row: dict[str, Any]) -> dict[str, Any]:
    return {
        k: (float(v) if isinstance(v, (np.floating, np.integer)) else v) for k, v in row.items()
    }


def best_row(rows: tuple[dict[str, Any], ...] | list[dict[str, Any]]) -> int:
    """Index of the configuration to choose (module docstring); the smallest wall error of all
    completed runs when none keeps the force, and 0 when none completed."""
    done = [i for i, r in enumerate(rows) if r.get("completed") and r.get("cycle_time_s")]
    if not done:
        return 0
    safe = [
        i for i in done if rows[i]["force_peak_N"] <= (1 + PEAK_MARGIN) * rows[i]["force_limit_N"]
    ]
    pool = safe or done
    fastest = min(rows[i]["cycle_time_s"] for i in pool)
    quick = [i for i in pool if rows[i]["cycle_time_s"] <= (1 + CYCLE_MARGIN) * fastest]
    return min(quick, key=lambda i: (rows[i]["wall_error_max_mm"], rows[i]["cycle_time_s"]))


def with_machining_result(project: Project, result: MachiningResult) -> Project:
    """The project holding ``result`` (stamped with the key it was computed from)."""
    return replace(project, machining=result, machining_inputs=result.inputs)


def with_machining_setup(project: Project, setup: MachiningSetup) -> Project:
    """The project with new machining settings; the chosen configuration follows them into the
    CMRR and compensation slots (``choose``)."""
    project = replace(project, machining_settings=setup)
    return choose(project, setup.settings.controller, setup.settings.compensation)


def choose(project: Project, controller: str, compensation: str) -> Project:
    """Save the configuration the exports carry: the machining settings' controller and
    compensation, the CMRR slot (the FC SpeedChange block; None for constant feed) and the
    compensation slot's mode (module docstring)."""
    from ..machining import COMPENSATION_NAMES, MACHINING_CONTROLLERS

    if controller not in MACHINING_CONTROLLERS:
        raise InvalidInputError(
            f"unknown controller {controller!r}; choose one of {', '.join(MACHINING_CONTROLLERS)}"
        )
    if compensation not in COMPENSATION_NAMES:
        raise InvalidInputError(
            f"unknown compensation {compensation!r}; choose one of {', '.join(COMPENSATION_NAMES)}"
        )
    setup = machining_setup_of(project)
    s = replace(setup.settings, controller=controller, compensation=compensation)
    if s.controller_settings is not None and s.controller_settings.kind != controller:
        s = replace(s, controller_settings=None)
    setup = replace(setup, settings=s)
    project = replace(project, machining_settings=setup, cmrr=cmrr_for(s))
    comp = project.compensation
    mode = EXPORT_COMPENSATION_MODES[compensation]
    if compensation != "off" and (comp is None or comp.robot != project.cell.robot):
        from ..stiffness import CompensationSettings

        model = compensation_model(replace(project, compensation=None), project.cell.robot)
        comp = CompensationSettings(
            robot=project.cell.robot,
            joint_stiffness_Nm_rad=tuple(float(k) for k in model.stiffness_Nm_rad),
            mode="off",
        )
    if comp is not None:
        gravity = comp.tool_gravity
        if mode == "online" and gravity is None:
            # Not identified here: the tool's nominal mass and centre of mass, no sensor bias.
            from ..stiffness.gravity import ToolGravity

            tool = project.tool()
            gravity = ToolGravity(tool.mass_kg, tuple(float(v) for v in tool.com_m))
        comp = replace(comp, mode=mode, tool_gravity=gravity)
    return replace(project, compensation=comp)


def cmrr_for(settings: Any) -> Any:
    """The CMRR settings of a machining configuration (None for constant feed): the same
    controller, reference force, speed cap and minimum speed ratio the run used."""
    if settings.controller == "constant":
        return None
    from ..cmrr import CmrrSettings
    from ..cmrr.controllers import settings_for

    return CmrrSettings(
        controller=settings.controller_settings or settings_for(settings.controller),
        reference_force_N=settings.reference_N,
        command_speed_m_s=settings.command_speed_cap_m_s,
        min_speed_ratio=settings.min_speed_ratio,
    )


def chosen_program(project: Project) -> tuple[Targets, str] | None:
    """The corrected program of the chosen offline-compensated run, when the project's machining
    result holds it and is current; else None (``program_targets`` falls back)."""
    result = project.machining
    if not isinstance(project.machining_settings, MachiningSetup) or not isinstance(
        result, MachiningResult
    ):
        return None
    s = machining_setup_of(project).settings
    if s.compensation != "offline" or project.status()["machining"] != "current":
        return None
    program = result.programs.get(f"{s.controller}/{s.compensation}")
    if program is None:
        return None
    nominal = require_processed(project).result.targets
    return program, (
        f"deflection compensation: offline for the {s.controller} cut's predicted process "
        f"force, {len(program)} targets from {len(nominal)}"
    )


# --- documents -------------------------------------------------------------------------------


def machining_setup_document(setup: MachiningSetup) -> dict[str, Any]:
    """JSON form of the setup (the stock mesh by file name only)."""
    from ..machining import settings_to_dict

    return {
        "settings": settings_to_dict(setup.settings),
        "stock_source": setup.stock_source,
        "stock_profile_mm": None
        if setup.stock_profile_mm is None
        else [list(p) for p in setup.stock_profile_mm],
        "stock_mesh": None if setup.stock_mesh is None else setup.stock_mesh[0],
    }


def machining_setup_from_document(doc: dict[str, Any], mesh: tuple[str, bytes] | None = None):
    """The setup from ``machining_setup_document`` (controller settings back to the defaults)."""
    from ..machining import MachiningSettings

    values = dict(doc.get("settings") or {})
    values.pop("controller_settings", None)
    known = set(MachiningSettings.__dataclass_fields__)
    settings = MachiningSettings(**{k: v for k, v in values.items() if k in known})
    profile = doc.get("stock_profile_mm")
    source = doc.get("stock_source", "builtin")
    if source == "mesh" and mesh is None:
        source = "builtin"
    return MachiningSetup(
        settings,
        source,
        None if profile is None else tuple((float(a), float(b)) for a, b in profile),
        mesh if source == "mesh" else None,
    )


def machining_result_document(result: MachiningResult) -> dict[str, Any]:
    """JSON form of a result: rows, table, choice, inputs and the offline programs."""
    return {
        "rows": list(result.rows),
        "table_text": result.table_text,
        "chosen": result.chosen,
        "inputs": result.inputs,
        "programs": {k: _targets_doc(t) for k, t in result.programs.items()},
    }


def machining_result_from_document(doc: dict[str, Any]) -> MachiningResult:
    return MachiningResult(
        rows=tuple(doc["rows"]),
        table_text=str(doc["table_text"]),
        chosen=int(doc["chosen"]),
        programs={k: _targets_from(v) for k, v in (doc.get("programs") or {}).items()},
        inputs=str(doc["inputs"]),
    )


def _targets_doc(t: Targets) -> dict[str, Any]:
    return {k: np.asarray(v).tolist() for k, v in asdict(t).items()}


def _targets_from(doc: dict[str, Any]) -> Targets:
    return Targets(
        position_m=np.asarray(doc["position_m"], dtype=float),
        quaternion_wxyz=np.asarray(doc["quaternion_wxyz"], dtype=float),
        joints_rad=np.asarray(doc["joints_rad"], dtype=float),
        speed_m_s=np.asarray(doc["speed_m_s"], dtype=float),
        curvature_1_m=np.asarray(doc["curvature_1_m"], dtype=float),
        sample_index=np.asarray(doc["sample_index"], dtype=int),
    )
