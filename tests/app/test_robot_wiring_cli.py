"""``robomach demo`` with the arm, language, arcs, open contours and mesh score (issue 11).

The tests that run a whole demo are slow; the refusals of bad arguments are not."""

from __future__ import annotations

import csv
import io
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from robomach_core.cell import Robot, Tool
from robomach_core.export import check_rapid_module
from robomach_core.export.rapid import confdata_from_joints
from robomach_core.export.urscript import script_poses
from robomach_core.part import builtin_workpiece
from robomach_core.teaching import guide_plan
from robomach_core.transforms import make_transform
from tests.cli import robomach_here
from tests.demo_project import arm_demo, pump_demo
from tests.rapid_grammar import rapidchecker_errors


def demo(out: Path, *args: str) -> tuple[dict, subprocess.CompletedProcess]:
    """``robomach demo`` in this process; the shared demos (tests/demo_project.py) run it as a
    process of its own."""
    proc = robomach_here("demo", "--out", str(out), "--no-plot", *args)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads((out / "summary.json").read_text()), proc


def targets_rows(out: Path) -> list[dict]:
    return list(csv.DictReader(io.StringIO((out / "targets.csv").read_text())))


def joints_of(row: dict) -> np.ndarray:
    return np.radians([float(row[f"joint{i}_deg"]) for i in range(1, 7)])


@pytest.fixture(scope="module")
def irb4400():
    """The pump demo on the IRB 4400 (``robomach demo --robot irb4400``), shared with
    tests/core/machining/test_read_back.py: read, never written."""
    run = arm_demo("irb4400")
    return run.folder, run.summary


@pytest.fixture(scope="module")
def ur10():
    """The README's demo (the UR10 is the default arm), shared with tests/app/test_demo_cli.py."""
    run = pump_demo()
    assert run.summary["robot"] == "ur10"
    return run.folder, run.summary, run


@pytest.mark.slow
def test_irb4400_meets_the_ur10_quality_figures(irb4400):
    out, s = irb4400
    assert s["robot"] == "irb4400"
    assert s["completed"]
    assert s["max_deviation_mm"] <= 0.3
    assert s["rms_deviation_mm"] <= 0.15
    assert s["robtargets_reachable"] == s["robtargets_total"] > 100
    assert s["mesh_max_deviation_mm"] <= 0.3
    assert s["program_language"] == "rapid"
    assert not (out / "program.script").exists()


@pytest.mark.slow
def test_irb4400_confdata_agrees_with_the_ik_joints_and_rapidchecker_passes(irb4400):
    out, _ = irb4400
    robot = Robot("irb4400", Tool().T_flange_tcp)
    rows = targets_rows(out)
    for name in ("program.mod", "program_fc.mod"):
        text = (out / name).read_text()
        assert rapidchecker_errors(text) == []
        info = check_rapid_module(text)
        confs = [conf for pos, quat, conf in info.robtargets.values()]
        assert len(confs) >= len(rows)
    info = check_rapid_module((out / "program.mod").read_text())
    targets = {k: v for k, v in info.robtargets.items() if k.startswith("p")}
    for k, row in enumerate(rows, start=1):
        q = joints_of(row)
        _, _, conf = targets[f"p{k}"]
        expected = confdata_from_joints(q, arm="irb4400")
        # targets.csv rounds joints to 1e-5 deg: a quadrant may differ only on its boundary
        for got, want, joint in zip(conf[:3], expected[:3], q[[0, 3, 5]], strict=True):
            on_boundary = abs(np.degrees(joint) / 90.0 - round(np.degrees(joint) / 90.0)) < 1e-6
            assert got == want or on_boundary, (k, conf, expected)
        assert conf[3] == expected[3]
        # the joints are the IK of the target pose: FK lands on it
        xyz = np.array([float(row[c]) for c in ("x_mm", "y_mm", "z_mm")])
        assert np.linalg.norm(robot.fk(q)[:3, 3] * 1e3 - xyz) < 0.01


@pytest.mark.slow
def test_ur10_writes_program_script_whose_poses_are_the_targets_fk(ur10):
    out, s, proc = ur10
    assert s["program_language"] == "urscript"
    assert (out / "program.mod").exists() and (out / "program_fc.script").exists()
    robot = Robot("ur10", Tool().T_flange_tcp)
    rows = targets_rows(out)
    motions = script_poses((out / "program.script").read_text())
    path = [poses[-1] for kind, poses in motions[1:-1]]  # without approach and retract
    assert len(path) == len(rows)
    for pose, row in zip(path, rows, strict=True):
        T = robot.fk(joints_of(row))
        assert np.linalg.norm(T[:3, 3] - pose[:3]) * 1e3 < 0.01
        R = trimesh.transformations.rotation_matrix(
            np.linalg.norm(pose[3:]), pose[3:] / max(np.linalg.norm(pose[3:]), 1e-12)
        )[:3, :3]
        assert np.degrees(np.arccos(np.clip((np.trace(R.T @ T[:3, :3]) - 1) / 2, -1, 1))) < 0.01
    assert "mesh deviation" in proc.stdout


def test_tool_radius_out_of_range_is_refused(tmp_path):
    proc = robomach_here(
        "demo", "--out", str(tmp_path), "--language", "rapid", "--tool-radius-mm", "9"
    )
    assert proc.returncode == 2 and "--tool-radius-mm" in proc.stderr and "0.5-5 mm" in proc.stderr


@pytest.mark.slow
def test_arcs_fewer_instructions_scored_like_the_straight_program(tmp_path):
    s, proc = demo(tmp_path, "--arcs", "--robot", "ur10")
    assert s["arcs"] and s["circular_moves"] > 10
    assert s["moves"] < s["straight_moves"]
    assert s["max_deviation_mm"] <= 0.3
    mod = (tmp_path / "program.mod").read_text()
    assert "MoveC" in mod and rapidchecker_errors(mod) == []
    assert "movec(" in (tmp_path / "program.script").read_text()
    assert s["robtargets_reachable"] == s["robtargets_total"]
    assert "circular" in proc.stdout


def _guide_csv(path: Path, count: int | None = None) -> Path:
    wp = builtin_workpiece("water_pump", robot="ur10")
    intents = guide_plan(wp, 0.001, np.random.default_rng(0))[:count]
    lines = ["x_mm,y_mm,z_mm,qw,qx,qy,qz,wall_nx,wall_ny,wall_nz"]
    for it in intents:
        q = trimesh.transformations.quaternion_from_matrix(make_transform(it.rotation, np.zeros(3)))
        n = it.wall_normal if it.wall_normal is not None else None
        if n is None:
            continue
        lines.append(",".join(f"{v:.6f}" for v in [*(it.position_m * 1e3), *q, *n]))
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.slow
def test_open_s_groove_has_no_move_across_the_slot_and_stays_on_its_wall(tmp_path):
    s, _ = demo(tmp_path, "--workpiece", "s_groove", "--open")
    assert s["closed"] is False and s["completed"]
    # the program (targets and the moves between them) against the taught wall and the mesh:
    # a move across the slot would be millimetres off both (a closed run: 4.2 mm, 2.0 mm)
    assert s["max_deviation_mm"] <= 0.3
    assert s["mesh_max_deviation_mm"] <= 0.3
    rows = targets_rows(tmp_path)
    pts = np.array([[float(r[c]) for c in ("x_mm", "y_mm", "z_mm")] for r in rows])
    assert np.linalg.norm(pts[-1] - pts[0]) > 80.0  # it ends at the slot's far end


@pytest.mark.slow
def test_an_uploaded_part_is_scored_against_its_mesh(tmp_path):
    wp = builtin_workpiece("water_pump", robot="ur10")
    mesh = wp.mesh.copy()
    mesh.apply_scale(1e3)
    part = tmp_path / "pump_copy.stl"
    mesh.export(part)
    guides = _guide_csv(tmp_path / "guides.csv")
    s, proc = demo(tmp_path / "o", "--workpiece", str(part), "--guide-points", str(guides))
    assert s["max_deviation_mm"] is None  # no known wall
    assert 0.0 < s["mesh_max_deviation_mm"] <= 0.3
    assert 0.0 < s["mesh_rms_deviation_mm"] <= s["mesh_max_deviation_mm"]
    assert "mesh deviation" in proc.stdout


def test_wobj_with_three_rotations_places_the_program(tmp_path):
    proc = robomach_here("demo", "--out", str(tmp_path), "--wobj", "800,160,0,0,0")
    assert proc.returncode == 2 and "3, 4 or 6" in proc.stderr


@pytest.mark.slow
def test_your_own_urdf_runs_the_demo(tmp_path):
    from robomach_core.cell.robot import robot_urdf_path

    urdf = tmp_path / "my_arm.urdf"
    urdf.write_bytes(robot_urdf_path("ur10").read_bytes())
    s, _ = demo(tmp_path / "o", "--robot", str(urdf))
    assert s["robot"].startswith("urdf_my_arm_")
    assert s["completed"] and s["max_deviation_mm"] <= 0.3
    assert s["robtargets_reachable"] == s["robtargets_total"]


def test_a_bad_urdf_on_the_command_line_is_one_line(tmp_path):
    urdf = tmp_path / "two_joints.urdf"
    urdf.write_text(
        '<robot name="x"><link name="a"/><link name="b"/>'
        '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
        '<limit lower="-1" upper="1"/></joint></robot>'
    )
    proc = robomach_here("demo", "--out", str(tmp_path / "o"), "--robot", str(urdf))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "has 1 revolute joints" in proc.stderr
