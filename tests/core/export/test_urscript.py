"""URScript export and target joints from inverse kinematics, on the real UR10 and IRB 4400."""

from __future__ import annotations

import re

import numpy as np
import pytest

from robomach_core.cell import TOOL_DOWN, Robot, Tool
from robomach_core.errors import InvalidInputError, UnreachableTargetError
from robomach_core.export.rapid import confdata_from_joints
from robomach_core.export.target_joints import configuration, target_joints, with_target_joints
from robomach_core.export.urscript import (
    BLEND_RADIUS_M,
    script_poses,
    urscript_program,
)
from robomach_core.part import builtin_workpiece
from robomach_core.postprocess import Move, Targets
from robomach_core.transforms import (
    make_transform,
    quaternions_from_matrices,
    rotation_about,
    rotation_log,
)

TOOL = Tool()


def groove_targets(robot: Robot, n: int = 12, *, joint_error_rad: float = 0.0) -> Targets:
    """Targets on a 30 mm arc over the built-in pump, the tool down and tilting a little.

    Their joints are the IK solution perturbed by ``joint_error_rad`` (as the recorded joints
    are: 0.09-0.25 mm off the target).
    """
    pump = builtin_workpiece("water_pump", robot=robot.name)
    centre = pump.T_base_wobj[:3, 3] + np.array([0.0, 0.0, pump.surface_z_m - 0.003])
    angles = np.linspace(0.0, np.pi / 2, n)
    Rs = np.array([rotation_about("x", 0.1 * np.sin(a)) @ TOOL_DOWN for a in angles])
    ps = centre + 0.030 * np.column_stack([np.cos(angles), np.sin(angles), np.zeros(n)])
    q = robot.home_rad
    joints = []
    for R, p in zip(Rs, ps, strict=True):
        q = robot.ik(make_transform(R, p), q)
        joints.append(q)
    rng = np.random.default_rng(1)
    return Targets(
        position_m=ps,
        quaternion_wxyz=quaternions_from_matrices(Rs),
        joints_rad=np.array(joints) + rng.uniform(-1, 1, (n, 6)) * joint_error_rad,
        speed_m_s=np.linspace(0.004, 0.012, n),
        curvature_1_m=np.full(n, 1 / 0.03),
        sample_index=np.arange(n) * 10,
    )


@pytest.fixture(scope="module")
def ur10() -> Robot:
    return Robot("ur10", TOOL.T_flange_tcp)


def assert_pose_is_fk(pose6: np.ndarray, robot: Robot, joints: np.ndarray) -> None:
    """A script pose against the FK of the target's joints: 0.01 mm and 1e-5 rad."""
    T = robot.fk(joints)
    assert np.linalg.norm(pose6[:3] - T[:3, 3]) < 1e-5
    angle = float(np.linalg.norm(pose6[3:]))
    R_script = rotation_about(pose6[3:] / angle, angle) if angle > 0 else np.eye(3)
    assert np.linalg.norm(rotation_log(R_script.T @ T[:3, :3])) < 1e-5


@pytest.mark.parametrize("force", [None, 12.0])
def test_every_script_pose_is_the_fk_of_its_target_joints(ur10, force):
    targets = with_target_joints(ur10, groove_targets(ur10, joint_error_rad=2e-4))
    pump = builtin_workpiece("water_pump", robot="ur10")
    text = urscript_program(targets, TOOL, pump, force_control_N=force, comment=("test",))
    motions = script_poses(text)
    path = motions[1:-1]  # approach and retract are 20 mm back along the tool axis
    assert [kind for kind, _ in path] == ["movel"] * len(targets)
    for k, (_, (pose6,)) in enumerate(path):
        assert_pose_is_fk(pose6, ur10, targets.joints_rad[k])
    approach = motions[0][1][0]
    T0 = ur10.fk(targets.joints_rad[0])
    np.testing.assert_allclose(approach[:3], T0[:3, 3] - 0.020 * T0[:3, 2], atol=1e-6)
    assert text.startswith("def learned_path():\n") and text.endswith("\nend\n")


def test_speeds_and_blends_per_target(ur10):
    targets = groove_targets(ur10)
    text = urscript_program(targets, TOOL, builtin_workpiece("water_pump"))
    lines = [line for line in text.splitlines() if line.strip().startswith("movel")][1:-1]
    speeds = [float(re.search(r"v=([0-9.]+)", line).group(1)) for line in lines]
    radii = [float(re.search(r"r=([0-9.]+)", line).group(1)) for line in lines]
    np.testing.assert_allclose(speeds, targets.speed_m_s, atol=1e-6)
    gaps = np.linalg.norm(np.diff(targets.position_m, axis=0), axis=1)
    assert radii[-1] == 0.0
    assert radii[0] <= 0.4 * gaps[0] + 1e-9
    for k in range(1, len(radii) - 1):
        assert radii[k] <= min(BLEND_RADIUS_M, 0.4 * gaps[k - 1], 0.4 * gaps[k]) + 1e-9


def test_force_variant_presses_along_tool_y_between_zeroing_and_end(ur10):
    targets = with_target_joints(ur10, groove_targets(ur10))
    text = urscript_program(targets, TOOL, builtin_workpiece("water_pump"), force_control_N=15)
    lines = [line.strip() for line in text.splitlines()]
    zero, end = lines.index("zero_ftsensor()"), lines.index("end_force_mode()")
    force_lines = [k for k, line in enumerate(lines) if line.startswith("force_mode(")]
    assert len(force_lines) == len(targets)
    assert zero < force_lines[0] and force_lines[-1] < end
    assert all("[0, 1, 0, 0, 0, 0], [0, 15, 0, 0, 0, 0], 2," in lines[k] for k in force_lines)
    # Each force frame is the pose of the target moved to next: tool y is that target's Yp.
    for k, line in zip(force_lines, targets.position_m, strict=True):
        frame = np.array(
            [float(v) for v in re.search(r"p\[([^\]]*)\]", lines[k]).group(1).split(",")]
        )
        np.testing.assert_allclose(frame[:3], line, atol=1e-6)
    assert lines[end + 1].startswith("movel(")  # retract after pressing ends


def test_arcs_become_movec_through_via_and_to(ur10):
    targets = with_target_joints(ur10, groove_targets(ur10, n=5))
    moves = (Move("linear", 0), Move("circular", 2, 1), Move("circular", 4, 3))
    text = urscript_program(targets, TOOL, builtin_workpiece("water_pump"), arcs=moves)
    path = script_poses(text)[1:-1]
    assert [kind for kind, _ in path] == ["movel", "movec", "movec"]
    for (kind, poses), move in zip(path, moves, strict=True):
        indices = [move.to] if kind == "movel" else [move.via, move.to]
        for pose6, k in zip(poses, indices, strict=True):
            assert_pose_is_fk(pose6, ur10, targets.joints_rad[k])
    assert text.count("mode=0") == 2


def test_bad_input_is_a_clear_error(ur10):
    targets = groove_targets(ur10, n=3)
    pump = builtin_workpiece("water_pump")
    with pytest.raises(InvalidInputError, match="force"):
        urscript_program(targets, TOOL, pump, force_control_N=-1.0)
    with pytest.raises(InvalidInputError, match="first move"):
        urscript_program(targets, TOOL, pump, arcs=(Move("linear", 1),))
    slow = Targets(**{**targets.__dict__, "speed_m_s": np.zeros(3)})
    with pytest.raises(InvalidInputError, match="speed"):
        urscript_program(slow, TOOL, pump)
    with pytest.raises(InvalidInputError, match="6 values"):
        script_poses("  movel(p[1, 2, 3], a=1, v=1, r=0)\n")


# -------------------------------------------------------------------------------------------------
# Target joints from IK


@pytest.mark.parametrize("name", ["ur10", "irb4400", "irb2400", "kr270"])
def test_target_joints_reach_the_target_pose_on_the_recorded_branch(name):
    robot = Robot(name, TOOL.T_flange_tcp)
    targets = groove_targets(robot, joint_error_rad=3e-4)
    before = [
        np.linalg.norm(robot.fk(q)[:3, 3] - p)
        for q, p in zip(targets.joints_rad, targets.position_m, strict=True)
    ]
    assert max(before) > 5e-5  # the recorded joints miss the target, as in a real recording
    q = target_joints(robot, targets)
    for k in range(len(targets)):
        T = robot.fk(q[k])
        assert np.linalg.norm(T[:3, 3] - targets.position_m[k]) < 1e-6
        assert robot.within_limits(q[k])
    # one configuration: ABB's cfx (UR: its branch in ABB's numbering), KUKA's Status
    branches = {configuration(robot, j) for j in q}
    assert branches == {configuration(robot, targets.joints_rad[0])}
    if robot.family != "kuka":
        assert branches == {confdata_from_joints(targets.joints_rad[0], arm=name)[3]}
    assert np.max(np.abs(q - targets.joints_rad)) < 0.01


def test_unreachable_target_is_named(ur10):
    targets = groove_targets(ur10, n=4)
    far = targets.position_m.copy()
    far[2] += np.array([0.0, 0.0, 5.0])
    with pytest.raises(UnreachableTargetError, match="target p3"):
        target_joints(ur10, Targets(**{**targets.__dict__, "position_m": far}))
