"""Read a written program back: the machining path it commands (targets and feeds) and its
feed control, in every language.

PROBLEM   "The program that leaves is the cut that was simulated" is only a claim until the
          file itself is cut: a writer that rounds, drops or reorders a target or a speed, or
          leaves the feed control out, would go unnoticed by a test of the in-memory program.
STRATEGY  Parse each language's files with the project's own checkers (``rapid_check``,
          ``krl_check``; URScript's motion lines and the feed loop's lists), keep the moves
          along the path (not the approach and retract in the air) in order, a circular move's
          via point before its end point, each with the speed of its move, and turn the
          poses into the robot's base frame.
SOLUTION  ``read_program(language, files) -> ProgramPath`` and
          ``ProgramPath.targets(robot, q_seed)`` (``postprocess.Targets`` with joints by
          inverse kinematics, ready to cut).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..postprocess import Targets
from ..transforms import (
    make_transform,
    matrices_from_quaternions,
    matrix_from_quaternion,
    quaternions_from_matrices,
)

MM = 1e-3
_RAPID_MOVE = re.compile(
    r"^\s*(MoveL|MoveC|FCPressL|FCPressC|FCPress1LStart)\s+(.*);\s*$", flags=re.IGNORECASE
)
_RAPID_SPEED = re.compile(r"CONST\s+speeddata\s+(\w+)\s*:=\s*\[([-+\d.eE]+),")
_RAPID_TARGET = re.compile(r"^p\d+$")
_NUMBERS = r"([-+\d.eE,\s]+)"
_RAPID_WOBJ = re.compile(
    r"wobjdata\s+\w+\s*:=\s*\[\s*\w+\s*,\s*\w+\s*,\s*\"[^\"]*\"\s*,"
    rf"\s*\[\s*\[{_NUMBERS}\]\s*,\s*\[{_NUMBERS}\]\s*\]\s*,"
    rf"\s*\[\s*\[{_NUMBERS}\]\s*,\s*\[{_NUMBERS}\]\s*\]\s*\]",
    flags=re.IGNORECASE,
)
_KRL_TARGET = re.compile(r"^XP\d+$", flags=re.IGNORECASE)


@dataclass(frozen=True, eq=False)
class ProgramPath:
    """The machining path of a program file.

    Attributes:
        position_m: (n, 3) targets in the robot base frame, in the order the program runs them.
        rotation: (n, 3, 3) their orientations.
        speed_m_s: (n,) the speed of the move to each target.
        feed_control: how the program controls the feed from the force: ``"FC SpeedChange"``,
            ``"URScript feed loop"`` or None (the programmed speeds, as written).
        reference_N: the force the feed control holds (None without).
        controller: the feed loop's controller (URScript), else None.
    """

    position_m: np.ndarray
    rotation: np.ndarray
    speed_m_s: np.ndarray
    feed_control: str | None = None
    reference_N: float | None = None
    controller: str | None = None

    def __len__(self) -> int:
        return len(self.position_m)

    def targets(self, robot, q_seed: np.ndarray) -> Targets:
        """The path as ``Targets``, each target's joints the inverse kinematics of its pose on
        ``robot`` seeded from the previous target's (the first from ``q_seed``)."""
        joints = np.empty((len(self), 6))
        q = np.asarray(q_seed, dtype=float)
        for k in range(len(self)):
            q = robot.ik(make_transform(self.rotation[k], self.position_m[k]), q)
            joints[k] = q
        return Targets(
            position_m=self.position_m,
            quaternion_wxyz=quaternions_from_matrices(self.rotation),
            joints_rad=joints,
            speed_m_s=self.speed_m_s,
            curvature_1_m=np.zeros(len(self)),
            sample_index=np.zeros(len(self), dtype=int),
        )


def read_program(language: str, files: dict[str, str]) -> ProgramPath:
    """The machining path of the program ``files`` (file name -> text) in ``language``, in
    the robot's base frame (through the work object or base frame the files declare).

    Raises:
        InvalidInputError: the files do not parse, or hold no path.
    """
    if language == "rapid":
        return _read_rapid(_one(files, ".mod"))
    if language == "krl":
        return _read_krl(_one(files, ".src"), _one(files, ".dat"))
    if language == "urscript":
        return _read_urscript(_one(files, ".script"))
    raise InvalidInputError(f"no reader for program language {language!r}")


def _one(files: dict[str, str], suffix: str) -> str:
    names = [n for n in files if n.endswith(suffix) and not n.startswith("program_fc")]
    if len(names) != 1:
        raise InvalidInputError(f"expected one {suffix} program, got {names or 'none'}")
    return files[names[0]]


def _wobj_frame(text: str) -> np.ndarray:
    """T_base_wobj of the module's (one) work object: user frame x object frame, as written."""
    found = _RAPID_WOBJ.search(text)
    if not found:
        raise InvalidInputError("the module declares no wobjdata to place its targets")
    u_pos, u_rot, o_pos, o_rot = (
        np.array([float(v) for v in group.split(",")]) for group in found.groups()
    )
    return make_transform(matrix_from_quaternion(u_rot), u_pos * MM) @ make_transform(
        matrix_from_quaternion(o_rot), o_pos * MM
    )


def _read_rapid(text: str) -> ProgramPath:
    from .rapid_check import check_rapid_module

    info = check_rapid_module(text)
    T_base_wobj = _wobj_frame(text)
    speeds = {name.upper(): float(v) * MM for name, v in _RAPID_SPEED.findall(text)}
    names, v = [], []
    for line in text.splitlines():
        found = _RAPID_MOVE.match(line)
        if not found:
            continue
        args = [a.strip() for a in found.group(2).split(",")]
        kind = found.group(1).upper()
        points = args[:2] if kind in ("MOVEC", "FCPRESSC") else args[:1]
        if not all(_RAPID_TARGET.match(p) for p in points):
            continue  # the approach or the retract
        speed = speeds[args[len(points)].upper()]
        names += points
        v += [speed] * len(points)
    # The quaternions turned into rotations together (one conversion, not one per target).
    quats = np.array([info.robtargets[name][1] for name in names], dtype=float).reshape(-1, 4)
    norms = np.linalg.norm(quats, axis=1)
    for q in quats[~(np.isfinite(norms) & (norms >= 1e-9))]:
        matrix_from_quaternion(q)  # raises, saying which has no direction
    positions, rotations = [], []
    for name, R in zip(names, matrices_from_quaternions(quats) if names else [], strict=True):
        T = T_base_wobj @ make_transform(R, info.robtargets[name][0] * MM)
        positions.append(T[:3, 3])
        rotations.append(T[:3, :3])
    reference = re.search(r"^\s*FCSpdChgAct\s+([-+\d.eE]+)\s*;", text, flags=re.M)
    return _path(
        positions, rotations, v,
        feed_control="FC SpeedChange" if reference else None,
        reference_N=float(reference.group(1)) if reference else None,
    )  # fmt: skip


def _read_krl(src: str, dat: str) -> ProgramPath:
    from .krl_check import check_krl_program

    info = check_krl_program(src, dat)
    T_base = np.eye(4) if info.base is None else info.base.transform()
    positions, rotations, v = [], [], []
    for motion in info.motions:
        if motion.kind == "PTP" or not all(_KRL_TARGET.match(p) for p in motion.points):
            continue
        for name in motion.points:
            T = T_base @ info.points[name.upper()].transform()
            positions.append(T[:3, 3])
            rotations.append(T[:3, :3])
            assert motion.vel_cp_m_s is not None  # the check refuses a LIN/CIRC before it
            v.append(float(motion.vel_cp_m_s))
    return _path(positions, rotations, v)


def _read_urscript(text: str) -> ProgramPath:
    from scipy.spatial.transform import Rotation

    from .urscript import script_numbers, script_poses

    motions = script_poses(text)
    path = [poses for kind, poses in motions if kind == "path"]
    if path:
        poses = path[0]
        speeds = script_numbers(text, "cm_speed")
        if speeds is None or len(speeds) != len(poses):
            raise InvalidInputError("the feed loop's cm_speed does not pair with its cm_path")
        controller = re.search(r"^\s*# CMRR: (\S+) holding ([-+\d.eE]+) N", text, flags=re.M)
        if controller is None:
            raise InvalidInputError(
                "the feed loop has no '# CMRR: <controller> holding <F> N' line"
            )
        feed: tuple[str | None, float | None, str | None] = (
            "URScript feed loop",
            float(controller.group(2)),
            controller.group(1),
        )
    else:
        moving = [(kind, poses) for kind, poses in motions if poses][1:-1]  # air moves out
        speeds_of = re.findall(r"^\s*move[lc]\(.*\bv=([-+\d.eE]+)", text, flags=re.M)[1:-1]
        poses, pose_speeds = [], []
        for (_kind, ps), v in zip(moving, speeds_of, strict=True):
            poses += ps
            pose_speeds += [float(v)] * len(ps)
        speeds = np.asarray(pose_speeds)
        feed = (None, None, None)
    rotations = [Rotation.from_rotvec(p[3:]).as_matrix() for p in poses]
    return _path(
        [p[:3] for p in poses], rotations, speeds, feed_control=feed[0], reference_N=feed[1],
        controller=feed[2],
    )  # fmt: skip


def _path(positions, rotations, speeds, **kwargs) -> ProgramPath:
    if not len(positions):
        raise InvalidInputError("the program has no machining path")
    return ProgramPath(
        np.asarray(positions, dtype=float),
        np.asarray(rotations, dtype=float),
        np.asarray(speeds, dtype=float),
        **kwargs,
    )
