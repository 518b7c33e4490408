"""The KRL writer and the project's KRL checker: E6POS, Status/Turn, motions, refusals."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from robomach_core.cell import TOOL_DOWN, Robot, Tool
from robomach_core.export.krl import (
    APPROACH_NAME,
    RETRACT_NAME,
    krl_program,
    kuka_abc_deg,
    kuka_rotation,
)
from robomach_core.export.krl_check import KrlSyntaxError, check_krl_program
from robomach_core.part import builtin_workpiece
from robomach_core.postprocess import Move, Targets
from robomach_core.robots import KR270
from robomach_core.robots.kuka import status_bits, turn_bits
from robomach_core.transforms import make_transform, quaternion_from_matrix, rotation_about


@pytest.fixture(scope="module")
def arm() -> Robot:
    return Robot("kr270", Tool().T_flange_tcp)


@pytest.fixture(scope="module")
def program(arm) -> tuple[str, str, Targets, object]:
    """Twelve targets around the pump's corner, tool down and turning about z, their joints
    the IK on the KR 270; one circular move."""
    pump = builtin_workpiece("water_pump", robot="kr270")
    positions, quats, joints = [], [], []
    q = arm.home_rad
    for k in range(12):
        R = rotation_about("z", math.radians(8.0 * k)) @ TOOL_DOWN
        p = pump.T_base_wobj[:3, 3] + (0.03 * math.cos(k / 3), 0.03 * math.sin(k / 3), 0.02)
        q = arm.ik(make_transform(R, p), q)
        positions.append(p)
        quats.append(quaternion_from_matrix(R))
        joints.append(q)
    n = len(positions)
    targets = Targets(
        position_m=np.array(positions),
        quaternion_wxyz=np.array(quats),
        joints_rad=np.array(joints),
        speed_m_s=np.linspace(0.004, 0.02, n),
        curvature_1_m=np.zeros(n),
        sample_index=np.arange(n),
    )
    moves = [Move("linear", k) for k in range(6)] + [Move("circular", 7, 6)]
    moves += [Move("linear", k) for k in range(8, n)]
    src, dat = krl_program(targets, Tool(), pump, arm, comment=("test",), moves=moves)
    return src, dat, targets, pump


def test_the_checker_accepts_the_pair_and_reads_its_motions(program):
    src, dat, targets, _ = program
    info = check_krl_program(src, dat, stem="program")
    assert info.module_name == "program"
    kinds = [m.kind for m in info.motions]
    assert kinds[0] == "PTP" and kinds.count("CIRC") == 1 and kinds[-1] == "LIN"
    assert info.motions[0].points == (APPROACH_NAME,)
    assert info.motions[-1].points == (RETRACT_NAME,)
    # every path move but the last is approximated; the last target and retract stop exactly
    path = info.motions[1:-1]
    assert all(m.approximation == "C_DIS" for m in path[:-1]) and path[-1].approximation is None
    # $VEL.CP in force at each move is the learned speed of its target [m/s]
    for motion in path:
        k = int(motion.points[-1][2:]) - 1
        assert motion.vel_cp_m_s == pytest.approx(targets.speed_m_s[k], abs=1e-5)
    assert src.isascii() and dat.isascii() and src.endswith("END\n") and dat.endswith("ENDDAT\n")


def test_every_e6pos_is_the_fk_of_its_joints_and_its_status_turn_theirs(program, arm):
    src, dat, targets, _ = program
    info = check_krl_program(src, dat)
    poses = dict(info.motion_poses())
    for k, q in enumerate(targets.joints_rad):
        name = f"XP{k + 1}"
        T_fk = arm.fk(q)
        np.testing.assert_allclose(poses[name][:3, 3], T_fk[:3, 3], atol=1e-5)  # 0.01 mm
        angle = np.arccos(np.clip((np.trace(poses[name][:3, :3].T @ T_fk[:3, :3]) - 1) / 2, -1, 1))
        assert math.degrees(angle) < 1e-3
        point = info.points[name]
        assert point.status == status_bits(KR270, q)
        # A4 stays at 0 on a tool-down path; its IK noise (< 1e-6 rad here) carries no sign
        sure = sum(1 << i for i in range(6) if abs(q[i]) > 1e-6)
        assert point.turn & sure == turn_bits(q) & sure


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-179.9, 179.9), min_size=3, max_size=3))
def test_abc_is_kukas_zyx_euler(abc):
    """A, B, C read back from the rotation they give (B away from the +-90 deg gimbal lock)."""
    assume(abs(abc[1]) <= 89.0)
    R = kuka_rotation(abc)
    expected = (
        rotation_about("z", math.radians(abc[0]))
        @ rotation_about("y", math.radians(abc[1]))
        @ rotation_about("x", math.radians(abc[2]))
    )
    np.testing.assert_allclose(R, expected, atol=1e-12)
    np.testing.assert_allclose(kuka_abc_deg(R), abc, atol=1e-9)


def _mutated(src: str, dat: str, where: str, old: str, new: str) -> tuple[str, str]:
    if where == "src":
        assert old in src, old
        return src.replace(old, new, 1), dat
    assert old in dat, old
    return src, dat.replace(old, new, 1)


@pytest.mark.parametrize(
    ("where", "old", "new", "needle"),
    [
        ("src", "DEF program( )", "DEF prog( )", "name different modules"),
        ("src", "\nEND\n", "\n", "must end with END"),
        ("dat", "\nENDDAT\n", "\n", "must end with ENDDAT"),
        ("src", "LIN XP3 C_DIS", "LIN XP999 C_DIS", "no such point"),
        ("src", "CIRC XP7, XP8", "CIRC XP8", "takes 2 point"),
        ("src", "  $BASE = RM_WOBJ\n", "", "before $BASE is assigned"),
        ("src", "  $APO.CDIS = 0.5\n", "", "C_DIS before $APO.CDIS"),
        ("src", "$VEL.CP = 0.1\n", "$VEL.CP = 5\n", "outside (0, 3]"),
        ("src", "  BAS(#INITMOV, 0)\n", "  IF TRUE THEN\n", "unsupported statement"),
        ("dat", "S 2,T", "S 999,T", "S must be an integer"),
        ("dat", ",C 180.00000,", ",C 181.00000,", "outside [-180, 180]"),
        ("dat", "DECL E6POS XP2={X", "DECL E6POS XP1={X", "declared twice"),
        ("dat", "DECL E6POS XP4={X", "DECL E6POS XP4_IS_A_VERY_LONG_NAME_XX={X", "longer than 24"),
        ("dat", ",Y ", ",Y {", "unbalanced braces"),
        ("dat", "RM_WOBJ={X", "RM_WOBJ={Q", "lacks X"),
        (
            "src",
            "  $BASE = RM_WOBJ\n",
            "  BASE_DATA[1] = {X 1, Y 2, Z 3, A 0, B 0, C 0}\n",
            "does not overwrite the controller's BASE_DATA",
        ),
        ("src", "  $LOAD = RM_LOAD\n", "  $LOAD = NO_LOAD\n", "no such LOAD"),
        ("dat", "RM_LOAD={M ", "RM_LOAD={Q ", "needs a mass"),
    ],
)
def test_the_checker_refuses_a_broken_pair_naming_the_file_and_line(
    program, where, old, new, needle
):
    src, dat, _, _ = program
    bad_src, bad_dat = _mutated(src, dat, where, old, new)
    with pytest.raises(KrlSyntaxError, match="line") as exc:
        check_krl_program(bad_src, bad_dat)
    assert needle in str(exc.value)


def test_the_stem_must_name_the_module(program):
    src, dat, _, _ = program
    with pytest.raises(KrlSyntaxError, match="does not name the file"):
        check_krl_program(src, dat, stem="pump")


def test_a_move_sequence_must_be_valid(program, arm):
    _, _, targets, pump = program
    with pytest.raises(Exception, match="move"):
        krl_program(targets, Tool(), pump, arm, moves=[Move("linear", 99)])


def test_the_program_keeps_its_frames_and_leaves_the_controllers_tables_alone(program):
    """Issue 31: a KUKA cell keeps its measured bases and tools in BASE_DATA / TOOL_DATA; the
    program's work object, tool and load are its own FRAME and LOAD in the .dat, made $BASE,
    $TOOL and $LOAD (and the points read back in the base frame through them)."""
    src, dat, targets, pump = program
    for table in ("BASE_DATA", "TOOL_DATA", "LOAD_DATA"):
        assert not re.search(rf"^\s*{table}\[", src + dat, re.M | re.I), table
    info = check_krl_program(src, dat, stem="program")
    np.testing.assert_allclose(info.base.transform(), pump.T_base_wobj, atol=1e-7)
    np.testing.assert_allclose(info.tool.transform(), Tool().T_flange_tcp, atol=1e-7)
    assert info.assignments["$LOAD"] == "RM_LOAD"
    poses = dict(info.motion_poses())
    for k in range(len(targets)):
        np.testing.assert_allclose(poses[f"XP{k + 1}"][:3, 3], targets.position_m[k], atol=1e-6)
