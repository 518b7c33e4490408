"""The machining stage's cut: the project's program on its stock, one configuration or the matrix.

``machine`` cuts the post-processed targets (each at its inverse kinematics, as exported) along
the stock (``build_stock``: built-in, a profile or a mesh) with the wall normals of the part
(``wall_normals_for_project``), on the local cores or a Dask cluster
(``machining.parallel``), and, with a variation sweep, on stocks drawn from the part's
variation; the rows and the rule's pick become a ``MachiningResult`` (``_machining``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from ..cell import Robot
from ..part import Workpiece
from ..postprocess import Targets
from ._machining import (
    MachiningResult,
    capabilities_of,
    compensation_model,
    machining_setup_of,
)
from ._stages import require_processed
from ._value import Project, machining_inputs_key


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
    from ..machining.compare import comparison_rows
    from ..machining.parallel import CutTask, run_tasks
    from ..machining.schedule import STAGED_CONTROLLERS
    from ..stiffness.modes import COMPENSATIONS

    targets = _program_cut(project, robot)
    setup = machining_setup_of(project)
    s = setup.settings
    normals = wall_normals_for_project(project, workpiece, targets)
    stock = build_stock(project, workpiece, targets, normals)
    ctrls = (s.controller,) if controllers is None else tuple(controllers)
    comps = (s.compensation,) if compensations is None else tuple(compensations)
    model = compensation_model(project, robot.name) if any(m != "off" for m in comps) else None
    # A controller's modes run in order in one task: offline rehearses from its off run.
    modes: tuple[str, ...] = tuple(m for m in COMPENSATIONS if m in comps)  # off, offline, online
    if "offline" in modes and "off" not in modes:
        modes = ("off", *modes)
    pairs = [(c, m) for c in ctrls for m in comps]
    cancelled = _cancel_callable(cancel)
    drawn, variation = _drawn_stocks(stock, setup.variations, project.cell.seed)
    share = 1.0 / (1 + len(drawn))

    def task(
        st: Any, c: str, settings: Any, keep: bool, corrected: Any = None, only: Any = None
    ) -> Any:
        return CutTask(
            robot.name, robot.T_flange_tcp, targets, normals, st, settings, c, only or modes,
            model, keep_runs=keep, program_frame=workpiece.T_base_wobj, corrected=corrected,
        )  # fmt: skip

    def part(lo: float, hi: float) -> Callable[[float], None] | None:
        if progress is None:
            return None
        return lambda f: progress(lo + (hi - lo) * f)

    # The nominal stock: its runs design the program (constant feed, controllers, offline
    # correction) every drawn stock is then cut with, as one program meets every casting.
    # With offline compensation in the matrix, the staged controllers' offline rows are cut
    # with the other stage plan too (``MachiningSettings.stages``): the table says what it
    # gives on this stock.
    other = "planned" if s.stages == "online" else "online"
    staged = [c for c in ctrls if c in STAGED_CONTROLLERS] if len(pairs) > 1 else []
    staged = staged if "offline" in comps else []
    first = run_tasks(
        [task(stock, c, s, True) for c in ctrls]
        + [task(stock, c, replace(s, stages=other), False, only=("offline",)) for c in staged],
        workers=workers, cluster=cluster, progress=part(0.0, share), cancel=cancelled,
    )  # fmt: skip
    first, alternatives = first[: len(ctrls)], dict(zip(staged, first[len(ctrls) :], strict=True))
    nominal = {(c, m): first[j][k] for j, c in enumerate(ctrls) for k, m in enumerate(modes)}
    runs = [nominal[p][0] for p in pairs if nominal[p][0] is not None]
    refused = {p: why for p in pairs if (why := nominal[p][2]) is not None}
    rows = comparison_rows(runs, refused=refused, order=pairs)
    rows = [
        _plain_row({**(nominal[p][1] or {}), **row}) for p, row in zip(pairs, rows, strict=True)
    ]
    for p, row in zip(pairs, rows, strict=True):
        if p[1] == "offline" and p[0] in alternatives:
            row["other_stages"] = _other_stages(other, alternatives[p[0]][0])
    if drawn:
        designed = replace(s, design_depth_m=stock.max_allowance_m)
        offline = {c: nominal[c, "offline"][0] for c in ctrls if (c, "offline") in nominal}
        corrected = {
            c: (run.program, run.nominal, run.summary.get("feed", "controller"))
            for c, run in offline.items()
            if run is not None
        }
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
        rows = _with_percentiles(rows, summaries, pairs, s)
    elif progress is not None:
        progress(1.0)
    return _machining_result(project, rows, runs, stock, variation)


def _other_stages(stages: str, cut: tuple[Any, dict[str, Any] | None, str | None]) -> dict:
    """What an offline row cut with the other stage plan (``stages``): its cycle, peak and
    wall, or that it stopped or was refused."""
    _, summary, refused = cut
    out: dict[str, Any] = {"stages": stages, "completed": False, "refused": refused}
    if summary is not None:
        out |= {
            "completed": bool(summary["completed"]),
            "feed": summary.get("feed", "controller"),
        }
        for key in ("cycle_time_s", "force_peak_N", "wall_error_max_mm"):
            value = summary.get(key)
            out[key] = None if value is None else float(value)
    return out


def _program_cut(project: Project, robot: Robot) -> Targets:
    """The program the robot runs: each post-processed target's joints its inverse kinematics,
    as exported (the recorded joints reach a point 0.1-0.25 mm off it), and a circular move's
    via point at its move's speed."""
    from ..export.target_joints import with_target_joints

    processed = require_processed(project)
    return with_move_speeds(with_target_joints(robot, processed.result.targets), processed.moves)


def _drawn_stocks(stock: Any, variations: int, seed: int) -> tuple[list[Any], dict | None]:
    """``variations`` stocks drawn from the part's variation around ``stock``
    (``machining.variation``, seeded by the project's ``seed``) and the sweep's description
    for the result; none and None without a sweep."""
    if not variations:
        return [], None
    from ..machining.variation import StockVariation, draw_stocks

    spec = StockVariation()
    drawn = draw_stocks(stock, variations, seed, spec)
    return drawn, {
        "stocks": variations + 1,
        "drawn": variations,
        "seed": seed,
        "ranges": spec.describe(),
        "program": "the nominal stock's: its design, constant feed and offline correction",
    }


def _with_percentiles(
    rows: list[dict[str, Any]],
    summaries: list[list[Any]],
    pairs: list[tuple[str, str]],
    settings: Any,
) -> list[dict[str, Any]]:
    """The rows with each configuration's figures over the nominal and the drawn stocks
    (``machining.variation.variation_rows``: p50 / p95, and whether every stock completed
    within the force limit); ``summaries[i]`` the run summaries of ``pairs[i]``, nominal
    first."""
    from ..machining.choice import PEAK_MARGIN
    from ..machining.variation import variation_rows

    stats = variation_rows(
        summaries, pairs, force_limit_N=settings.force_limit_N, peak_margin=PEAK_MARGIN
    )
    return [dict(row, **_plain_row(st)) for row, st in zip(rows, stats, strict=True)]


def _machining_result(
    project: Project,
    rows: list[dict[str, Any]],
    runs: list[Any],
    stock: Any,
    variation: dict | None,
) -> MachiningResult:
    """The result: the rows marked for the cell's options (``capabilities_of``), the rule's
    pick among them (``machining.choice.choose``), the offline runs' corrected programs, and
    the stamp of the project's inputs."""
    from ..machining import format_table
    from ..machining.choice import choose, mark_runnable

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
