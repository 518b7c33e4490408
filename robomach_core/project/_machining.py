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
          holds compensation settings, else ``machining.stiffness_model``. Its result is
          stamped with ``machining_inputs_key``, which leaves the controller and compensation
          out (a comparison covers them all), so choosing never makes a result stale.
SOLUTION  ``choose`` saves the configuration: it sets the machining settings' controller and
          compensation AND the project's ``cmrr`` slot (the FC SpeedChange block, from the same
          reference, speed cap and minimum ratio; None for constant feed) and the
          ``compensation`` slot's mode, so the CMRR settings and the machining choice are one
          thing. ``program_targets`` then exports the run's corrected program when offline
          compensation is chosen and the machining result holding it is current.

Choice rule (``machining.choice.choose``, the one the CLI, REST and both GUIs use): among the
completed runs the cell can run (``capabilities_of``) whose peak force stays within the
limit, those within 5 % of the fastest cycle time; of these the smallest finished-wall max
error; with a variation sweep (``MachiningSetup.variations``) on the 95th percentiles.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from ..cell import Robot
from ..errors import InvalidInputError
from ..part import Workpiece
from ..postprocess import Targets
from ._stages import require_processed
from ._value import Project, machining_inputs_key

if TYPE_CHECKING:
    from ..stiffness.settings import CompensationSetting

MM = 1e-3
STOCK_SOURCES = ("builtin", "profile", "mesh")
# Stocks of a variation sweep (0: the one stock only).
MAX_VARIATIONS = 1000
# compensation choice -> the compensation settings' mode of the exported program.
EXPORT_COMPENSATION_MODES: dict[str, CompensationSetting] = {
    "off": "off",
    "offline": "offline_linear",
    "online": "online",
}
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
        cell_options: The cell's controller options (``machining.choice.OPTION_NAMES``);
            None: the defaults of the arm's program language.
        variations: Stocks drawn from the part's variation per configuration (0: the one
            stock); the choice then reads the 95th percentiles.
        campaign_stiffness_Nm_rad: The joint stiffness ``choose`` copied into the project's
            compensation slot from the simulated CMM campaign, if it did: compensation
            settings holding it are the campaign, so a result cut with the campaign stays
            current when they are copied in (``inputs_key``).
    """

    settings: Any = None
    stock_source: str = "builtin"
    stock_profile_mm: tuple[tuple[float, float], ...] | None = None
    stock_mesh: tuple[str, bytes] | None = field(default=None, repr=False)
    cell_options: tuple[str, ...] | None = None
    variations: int = 0
    campaign_stiffness_Nm_rad: tuple[float, ...] | None = None

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
        if self.stock_profile_mm is not None:
            from ..machining.stock import check_profile_mm

            object.__setattr__(self, "stock_profile_mm", check_profile_mm(self.stock_profile_mm))
        if self.stock_source == "mesh" and self.stock_mesh is None:
            raise InvalidInputError("a mesh stock needs its mesh file")
        if self.cell_options is not None:
            from ..machining.choice import CellCapabilities

            options = tuple(sorted(CellCapabilities(frozenset(self.cell_options)).options))
            object.__setattr__(self, "cell_options", options)
        if isinstance(self.variations, bool) or not (
            isinstance(self.variations, int) and 0 <= self.variations <= MAX_VARIATIONS
        ):
            raise InvalidInputError(
                f"variations must be an integer within 0-{MAX_VARIATIONS}, got {self.variations!r}"
            )

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
        if self.variations:
            h.update(f"variations {self.variations}".encode())
        if self.stock_mesh is not None:
            h.update(self.stock_mesh[0].encode())
            h.update(self.stock_mesh[1])
        return h.hexdigest()

    def inputs_key(self, project: Project) -> str:
        """``key`` and where the stiffness the compensated runs use comes from: the project's
        compensation settings, or the simulated campaign (named by its arm and settings, not
        run: ``Project.status`` stays cheap), the same whether or not ``choose`` copied the
        campaign's stiffness in."""
        comp = project.compensation
        robot = project.cell.robot
        if comp is not None and comp.robot == robot:
            own = tuple(float(k) for k in comp.joint_stiffness_Nm_rad)
            if own != self.campaign_stiffness_Nm_rad:
                return f"{self.key()}:{json.dumps(own)}"
        s = self.settings
        campaign = f"campaign {robot} {s.seed} {s.identification_poses} {s.cmm_noise_m!r}"
        return f"{self.key()}:{campaign}"


@dataclass(frozen=True, eq=False)
class MachiningResult:
    """The machining stage's result (the project's ``machining`` slot).

    Attributes:
        rows: One dict per configuration (``machining.comparison_rows``: units in the keys;
            with a variation sweep also its p50 / p95 figures), ``runnable`` and ``needs``
            marked for the cell it was chosen for.
        table_text: The side-by-side table.
        chosen: Index into ``rows`` of the rule's pick (``machining.choice.choose``); None
            when the cell can run no completed configuration.
        programs: "controller/compensation" -> corrected program of each offline run.
        runs: The ``MachiningRun`` values (traces), when computed in this process.
        stock: The ``machining.Stock`` cut (None when read back from a store).
        inputs: ``machining_inputs_key`` of the project it was computed from.
        reason: The rule's reason for ``chosen``, in words.
        capabilities: The cell options the rows were marked for.
        variation: The variation sweep (stocks, seed, ranges) or None.
    """

    rows: tuple[dict[str, Any], ...]
    table_text: str
    chosen: int | None
    programs: dict[str, Targets]
    runs: tuple[Any, ...] = ()
    stock: Any = None
    inputs: str = ""
    reason: str = ""
    capabilities: tuple[str, ...] = ()
    variation: dict[str, Any] | None = None

    def summary(self) -> dict[str, Any]:
        """``machining_summary.json``: the runs, the rule's pick and why."""
        from ..machining.choice import RULE_TEXT

        chosen = None if self.chosen is None else self.rows[self.chosen]
        return {
            "runs": [dict(r, chosen=i == self.chosen) for i, r in enumerate(self.rows)],
            "chosen": None
            if chosen is None
            else {"controller": chosen["controller"], "compensation": chosen["compensation"]},
            "choice_rule": RULE_TEXT,
            "choice_reason": self.reason,
            "cell_options": list(self.capabilities),
            "variation": self.variation,
        }

    def for_cell(self, capabilities: Any) -> MachiningResult:
        """The result re-chosen for another cell (rows re-marked; the figures are the same)."""
        from ..machining import format_table
        from ..machining.choice import choose, mark_runnable

        rows = tuple(mark_runnable(list(self.rows), capabilities))
        pick = choose(list(rows), capabilities)
        return replace(
            self,
            rows=rows,
            table_text=format_table(rows, chosen=pick.index),
            chosen=pick.index,
            reason=pick.reason,
            capabilities=tuple(sorted(capabilities.options)),
        )

    def run_for(self, controller: str, compensation: str) -> Any:
        """The ``MachiningRun`` of a configuration, or None."""
        for run in self.runs:
            if run.controller == controller and run.compensation == compensation:
                return run
        return None


def capabilities_of(project: Project) -> Any:
    """The cell's controller options: the machining setup's (those the arm's controller can
    have: ``machining.choice.OPTION_FAMILIES``), else the defaults of the program language of
    the cell's arm (``machining.choice.LANGUAGE_DEFAULT_OPTIONS``)."""
    from ..machining.choice import CellCapabilities

    family = _arm_family(project.cell.robot)
    setup = project.machining_settings
    if isinstance(setup, MachiningSetup) and setup.cell_options is not None:
        return CellCapabilities.for_family(family, setup.cell_options)
    try:
        from ..cell import program_language

        language = program_language(project.cell.robot)
    except Exception:  # an arm not (yet) registered in this process: no options assumed
        return CellCapabilities(frozenset(), family)
    return CellCapabilities.for_language(language)


def _arm_family(robot_name: str) -> str | None:
    """The arm's family (``abb``, ``ur``, ``kuka``), None when it is not registered here."""
    from ..robots import registry

    try:
        return registry.arm(robot_name).family
    except Exception:  # an arm not (yet) registered in this process
        return None


def machining_setup_of(project: Project) -> MachiningSetup:
    """The project's machining setup (defaults when it holds none), its controller and
    compensation read from the project's CMRR and compensation slots: those are what the
    exports carry, so the machining choice and the CMRR settings cannot disagree (a CMRR
    controller set another way, e.g. from a study, is the machining controller; without
    machining settings, its reference force too)."""
    setup = project.machining_settings
    if not isinstance(setup, MachiningSetup):
        setup = MachiningSetup()
        if project.cmrr is None and project.compensation is None:
            return setup
    controller = "constant" if project.cmrr is None else project.cmrr.controller.kind
    comp = project.compensation
    compensation = "off" if comp is None else EXPORT_MODE_CHOICES.get(comp.mode, "off")
    s = setup.settings
    # without machining settings, the CMRR's reference force (a study's, --cmrr-settings) is the
    # machining's; a reference over the limit brings the limit the default fraction pairs with
    # it (a study's 200 N: 286 N). With them, their reference rules (a choice copies it).
    reference = {}
    own_settings = isinstance(project.machining_settings, MachiningSetup)
    if (
        project.cmrr is not None
        and not own_settings
        and abs(project.cmrr.reference_force_N - s.reference_N) > 1e-9
    ):
        f_ref = project.cmrr.reference_force_N
        reference = {"reference_force_N": f_ref}
        if f_ref > s.force_limit_N:
            from ..machining.settings import DEFAULT_REFERENCE_FRACTION

            reference["force_limit_N"] = f_ref / DEFAULT_REFERENCE_FRACTION
    if (s.controller, s.compensation) == (controller, compensation) and not reference:
        return setup
    own = s.controller_settings
    s = replace(
        s,
        controller=controller,
        compensation=compensation,
        controller_settings=own if own is not None and own.kind == controller else None,
        **reference,
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
    from ._stages import require_learned

    rec = require_learned(project).recording
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
        assert setup.stock_profile_mm is not None  # MachiningSetup requires it for "profile"
        return stock_from_profile(
            p, setup.stock_profile_mm, wall_normals_m=normals, tool_radius_m=r
        )
    if setup.stock_source == "mesh":
        from pathlib import Path

        from ..part import mesh_from_bytes

        assert setup.stock_mesh is not None  # MachiningSetup requires it for "mesh"
        name, data = setup.stock_mesh
        mesh = mesh_from_bytes(data, Path(name).suffix.lower(), name=Path(name).stem).mesh
        mesh = mesh.copy()
        mesh.apply_transform(workpiece.T_base_wobj)
        return stock_from_mesh(mesh, p, normals, tool_radius_m=r)
    return builtin_stock(p, project.cell.seed, wall_normals_m=normals, tool_radius_m=r)


def compensation_model(project: Project, robot_name: str) -> Any:
    """The identified stiffness: the project's compensation settings when it holds some (on this
    robot), else the simulated CMM campaign of ``machining.stiffness_model``."""
    from ..cell import JointCompliance
    from ..machining import stiffness_model

    comp = project.compensation
    if comp is not None and comp.robot == robot_name:
        return JointCompliance(tuple(comp.joint_stiffness_Nm_rad))
    return stiffness_model(robot_name, machining_setup_of(project).settings)


def machine(
    project: Project,
    workpiece: Workpiece,
    robot: Robot,
    *,
    controllers: tuple[str, ...] | None = None,
    compensations: tuple[str, ...] | None = None,
    progress: Callable[[float], None] | None = None,
    cancel: Any = None,
    workers: int | None = 1,
    cluster: str | None = None,
) -> MachiningResult:
    """Cut the project's current program, one configuration or the matrix, on the stock and,
    with ``MachiningSetup.variations``, on that many stocks drawn from the part's variation.

    ``controllers`` / ``compensations`` None run the chosen one of the project's settings; give
    tuples for the matrix. ``workers`` local processes (None: every core, 1: this process) or
    a Dask ``cluster`` address run the cuts (``machining.parallel``); ``cancel`` (flag or
    callable) raises ``CancelledError``. The result is stamped with
    ``machining_inputs_key(project)``; store it with ``with_machining_result``.

    Raises:
        MissingResultError / StaleResultError: no current post-processed program.
    """
    from ..export.target_joints import with_target_joints
    from ..machining import COMPENSATION_NAMES, format_table
    from ..machining.choice import PEAK_MARGIN, choose, mark_runnable
    from ..machining.compare import comparison_rows
    from ..machining.parallel import CutTask, run_tasks
    from ..machining.variation import StockVariation, draw_stocks, variation_rows

    processed = require_processed(project)
    # The program the robot runs: each target's joints its inverse kinematics, as exported
    # (the recorded joints reach a point 0.1-0.25 mm off it), and a circular move's via
    # point at its move's speed.
    targets = with_move_speeds(with_target_joints(robot, processed.result.targets), processed.moves)
    setup = machining_setup_of(project)
    s = setup.settings
    normals = wall_normals_for_project(project, workpiece, targets)
    stock = build_stock(project, workpiece, targets, normals)
    ctrls = (s.controller,) if controllers is None else tuple(controllers)
    comps = (s.compensation,) if compensations is None else tuple(compensations)
    model = compensation_model(project, robot.name) if any(m != "off" for m in comps) else None
    # A controller's modes run in order in one task: offline rehearses from its off run.
    modes = tuple(m for m in COMPENSATION_NAMES if m in comps)  # off, offline, online
    if "offline" in modes and "off" not in modes:
        modes = ("off", *modes)
    pairs = [(c, m) for c in ctrls for m in comps]
    cancelled = _cancel_callable(cancel)
    drawn: list[Any] = []
    variation = None
    if setup.variations:
        spec = StockVariation()
        drawn = draw_stocks(stock, setup.variations, project.cell.seed, spec)
        variation = {
            "stocks": setup.variations + 1,
            "drawn": setup.variations,
            "seed": project.cell.seed,
            "ranges": spec.describe(),
            "program": "the nominal stock's: its design, constant feed and offline correction",
        }
    share = 1.0 / (1 + len(drawn))

    def task(st: Any, c: str, settings: Any, keep: bool, corrected: Any = None) -> Any:
        return CutTask(
            robot.name, robot.T_flange_tcp, targets, normals, st, settings, c, modes, model,
            keep_runs=keep, program_frame=workpiece.T_base_wobj, corrected=corrected,
        )  # fmt: skip

    def part(lo: float, hi: float) -> Callable[[float], None] | None:
        if progress is None:
            return None
        return lambda f: progress(lo + (hi - lo) * f)

    # The nominal stock: its runs design the program (constant feed, controllers, offline
    # correction) every drawn stock is then cut with, as one program meets every casting.
    first = run_tasks(
        [task(stock, c, s, True) for c in ctrls], workers=workers, cluster=cluster,
        progress=part(0.0, share), cancel=cancelled,
    )  # fmt: skip
    nominal = {(c, m): first[j][k] for j, c in enumerate(ctrls) for k, m in enumerate(modes)}
    runs = [nominal[p][0] for p in pairs if nominal[p][0] is not None]
    refused = {p: why for p in pairs if (why := nominal[p][2]) is not None}
    rows = comparison_rows(runs, refused=refused, order=pairs)
    rows = [
        _plain_row({**(nominal[p][1] or {}), **row}) for p, row in zip(pairs, rows, strict=True)
    ]
    if drawn:
        designed = replace(s, design_depth_m=stock.max_allowance_m)
        offline = {c: nominal[c, "offline"][0] for c in ctrls if (c, "offline") in nominal}
        corrected = {c: (run.program, run.nominal) for c, run in offline.items() if run is not None}
        later = run_tasks(
            [task(st, c, designed, False, corrected.get(c)) for st in drawn for c in ctrls],
            workers=workers, cluster=cluster, progress=part(share, 1.0), cancel=cancelled,
        )  # fmt: skip
        # later[i * len(ctrls) + j][k]: drawn stock i, controller j, mode k.
        summaries = [
            [nominal[p][1]]
            + [later[i * len(ctrls) + ctrls.index(p[0])][modes.index(p[1])][1]
               for i in range(len(drawn))]
            for p in pairs
        ]  # fmt: skip
        stats = variation_rows(
            summaries, pairs, force_limit_N=s.force_limit_N, peak_margin=PEAK_MARGIN
        )
        rows = [dict(row, **_plain_row(st)) for row, st in zip(rows, stats, strict=True)]
    elif progress is not None:
        progress(1.0)
    capabilities = capabilities_of(project)
    rows = mark_runnable(rows, capabilities)
    pick = choose(rows, capabilities)
    programs = {
        f"{r.controller}/{r.compensation}": r.program
        for r in runs
        if r.compensation == "offline" and r.program is not None
    }
    return MachiningResult(
        rows=tuple(rows),
        table_text=format_table(rows, chosen=pick.index),
        chosen=pick.index,
        programs=programs,
        runs=tuple(runs),
        stock=stock,
        inputs=machining_inputs_key(project),
        reason=pick.reason,
        capabilities=tuple(sorted(capabilities.options)),
        variation=variation,
    )


def _cancel_callable(cancel: Any) -> Callable[[], bool] | None:
    if cancel is None:
        return None
    is_set = getattr(cancel, "is_set", None)
    return is_set if callable(is_set) else cancel


def _plain_row(row: dict[str, Any]) -> dict[str, Any]:
    return {
        k: (float(v) if isinstance(v, (np.floating, np.integer)) else v) for k, v in row.items()
    }


def best_row(
    rows: tuple[dict[str, Any], ...] | list[dict[str, Any]], capabilities: Any = None
) -> int | None:
    """Index of the configuration to choose (``machining.choice.choose``; every configuration
    counts as runnable without ``capabilities``); None when none completed."""
    from ..machining.choice import OPTION_NAMES, CellCapabilities, choose

    caps = capabilities or CellCapabilities(frozenset(OPTION_NAMES))
    return choose(list(rows), caps).index


def with_machining_result(project: Project, result: MachiningResult) -> Project:
    """The project holding ``result`` (stamped with the key it was computed from)."""
    return replace(project, machining=result, machining_inputs=result.inputs)


def with_machining_setup(project: Project, setup: MachiningSetup) -> Project:
    """The project with new machining settings; the chosen configuration follows them into the
    CMRR and compensation slots (``choose``).

    Raises:
        MachiningSettingsError: a cell option the arm's controller cannot have (FC SpeedChange
            on a KUKA).
    """
    if setup.cell_options is not None:
        from ..machining.choice import check_options_for_arm

        robot = project.cell.robot
        check_options_for_arm(setup.cell_options, _arm_family(robot), robot)
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
    project = replace(project, machining_settings=setup)
    project = replace(project, cmrr=cmrr_for(s, designed=_designed_settings(project, controller)))
    comp = project.compensation
    mode = EXPORT_COMPENSATION_MODES[compensation]
    if compensation != "off" and (comp is None or comp.robot != project.cell.robot):
        from ..stiffness import CompensationSettings

        model = compensation_model(replace(project, compensation=None), project.cell.robot)
        stiffness = tuple(float(k) for k in model.stiffness_Nm_rad)
        comp = CompensationSettings(
            robot=project.cell.robot, joint_stiffness_Nm_rad=stiffness, mode="off"
        )
        setup = replace(setup, campaign_stiffness_Nm_rad=stiffness)
        project = replace(project, machining_settings=setup)
    if comp is not None:
        gravity = comp.tool_gravity
        if mode == "online" and gravity is None:
            # Not identified here: the tool's nominal mass and centre of mass, no sensor bias.
            from ..cell import ToolGravity

            tool = project.tool()
            gravity = ToolGravity.from_tool(tool)
        comp = replace(comp, mode=mode, tool_gravity=gravity)
    return replace(project, compensation=comp)


def _designed_settings(project: Project, controller: str) -> Any:
    """The controller's settings as the current machining result designed them for the cut
    (``machining.design``: e.g. the two-stage low stage), or None."""
    result = project.machining
    if not isinstance(result, MachiningResult) or project.status()["machining"] != "current":
        return None
    from ..cmrr.settings import controller_settings_from_dict

    for row in result.rows:
        doc = row.get("controller_settings")
        if row["controller"] == controller and doc:
            try:
                return controller_settings_from_dict(controller, doc)
            except InvalidInputError:
                return None
    return None


def cmrr_for(settings: Any, *, designed: Any = None) -> Any:
    """The CMRR settings of a machining configuration (None for constant feed): the same
    controller (as ``designed`` for the cut, when given), reference force, speed cap and
    minimum speed ratio the run used."""
    if settings.controller == "constant":
        return None
    from ..cmrr import CmrrSettings
    from ..cmrr.controllers import settings_for

    return CmrrSettings(
        controller=settings.controller_settings or designed or settings_for(settings.controller),
        reference_force_N=settings.reference_N,
        command_speed_m_s=settings.command_speed_cap_m_s,
        min_speed_ratio=settings.min_speed_ratio,
    )


def with_move_speeds(targets: Targets, moves: Any) -> Targets:
    """``targets`` with each circular move's via point at the speed of its move (the speed
    the MoveC / movec / CIRC is written with)."""
    if not moves:
        return targets
    speeds = np.array(targets.speed_m_s, dtype=float)
    for move in moves:
        if move.via is not None:
            speeds[move.via] = speeds[move.to]
    return replace(targets, speed_m_s=speeds)


def machining_targets(
    project: Project, targets: Targets, workpiece: Workpiece | None = None
) -> Targets | None:
    """``targets`` with the feeds the chosen machining configuration commands
    (``machining.program.machining_program``: the learned speeds capped at Vr, at the constant
    feed the stock allows for ``constant``, rounded down to 0.01 mm/s) and the positions as
    the files write them (``as_written``): the program the simulation cut; None when the
    project holds no machining settings."""
    if not isinstance(project.machining_settings, MachiningSetup):
        return None
    from ..machining.program import as_written, design_depth_m, machining_program

    s = machining_setup_of(project).settings
    targets = with_move_speeds(targets, require_processed(project).moves)
    if workpiece is None:
        from ._stages import build_workpiece

        workpiece = build_workpiece(project.cell, project.mesh)
    depth = s.design_depth_m
    if depth is None and s.controller == "constant" and s.constant_feed_m_s is None:
        processed = require_processed(project).result.targets
        normals = wall_normals_for_project(project, workpiece, processed)
        depth = build_stock(project, workpiece, processed, normals).max_allowance_m
    program = machining_program(targets, s, design_depth_m=design_depth_m(s, depth or 0.0))
    return as_written(program, workpiece.T_base_wobj)


def feed_note(project: Project, targets: Targets) -> str:
    """The header's line on the feeds the program commands."""
    s = machining_setup_of(project).settings
    v = np.asarray(targets.speed_m_s, dtype=float) / MM
    if s.controller == "constant":
        return (
            f"feeds as simulated: constant {v.max():.2f} mm/s (the greatest that keeps the "
            f"{s.force_limit_N:g} N limit at the stock's deepest cut), slower where learned"
            if v.min() < v.max()
            else f"feeds as simulated: constant {v.max():.2f} mm/s (the greatest that keeps "
            f"the {s.force_limit_N:g} N limit at the stock's deepest cut)"
        )
    return (
        f"feeds as simulated: programmed {v.min():.2f}-{v.max():.2f} mm/s (learned, at most "
        f"{s.command_speed_cap_m_s / MM:g} mm/s), scaled by the {s.controller} feed control "
        f"holding {s.reference_N:g} N"
    )


def ur_feed_loop(project: Project, workpiece: Workpiece, robot: Robot, targets: Targets) -> Any:
    """The feed loop a UR program runs for the chosen CMRR controller
    (``export.urscript_feed``): the controller as the simulation designed it for this program
    on this stock, its filter and the path acceleration; None for constant feed. Without
    machining settings, the defaults' (``machining_setup_of``) with the project's CMRR: a UR
    program of a project with CMRR settings said "CMRR: two-stage" in its header and ran plain
    moves at the learned feeds."""
    if project.cmrr is None and not isinstance(project.machining_settings, MachiningSetup):
        return None
    s = machining_setup_of(project).settings
    if s.controller == "constant":
        return None
    import copy

    from ..export.urscript_feed import UrFeedLoop
    from ..machining.run import FORCE_SUPERVISION_FACTOR, plan_cut

    processed = require_processed(project).result.targets
    normals = wall_normals_for_project(project, workpiece, processed)
    stock = build_stock(project, workpiece, processed, normals)
    designed = _designed_settings(project, s.controller)
    if s.controller_settings is None and designed is not None:
        s = replace(s, controller_settings=designed)
    plan = plan_cut(robot, targets, None, stock, replace(s, compensation="off"))
    if plan.packed is NotImplemented:
        return None
    i = plan.inputs
    return UrFeedLoop(
        controller=s.controller,
        reference_N=s.reference_N,
        packed=copy.deepcopy(plan.packed),
        filter_sos=tuple(float(v) for v in i.filt),
        filter_z0=(float(i.filt_z[0]), float(i.filt_z[1])),
        dt_s=i.dt,
        acceleration_m_s2=s.path_acceleration_m_s2,
        force_limit_N=s.force_limit_N,
        supervision_factor=FORCE_SUPERVISION_FACTOR,
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
        f"deflection compensation: offline, planned from rehearsals of the {s.controller} cut "
        f"on the stock, {len(program)} targets from {len(nominal)}"
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
        "cell_options": None if setup.cell_options is None else list(setup.cell_options),
        "variations": setup.variations,
        "campaign_stiffness_Nm_rad": None
        if setup.campaign_stiffness_Nm_rad is None
        else list(setup.campaign_stiffness_Nm_rad),
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
    options = doc.get("cell_options")
    return MachiningSetup(
        settings,
        source,
        None if profile is None else tuple((float(a), float(b)) for a, b in profile),
        mesh if source == "mesh" else None,
        cell_options=None if options is None else tuple(str(o) for o in options),
        variations=int(doc.get("variations") or 0),
        campaign_stiffness_Nm_rad=None
        if doc.get("campaign_stiffness_Nm_rad") is None
        else tuple(float(k) for k in doc["campaign_stiffness_Nm_rad"]),
    )


def machining_result_document(result: MachiningResult) -> dict[str, Any]:
    """JSON form of a result: rows, table, choice, inputs and the offline programs."""
    return {
        "rows": list(result.rows),
        "table_text": result.table_text,
        "chosen": result.chosen,
        "inputs": result.inputs,
        "programs": {k: _targets_doc(t) for k, t in result.programs.items()},
        "reason": result.reason,
        "capabilities": list(result.capabilities),
        "variation": result.variation,
    }


def machining_result_from_document(doc: dict[str, Any]) -> MachiningResult:
    chosen = doc.get("chosen")
    return MachiningResult(
        rows=tuple(doc["rows"]),
        table_text=str(doc["table_text"]),
        chosen=None if chosen is None else int(chosen),
        programs={k: _targets_from(v) for k, v in (doc.get("programs") or {}).items()},
        inputs=str(doc["inputs"]),
        reason=str(doc.get("reason") or ""),
        capabilities=tuple(doc.get("capabilities") or ()),
        variation=doc.get("variation"),
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


# --- what the program needs from the cell, and settings of another arm ---------------------


def machining_note(project: Project) -> str | None:
    """The program header's line on the chosen configuration: what it needs from the cell
    and whether the cell (``capabilities_of``) has it; None without machining settings."""
    from ..machining.choice import missing, needs_text, requirements

    if not isinstance(project.machining_settings, MachiningSetup):
        return None
    s = machining_setup_of(project).settings
    caps = capabilities_of(project)
    needs = requirements(s.controller, s.compensation)
    lacks = set(missing(s.controller, s.compensation, caps))
    head = f"machining: {s.controller} / {s.compensation}"
    if not needs:
        return f"{head}; needs nothing from the cell beyond this program"
    parts = []
    for r in needs:
        if r in lacks:
            parts.append(f"{needs_text(r, caps)} (MISSING in this cell)")
        elif r == "feed_override" and caps.family in FEED_OVERRIDE_MEANS:
            means = FEED_OVERRIDE_MEANS[caps.family]
            parts.append(f"a force-driven feed override: {means} (the cell has it)")
        else:
            parts.append(f"{needs_text(r, caps)} (the cell has it)")
    return f"{head}; the cell must provide " + " and ".join(parts)


def with_runnable_choice(project: Project) -> tuple[Project, str]:
    """The project whose machining choice its cell can run: a part of the chosen
    configuration the cell's controller lacks (after a cell change: a UR10's force-mode feed
    control in a KUKA cell) goes back to the neutral one (constant feed, no compensation),
    and a sentence says what was cleared and why ("" when nothing was). A program never
    carries a choice its controller cannot run (issue 31: the KRL header said "MISSING in
    this cell")."""
    from ..machining.choice import REQUIREMENT_TEXT, missing

    if project.cmrr is None and project.compensation is None:
        return project, ""  # the neutral choice: nothing to clear
    s = machining_setup_of(project).settings
    caps = capabilities_of(project)
    lacks = missing(s.controller, s.compensation, caps)
    if not lacks:
        return project, ""
    controller = "constant" if "feed_override" in lacks else s.controller
    compensation = "off" if "online_correction" in lacks else s.compensation
    cleared = choose(project, controller, compensation)
    why = " and ".join(REQUIREMENT_TEXT[r] for r in lacks)
    return cleared, (
        f"The machining choice {s.controller} / {s.compensation} needs {why}, which the "
        f"{project.cell.robot}'s controller does not have here, so it is now {controller} / "
        f"{compensation}. Compare the configurations again to choose among those it can run."
    )


# How each family's program carries the force-driven feed override.
FEED_OVERRIDE_MEANS = {
    "abb": "FC SpeedChange (FCSpdChgAct in the RAPID module)",
    "ur": "the URScript program runs its own loop on the UR's force/torque sensor (the RAPID "
    "module carries FC SpeedChange for an ABB controller)",
}


def stale_settings(project: Project) -> dict[str, str]:
    """Settings that belong to another arm than the cell's, with a sentence each: they are
    re-derived for the cell's arm when the program is exported, not a reason to refuse it."""
    comp = project.compensation
    if comp is not None and comp.robot != project.cell.robot:
        return {
            "compensation": (
                f"the compensation's joint stiffness was identified on {comp.robot}; the "
                f"export re-derives it for {project.cell.robot} (simulated CMM campaign)"
            )
        }
    return {}


def compensation_for_arm(project: Project, robot_name: str) -> Any:
    """The project's compensation settings for ``robot_name``: as they are when identified on
    it, else re-derived (the simulated CMM campaign's stiffness, the same mode and tool)."""
    comp = project.compensation
    if comp is None or comp.robot == robot_name:
        return comp
    model = compensation_model(replace(project, compensation=None), robot_name)
    return replace(
        comp,
        robot=robot_name,
        joint_stiffness_Nm_rad=tuple(float(k) for k in model.stiffness_Nm_rad),
    )
