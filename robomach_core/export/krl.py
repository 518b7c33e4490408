"""KUKA KRL export of a learned machining path: a ``program.src`` / ``program.dat`` pair.

PROBLEM   A KUKA controller (KR C4, KSS 8) runs KRL: a ``.src`` with the motion statements and a
          ``.dat`` with the points, as E6POS {X, Y, Z [mm], A, B, C [deg], S, T, E1..E6} in the
          active $BASE for the active $TOOL. A, B, C are KUKA's Euler angles: R = Rz(A) Ry(B)
          Rx(C). S (Status) and T (Turn) pick the joint solution, so they must come from the
          target's joints on that arm.
STRATEGY  The same inputs as the RAPID and URScript writers (targets in the base frame with
          their joint solutions, the tool, the work object, the arc-fitted moves) and the same
          structure: $BASE from the work object (the part's frame in the robot base,
          $ROBROOT = $WORLD assumed), $TOOL and $LOAD from the tool, each from a FRAME / LOAD
          of the program's own .dat (``RM_WOBJ``, ``RM_TOOL``, ``RM_LOAD``): the controller's
          BASE_DATA / TOOL_DATA tables, where a cell keeps its measured bases and tools, are
          left as they are, as a KUKA programmer keeps them; PTP (at
          20 % axis speed) to an approach point 20 mm back along the tool axis; ``LIN`` /
          ``CIRC via, to`` along the path with ``C_DIS`` approximation ($APO.CDIS, the RAPID
          zone's 0.5 mm) and ``$VEL.CP`` [m/s] set before every move whose learned speed
          differs; an exact stop
          at the last target; LIN to the retract point. Status and Turn come from the joints
          (``robots.kuka``: bit 0 overhead area, bit 1 A3 >= phi, bit 2 A5 <= 0; Turn bit
          i - 1 when Ai < 0), computed on the pinocchio model so an uploaded KUKA arm gets them
          too. No force-control variant: KUKA.ForceTorqueControl's instructions are an option
          package robomach does not write.
SOLUTION  ``krl_program(context) -> (src_text, dat_text)``; ``krl_check.check_krl_program``
          parses them back (the tests run it on every generated pair).

KRL reference: KUKA System Software 8.x, "Operating and Programming Instructions for System
Integrators" (DEF/DEFDAT, E6POS, LIN/CIRC/PTP, C_DIS with $APO.CDIS, $VEL.CP in m/s,
$BASE/$TOOL/$LOAD from FRAME and LOAD variables, BAS(#INITMOV, 0)).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from ..cell import Robot, Tool
from ..errors import InvalidInputError, RobomachError
from ..part import Workpiece
from ..postprocess import Move, Targets, linear_moves, validate_moves
from ..transforms import inverse_transform, make_transform, matrix_from_quaternion

MODULE_NAME = "program"  # KRL: the DEF / DEFDAT name is the file name (program.src/.dat)
MAX_IDENTIFIER_LEN = 24
POSITION_DECIMALS = 4  # mm: 0.1 um, as the RAPID module's
ANGLE_DECIMALS = 5  # deg: 1.7e-7 rad (BASE_DATA places the path to 0.03 um at 0.2 m)
VELOCITY_DECIMALS = 5  # m/s: 0.01 mm/s
APPROACH_OFFSET_M = 0.020
PTP_PERCENT = 20  # axis speed and acceleration of the PTP to the approach point (BAS)
AIR_SPEED_M_S = 0.1
APPROXIMATION_MM = 0.5  # the RAPID program's z_path zone
TOOL_INERTIA_KG_M2 = (0.001, 0.001, 0.001)
# Joint values this close to 0 count as 0 for Status and Turn: the target joints are solved to
# 1e-9 (export.target_joints), and a tool-down path keeps A4 at 0 within that noise; its sign
# would make T flip from point to point.
ANGLE_NOISE_RAD = 1e-8
APPROACH_NAME = "XP_APPROACH"
RETRACT_NAME = "XP_RETRACT"
# The program's own work object, tool and load, declared in its .dat: the controller's
# BASE_DATA / TOOL_DATA / LOAD_DATA tables (measured bases and tools other programs use) are
# never written by the program (issue 31).
BASE_NAME = "RM_WOBJ"
TOOL_NAME = "RM_TOOL"
LOAD_NAME = "RM_LOAD"


@dataclass(frozen=True)
class KrlPoint:
    """One E6POS: pose in $BASE [mm, deg] and the Status / Turn of its joint solution."""

    name: str
    xyz_mm: np.ndarray
    abc_deg: np.ndarray
    status: int
    turn: int


def kuka_abc_deg(R: np.ndarray) -> np.ndarray:
    """KUKA's A, B, C [deg] of a rotation: R = Rz(A) Ry(B) Rx(C). Shape (3,)."""
    return Rotation.from_matrix(np.asarray(R, dtype=float)).as_euler("ZYX", degrees=True)


def kuka_rotation(abc_deg: np.ndarray) -> np.ndarray:
    """The rotation Rz(A) Ry(B) Rx(C) of KUKA's A, B, C [deg]. Shape (3, 3)."""
    return Rotation.from_euler("ZYX", np.asarray(abc_deg, dtype=float), degrees=True).as_matrix()


def load_literal(tool: Tool) -> str:
    """``{M .., CM {X .., ..}, J {X .., Y .., Z ..}}``: the tool's mass [kg], centre of mass
    [mm] on the flange and inertia [kg m^2]."""
    cog = np.asarray(tool.com_m, dtype=float) * 1e3
    inertia = ", ".join(f"{a} {_short(v)}" for a, v in zip("XYZ", TOOL_INERTIA_KG_M2, strict=True))
    return (
        f"{{M {_short(tool.mass_kg, 3)}, CM {{X {_fixed(cog[0], 3)}, Y {_fixed(cog[1], 3)}, "
        f"Z {_fixed(cog[2], 3)}, A 0.0, B 0.0, C 0.0}}, J {{{inertia}}}}}"
    )


def frame_literal(T: np.ndarray) -> str:
    """``{X .., Y .., Z .., A .., B .., C ..}`` of a transform [m] in mm and degrees."""
    x, y, z = (np.asarray(T)[:3, 3] * 1e3).tolist()
    a, b, c = kuka_abc_deg(np.asarray(T)[:3, :3]).tolist()
    return (
        f"{{X {_fixed(x, POSITION_DECIMALS)}, Y {_fixed(y, POSITION_DECIMALS)}, "
        f"Z {_fixed(z, POSITION_DECIMALS)}, A {_fixed(a, ANGLE_DECIMALS)}, "
        f"B {_fixed(b, ANGLE_DECIMALS)}, C {_fixed(c, ANGLE_DECIMALS)}}}"
    )


def _fixed(x: float, decimals: int) -> str:
    value = round(float(x), decimals) + 0.0  # no negative zero
    return f"{value:.{decimals}f}"


def _short(x: float, decimals: int = 6) -> str:
    text = _fixed(x, decimals)
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def _comment(text: str) -> str:
    return "".join(ch if " " <= ch <= "~" else "?" for ch in text).rstrip()


def status_turn(robot: Robot, joints_rad: np.ndarray) -> tuple[int, int]:
    """KUKA's Status and Turn of a joint solution on ``robot`` (``robots.kuka`` gives the
    definitions), from the arm's own model: the wrist root point is axis 5's origin, the A1
    coordinate system axis 1's frame, the A2-A3 line the one through axes 2 and 3."""
    q = np.asarray(joints_rad, dtype=float)
    q = np.where(np.abs(q) < ANGLE_NOISE_RAD, 0.0, q)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    o1, R1 = data.oMi[1].translation, data.oMi[1].rotation
    o2, o3, wrist = data.oMi[2].translation, data.oMi[3].translation, data.oMi[5].translation
    axis2 = data.oMi[2].rotation @ _joint_axis(robot, 2)
    overhead = float((R1.T @ (wrist - o1))[0]) < 0.0
    # the wrist in front of the line through A2 and A3 (seen along A2's axis) <=> A3 >= phi
    in_front = float(np.cross(o3 - o2, wrist - o3) @ axis2) > 0.0
    a5_not_positive = q[4] <= 0.0
    status = int(overhead) + 2 * int(in_front) + 4 * int(a5_not_positive)
    turn = int(sum(1 << i for i in range(6) if q[i] < 0.0))
    return status, turn


def _joint_axis(robot: Robot, joint: int) -> np.ndarray:
    """A revolute joint's axis in its own frame (pinocchio's motion subspace)."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, np.zeros(robot.nq))
    S = np.asarray(data.joints[joint].S).reshape(6, -1)[:, 0]
    return S[3:] / np.linalg.norm(S[3:])


def _point_literal(point: KrlPoint) -> str:
    x, y, z = (_fixed(v, POSITION_DECIMALS) for v in point.xyz_mm)
    a, b, c = (_fixed(v, ANGLE_DECIMALS) for v in point.abc_deg)
    axes = ",".join(f"E{i} 0.0" for i in range(1, 7))
    return f"{{X {x},Y {y},Z {z},A {a},B {b},C {c},S {point.status},T {point.turn},{axes}}}"


def _point(
    name: str, T_base_tcp: np.ndarray, T_wobj_base: np.ndarray, st: tuple[int, int]
) -> KrlPoint:
    T = T_wobj_base @ T_base_tcp
    return KrlPoint(name, T[:3, 3] * 1e3, kuka_abc_deg(T[:3, :3]), st[0], st[1])


def _backed_off(T: np.ndarray) -> np.ndarray:
    out = np.array(T, dtype=float)
    out[:3, 3] -= out[:3, 2] * APPROACH_OFFSET_M
    return out


def _velocity_text(speed_m_s: float) -> str:
    value = round(float(speed_m_s), VELOCITY_DECIMALS)
    if not math.isfinite(value) or value <= 0.0:
        raise InvalidInputError(
            f"speed {speed_m_s * 1e3:g} mm/s rounds to 0 m/s at {VELOCITY_DECIMALS} decimals"
        )
    return _short(value, VELOCITY_DECIMALS)


def krl_program(
    targets: Targets,
    tool: Tool,
    workpiece: Workpiece,
    robot: Robot,
    *,
    comment: Sequence[str] = (),
    moves: Sequence[Move] | None = None,
) -> tuple[str, str]:
    """The ``program.src`` and ``program.dat`` texts (ASCII, LF line ends).

    Args:
        targets: The program's targets (base frame, SI) with their joint solutions on
            ``robot`` (``export.target_joints``): Status and Turn come from those joints.
        tool: Its TCP is the .dat's ``RM_TOOL`` (in KUKA's $FLANGE, the model's tool0), its
            mass and centre of mass ``RM_LOAD``.
        workpiece: Its ``T_base_wobj`` is the .dat's ``RM_WOBJ``; the points are in that frame.
        robot: The KUKA arm (its model gives Status and the approach/retract joints).
        comment: Header comment lines.
        moves: Move sequence with circular moves (``arcs.arc_targets``); None: LIN to each.

    Raises:
        InvalidInputError: no targets, a speed that rounds to zero, or a bad move sequence.
    """
    n = len(targets)
    if n == 0:
        raise InvalidInputError("a KRL program needs at least one target")
    moves = validate_moves(linear_moves(n) if moves is None else moves, n)
    T_base_wobj = np.asarray(workpiece.T_base_wobj, dtype=float)
    T_wobj_base = inverse_transform(T_base_wobj)
    Ts = [
        make_transform(matrix_from_quaternion(q), p)
        for p, q in zip(targets.position_m, targets.quaternion_wxyz, strict=True)
    ]
    joints = np.asarray(targets.joints_rad, dtype=float)
    points = [
        _point(f"XP{k + 1}", T, T_wobj_base, status_turn(robot, joints[k]))
        for k, T in enumerate(Ts)
    ]
    first, last = moves[0].to, moves[-1].to
    approach_T, retract_T = _backed_off(Ts[first]), _backed_off(Ts[last])
    approach = _point(
        APPROACH_NAME, approach_T, T_wobj_base, _air_st(robot, approach_T, joints[first])
    )
    retract = _point(RETRACT_NAME, retract_T, T_wobj_base, _air_st(robot, retract_T, joints[last]))
    src = _src_lines(targets, tool, T_base_wobj, moves, comment, workpiece.name)
    dat = ["&ACCESS RVP", "&REL 1", f"DEFDAT {MODULE_NAME}"]
    dat.append(
        f"  ; The work object {_comment(workpiece.name)} in the robot base, the tool on the flange "
        "and its load: this program's own (the controller's BASE_DATA and TOOL_DATA are not "
        "written)"
    )
    dat.append(f"  DECL FRAME {BASE_NAME}={frame_literal(T_base_wobj)}")
    dat.append(f"  DECL FRAME {TOOL_NAME}={frame_literal(tool.T_flange_tcp)}")
    dat.append(f"  DECL LOAD {LOAD_NAME}={load_literal(tool)}")
    dat.append(f"  ; E6POS in {BASE_NAME} (work object {_comment(workpiece.name)}): mm, deg")
    for point in (approach, *points, retract):
        dat.append(f"  DECL E6POS {point.name}={_point_literal(point)}")
    dat.append("ENDDAT")
    return "\n".join(src) + "\n", "\n".join(dat) + "\n"


def _air_st(robot: Robot, T_base_tcp: np.ndarray, q_near: np.ndarray) -> tuple[int, int]:
    """Status/Turn of an approach or retract point: its IK seeded at the path's end joints
    (the path's own when it cannot be solved: the controller keeps the branch on a LIN)."""
    try:
        q = robot.ik(T_base_tcp, q_near)
    except RobomachError:
        q = q_near
    return status_turn(robot, q)


def _src_lines(
    targets: Targets,
    tool: Tool,
    T_base_wobj: np.ndarray,
    moves: Sequence[Move],
    comment: Sequence[str],
    workpiece_name: str,
) -> list[str]:
    n = len(targets)
    n_arcs = sum(m.via is not None for m in moves)
    lines = ["&ACCESS RVP", "&REL 1", f"DEF {MODULE_NAME}( )"]
    lines.append(
        f"  ; Generated by robomach: {n} targets, {len(moves)} moves ({n_arcs} CIRC), "
        f"tool {_comment(tool.name)}, work object {_comment(workpiece_name)}."
    )
    lines += [f"  ; {_comment(c)}".rstrip() for c in comment]
    lines.append(
        f"  ; $ROBROOT is assumed at $WORLD: {BASE_NAME} (program.dat) is the part in the robot "
        "base; the controller's BASE_DATA and TOOL_DATA tables are not written."
    )
    lines += [";FOLD INI", "  BAS(#INITMOV, 0)", ";ENDFOLD (INI)"]
    lines += [f"  BAS(#VEL_PTP, {PTP_PERCENT})", f"  BAS(#ACC_PTP, {PTP_PERCENT})"]
    lines += [
        f"  $BASE = {BASE_NAME}",
        f"  $TOOL = {TOOL_NAME}",
        f"  $LOAD = {LOAD_NAME}",
        f"  $APO.CDIS = {_short(APPROXIMATION_MM)}",
        f"  $VEL.CP = {_velocity_text(AIR_SPEED_M_S)}",
        f"  PTP {APPROACH_NAME}",
    ]
    speed = _velocity_text(AIR_SPEED_M_S)
    for k, move in enumerate(moves):
        v = _velocity_text(targets.speed_m_s[move.to])
        if v != speed:
            lines.append(f"  $VEL.CP = {v}")
            speed = v
        approximation = "" if k == len(moves) - 1 else " C_DIS"
        if move.via is None:
            lines.append(f"  LIN XP{move.to + 1}{approximation}")
        else:
            lines.append(f"  CIRC XP{move.via + 1}, XP{move.to + 1}{approximation}")
    air = _velocity_text(AIR_SPEED_M_S)
    if air != speed:
        lines.append(f"  $VEL.CP = {air}")
    lines += [f"  LIN {RETRACT_NAME}", "END"]
    return lines
