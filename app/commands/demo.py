"""``robomach demo``: the whole programming-by-demonstration pipeline, headless."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.commands.progress import StageProgress
from robomach_core import limits

if TYPE_CHECKING:
    from robomach_core.project import Project


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "demo",
        help="run lead-through, path learning, post-processing and program export headless",
        description=(
            "Lead the simulated robot to guide points around the workpiece by virtual pushes, "
            "learn the contour at constant contact force, filter and reduce the recording, and "
            "write the program in the arm's language (program.mod for ABB and UR arms, "
            "program.script for UR arms, program.src/.dat for KUKA arms), samples.csv, "
            "targets.csv, workpiece.stl, summary.json and demo.png into --out."
        ),
    )
    p.add_argument("--out", required=True, type=Path, help="output folder (created if missing)")
    from robomach_core.robots.registry import BUILTIN_NAMES as ROBOT_NAMES  # not the cell's

    p.add_argument(
        "--robot",
        default=None,
        metavar="|".join(ROBOT_NAMES) + "|FILE.urdf",
        help="the arm: a built-in one, or your own serial 6-axis URDF file (default ur10; with "
        "--language, that language's arm: irb4400 for rapid, kr270 for krl)",
    )
    from robomach_core.export.languages import language_choices, languages

    by_family = "; ".join(
        f"{lang.name}: {'/'.join(lang.file_names())} for {', '.join(lang.families)} arms"
        for lang in languages()
    )
    p.add_argument(
        "--language",
        choices=language_choices(),
        default="auto",
        help="program language: auto writes every language the arm's controller is offered "
        f"({by_family}); a language the arm's controller does not run is refused",
    )
    p.add_argument(
        "--arcs",
        action="store_true",
        help="fit circular moves (MoveC / movec) where the contour is an arc within tolerance",
    )
    p.add_argument(
        "--arc-tolerance",
        type=float,
        default=None,
        metavar="MM",
        help="largest distance of a sample from its line or arc with --arcs (default: --tolerance)",
    )
    p.add_argument(
        "--open",
        action="store_true",
        help="the contour is open (a groove or an edge that ends): no move back to the first "
        "guide point",
    )
    p.add_argument(
        "--tool-radius-mm",
        type=float,
        default=limits.TOOL_RADIUS_MM.default,
        metavar="MM",
        help="ball cutter radius in mm (default %(default)g)",
    )
    p.add_argument("--workpiece", default="water_pump", help="water_pump (default) or block")
    p.add_argument(
        "--wobj",
        metavar="X,Y,Z[,RZ|,RX,RY,RZ]",
        help="work-object frame placing the workpiece and the program's wobjdata: x,y,z in mm "
        "(robot base frame) and an optional rotation about z, or rotations about the base x, "
        "y and z axes in that order, in degrees (default: in front of the arm, 800,160,0 for "
        "a UR10)",
    )
    p.add_argument(
        "--force",
        type=float,
        default=limits.LEARNING_FORCE_N.default,
        metavar="N",
        help="contact force reference in N (1-50, default %(default)g; the paper used 10-20); "
        "the post-processing "
        "filter keeps samples at 5-15 N, or at 0.5-1.5 times the force where that band would "
        "not hold it (as the workbench)",
    )
    p.add_argument(
        "--speed",
        type=float,
        default=limits.LEARNING_SPEED_MM_S.default,
        metavar="MM_S",
        help="learning speed in mm/s (default %(default)g)",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=limits.TOLERANCE_MM.default,
        metavar="MM",
        help="deviation-height tolerance in mm (default %(default)g)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of every random element")
    p.add_argument(
        "--guide-points",
        type=Path,
        metavar="CSV",
        help="lead the robot to these guide points instead of the built-in plan: rows "
        "x_mm,y_mm,z_mm[,qw,qx,qy,qz[,wall_nx,wall_ny,wall_nz]] in the robot base "
        "frame (needed for a mesh file); the optional wall direction points from the tool "
        "into the wall (where to push lightly to feel it), see docs/guide_points.md",
    )
    from robomach_core.learning.settings import WALL_SIDE_CHOICES

    p.add_argument(
        "--propose-guide-points",
        metavar="X,Y,Z",
        help="propose the guide points along the wall through this point (on the wall, in the "
        "work-object frame, mm, as a click in the workbench gives it: -12.5,3,4 or -12.5 3 4 "
        "or '(-12.5, 3, 4)') and lead the robot to "
        "them: no CSV needed, for a mesh file too; the wall decides open or closed and the "
        "wall side",
    )
    p.add_argument(
        "--gap-mm",
        type=float,
        default=limits.WALL_GAP_MM.default,
        metavar="MM",
        help="with --propose-guide-points: gap between the cutter and the wall (default "
        "%(default)g)",
    )
    p.add_argument(
        "--realistic",
        action="store_true",
        help="the realistic preset: the part in the cell differs from its mesh by a fixture "
        "error (2-4 mm, 1-2 deg) and casting deviations (walls within +-0.5 mm, burrs), "
        "drawn from --seed; teaching uses the mesh, learning meets the real part, and the "
        "program a CAD/CAM tool would make from the mesh is scored beside the learned one "
        "(add --calibrate: points taught on a CAD a few mm off land on a groove's rim)",
    )
    p.add_argument(
        "--calibrate",
        action="store_true",
        help="before teaching, measure the work object on the real part: the operator touches "
        "its top face three times and two sides three and two times (guarded touch-offs at "
        "--force, at least 2 N), the CAD is registered to the touches by a point-to-plane "
        "least-squares fit (its residual printed), and the guide points, the checks, the "
        "CAD-only program and the program's work object use the registered CAD",
    )
    p.add_argument(
        "--wall-side",
        choices=WALL_SIDE_CHOICES,
        default="auto",
        help="side of the wall to follow, left or right of the direction of travel looking "
        "along the tool into the part; auto (default) decides from a clear push against the "
        "wall at the guide points or from the part's mesh, and refuses when neither tells",
    )
    p.add_argument(
        "--cmrr-settings",
        type=Path,
        metavar="JSON",
        help="cmrr_settings.json from `robomach cmrr`: wrap the machining moves in an "
        "FC SpeedChange block with that controller's reference and speed stages",
    )
    p.add_argument(
        "--compensation-settings",
        type=Path,
        metavar="JSON",
        help="compensation_settings.json from `robomach compensate`: in the offline "
        "modes, correct every target for the contact wrench learned at it",
    )
    p.add_argument("--no-plot", action="store_true", help="skip demo.png")
    p.set_defaults(func=run)


def _point_mm(text: str, option: str) -> tuple[float, float, float]:
    """A point x,y,z in mm (work-object frame) as metres, each inside the work-object range."""
    from app.cli import number_parts
    from robomach_core.errors import InvalidInputError

    values = tuple(float(v) for v in number_parts(text))
    if not values:
        raise InvalidInputError(f"{option} {text!r}: expected three numbers x,y,z in mm")
    if len(values) != 3:
        raise InvalidInputError(
            f"{option} {text!r}: expected three numbers x,y,z in mm, got {len(values)}"
        )
    for v in values:
        limits.WOBJ_POSITION_MM.check(v, option)
    return values[0] * 1e-3, values[1] * 1e-3, values[2] * 1e-3


# A guide-point file holds at most ``limits.GUIDE_POINTS_MAX`` rows of ten numbers: a few kB.
MAX_GUIDE_POINTS_FILE_BYTES = 1_000_000


def read_guide_points_file(path: Path) -> str:
    """The text of a ``--guide-points`` file once it holds at most ``GUIDE_POINTS_MAX`` points
    (rows that are neither blank, a comment, nor a first-line header), checked before any
    work: the cap was met after a 3-minute lead-through (a million-row file ran 185 s with
    no output; issue 32)."""
    from robomach_core.errors import InvalidInputError
    from robomach_core.limits import GUIDE_POINTS_MAX

    if not path.is_file():
        raise InvalidInputError(f"--guide-points {path}: no such file")
    size = path.stat().st_size
    if size > MAX_GUIDE_POINTS_FILE_BYTES:
        raise InvalidInputError(
            f"--guide-points {path}: {size / 1e6:.1f} MB is not a guide-point file (at most "
            f"{GUIDE_POINTS_MAX} points, a few kB)"
        )
    text = path.read_text(errors="replace")
    rows = [
        line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")
    ]
    if rows and rows[0].lstrip()[:1] not in set("0123456789+-."):
        rows = rows[1:]  # a header
    if len(rows) > GUIDE_POINTS_MAX:
        raise InvalidInputError(
            f"--guide-points {path}: {len(rows)} points, more than the {GUIDE_POINTS_MAX} a "
            "project holds"
        )
    return text


def run(args: argparse.Namespace) -> int:
    from app.cli import settings_file, writable_folder
    from robomach_core.errors import InvalidInputError

    limits.TOLERANCE_MM.check(args.tolerance, "--tolerance")
    limits.LEARNING_FORCE_N.check(args.force, "--force")
    limits.LEARNING_SPEED_MM_S.check(args.speed, "--speed")
    limits.SEED.check(args.seed, "--seed")
    limits.TOOL_RADIUS_MM.check(args.tool_radius_mm, "--tool-radius-mm")
    if args.arc_tolerance is not None:
        limits.TOLERANCE_MM.check(args.arc_tolerance, "--arc-tolerance")
    writable_folder(args.out)

    wobj = None
    if args.wobj is not None:
        from app.cli import number_parts

        wobj = tuple(float(v) for v in number_parts(args.wobj))
        if not wobj:
            raise InvalidInputError(
                f"--wobj {args.wobj!r}: expected numbers x,y,z[,rz] or x,y,z,rx,ry,rz"
            )
        if len(wobj) not in (3, 4, 6):
            raise InvalidInputError(
                f"--wobj {args.wobj!r}: expected 3, 4 or 6 numbers (x,y,z[,rz] or "
                f"x,y,z,rx,ry,rz), got {len(wobj)}"
            )
        ranges = (limits.WOBJ_POSITION_MM,) * 3 + (limits.WOBJ_ROTATION_DEG,) * 3
        for value, rng in zip(wobj, ranges, strict=False):
            rng.check(value, "--wobj")
    propose_at = None
    if args.propose_guide_points is not None:
        if args.guide_points is not None:
            raise InvalidInputError("give --guide-points or --propose-guide-points, not both")
        propose_at = _point_mm(args.propose_guide_points, "--propose-guide-points")
    limits.WALL_GAP_MM.check(args.gap_mm, "--gap-mm")
    guide_csv = None
    if args.guide_points is not None:
        guide_csv = read_guide_points_file(args.guide_points)

    cmrr = compensation = None
    if args.cmrr_settings is not None:
        from robomach_core.cmrr import load_settings as load_cmrr

        cmrr = load_cmrr(settings_file(args.cmrr_settings, "--cmrr-settings"))
    if args.compensation_settings is not None:
        from robomach_core.stiffness import load_settings as load_compensation

        compensation = load_compensation(
            settings_file(args.compensation_settings, "--compensation-settings")
        )

    from robomach_core.errors import RobomachError, SupervisionError
    from robomach_core.export.languages import default_arm
    from robomach_core.learning.settings import PathLearningSettings
    from robomach_core.pipeline import run_demo, write_demo_outputs
    from robomach_core.teaching.pointing import ProposalSettings

    robot = args.robot or default_arm(args.language)
    project = _project(args, robot, wobj, cmrr, compensation)
    robot = project.cell.robot  # a URDF file's: the name it is registered under
    learning = PathLearningSettings(
        force_N=args.force,
        speed_m_s=args.speed * 1e-3,
        wall_side=args.wall_side,
        closed=not args.open,
    )
    bar = StageProgress()

    def checked(findings: tuple) -> None:
        """The guide-point check, printed before the run starts (as the workbench shows it)."""
        from app.findings import grouped_findings

        bar.close()
        lines = [f"{g.severity}: {g.text()}" for g in grouped_findings(findings)]
        for line in lines or ["the guide points pass every rule"]:
            print(f"check             {line}", flush=True)
        bar.stage = None

    try:
        result = run_demo(
            project,
            learning,
            guide_points_csv=guide_csv,
            propose_at_m=propose_at,
            proposal_settings=ProposalSettings(gap_m=args.gap_mm * 1e-3),
            touch_force_N=max(args.force, limits.TOUCH_OFF_FORCE_N.min) if args.calibrate else None,
            language=args.language,
            progress=bar,
            checked=checked,
        )
    except SupervisionError as exc:
        where = "" if args.wobj is not None else " (now the built-in placement)"
        raise exc.with_cause_note(robot, place=f"--wobj x,y,z (mm){where}") from None
    except RobomachError as exc:
        if args.realistic and not args.calibrate:  # the likely cause, which the user chose
            exc.args = (
                f"{exc}. The part stands a few mm and a degree or two off its CAD "
                "(--realistic), so points taught on the CAD miss its walls: measure the work "
                "object on the part first (--calibrate)",
            )
        raise
    finally:
        bar.close()
    paths = write_demo_outputs(result, args.out)
    if not args.no_plot:
        from robomach_core.plots import demo_figure

        paths.append(demo_figure(result, args.out / "demo.png"))
    s = result.summary()
    if result.workpiece.deviation_note:
        print(f"real part         {result.workpiece.deviation_note}")
    if result.calibration is not None:
        print(f"calibration       {result.calibration.describe()}")
    proposed = s.get("proposed_guide_points")
    if proposed is not None:
        shape = "a closed" if proposed["closed"] else "an open"
        print(
            f"proposed          {proposed['points']} guide points along {shape} wall of "
            f"{proposed['wall_length_mm']:.0f} mm, {proposed['height_above_floor_mm']:.1f} mm "
            f"above the floor (z = {proposed['height_wobj_mm']:.1f} mm at G1, work object), "
            f"wall side {proposed['wall_side']}"
        )
        for note in proposed["notes"]:  # a changed height, an open wall, a centred tool
            print(f"                  {note}")
    print(f"guide points      {s['guide_points']}")
    print(
        f"samples           {s['samples_raw']} raw, {s['samples_filtered']} kept "
        f"(force in [{s['force_min_N']:g}, {s['force_max_N']:g}] N)"
    )
    print(
        f"contact force     mean {s['force_mean_N']:.2f} N, |error| p95 "
        f"{s['force_abs_error_p95_N']:.2f} N, within 2 N: {s['force_within_2N_fraction']:.1%}"
    )
    print(f"targets           {s['targets']} (tolerance {s['tolerance_mm']:g} mm)")
    if s["max_deviation_mm"] is not None:
        elsewhere = s["max_deviation_mm"] > 1.0 and s.get("wall_side_source") == "setting"
        print(
            f"deviation         max {s['max_deviation_mm']:.3f} mm, RMS "
            f"{s['rms_deviation_mm']:.3f} mm (path vs true wall - tool radius)"
            + (
                f": the program follows another wall, the one on the {s['wall_side']} as set"
                if elsewhere
                else ""
            )
        )
    if s.get("arcs"):
        print(
            f"moves             {s['moves']} ({s['circular_moves']} circular) vs "
            f"{s['straight_moves']} straight: {s['moves'] / s['straight_moves']:.0%}"
        )
    if s.get("mesh_max_deviation_mm") is not None:
        print(
            f"mesh deviation    max {s['mesh_max_deviation_mm']:.3f} mm, RMS "
            f"{s['mesh_rms_deviation_mm']:.3f} mm, overcut {s['mesh_overcut_mm']:.3f} mm, air "
            f"{s['mesh_air_mm']:.3f} mm (program vs the part's walls - tool radius)"
        )
    print(f"wall              on the {s['wall_side']} of travel: {s['wall_side_reason']}")
    if s.get("taught_wall"):
        print(f"taught wall       {s['taught_wall']}")
    comparison = s.get("cad_comparison")
    if comparison is not None:
        title = "vs the real wall" if comparison["part_deviates_from_cad"] else "vs the wall"
        rows = [("learned program", "learned"), ("CAD-only program", "cad_only")]
        if comparison.get("cad_only_uncalibrated") is not None:
            rows.append(("CAD-only, uncal.", "cad_only_uncalibrated"))
        for label, key in rows:
            c = comparison[key]
            x, y, _ = c["worst_at_wobj_mm"]
            print(
                f"{title if key == 'learned' else '':<18}{label:<17} max "
                f"{c['max_deviation_mm']:.3f} mm, RMS {c['rms_deviation_mm']:.3f} mm, overcut "
                f"{c['overcut_mm']:.3f} mm, air {c['air_mm']:.3f} mm; worst at ({x:.1f}, "
                f"{y:.1f}) mm, {c['worst_at_fraction']:.0%} along"
            )
    print(
        f"reachable         {s['robtargets_reachable']}/{s['robtargets_total']} program targets "
        f"({s['program_language']})"
    )
    print(
        f"run               {s['stop_reason']}; {s['sim_time_s']:.1f} s simulated in "
        f"{s['learning_wall_time_s']:.1f} s (x{s['realtime_factor']:.0f} real time)"
    )
    out = Path(args.out)
    names = [p.relative_to(out).as_posix() if p.is_relative_to(out) else p.name for p in paths]
    print(f"wrote             {', '.join(names)} in {args.out}")
    for problem in s.get("problems") or ():
        print(f"NOT FIT TO MACHINE: {problem}", file=sys.stderr)
    return 0 if result.recording.completed and not s.get("problems") else 1


def _project(
    args: argparse.Namespace, robot: str, wobj: tuple | None, cmrr: Any, compensation: Any
) -> Project:
    """The job the flags describe, built by the project's transitions as the workbench builds
    it (an uploaded arm, an uploaded mesh, the cell, the process settings); its settings are
    the project's own (``CellSettings``, ``PostprocessSettings``), each flag onto one."""
    from robomach_core import project as core
    from robomach_core.cell import Robot
    from robomach_core.export.languages import resolve_languages
    from robomach_core.part import PartDeviation
    from robomach_core.pipeline import read_mesh_file

    project = core.Project()
    if robot.lower().endswith(".urdf"):
        from robomach_core.robots.custom import read_robot_file, register_urdf

        filename, data = read_robot_file(Path(robot))
        project = core.with_robot_file(project, filename, data, register_urdf(filename, data))
        robot = project.cell.robot
    # A language the arm's controller does not run is refused now, not after learning.
    resolve_languages(Robot(robot), args.language)
    mesh = Path(args.workpiece)
    if mesh.suffix:
        from robomach_core.part import mesh_from_bytes

        filename, data = read_mesh_file(mesh)
        name = core.mesh_file_name(filename)
        # parsed and checked first, as an upload is (a flat or broken file says so here)
        mesh_from_bytes(data, Path(name).suffix, name=Path(name).stem)
        project = core.with_uploaded_mesh(project, filename, data)
    project = core.with_cell(
        project,
        robot=robot,
        workpiece=None if mesh.suffix else args.workpiece,
        tool_radius_m=args.tool_radius_mm * 1e-3,
        wobj_mm_deg=wobj,
        part_deviation=PartDeviation.realistic(args.seed) if args.realistic else None,
        seed=args.seed,
    )
    post = core.post_settings_with(
        project,
        tolerance_m=args.tolerance * 1e-3,
        arcs=args.arcs,
        arc_tolerance_m=None if args.arc_tolerance is None else args.arc_tolerance * 1e-3,
    )
    return core.with_process_settings(replace(project, post_settings=post), cmrr, compensation)
