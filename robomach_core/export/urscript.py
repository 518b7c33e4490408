"""URScript export of a learned machining path, for the UR arms' controllers.

PROBLEM   A UR controller runs URScript, not RAPID: poses ``p[x, y, z, rx, ry, rz]`` in the
          robot base frame (metres, rotation vector in radians), ``movel``/``movec`` with
          acceleration ``a`` [m/s^2], speed ``v`` [m/s] and blend radius ``r`` [m], and
          ``force_mode(task_frame, selection, wrench, type, limits)`` for pressing.
STRATEGY  The same inputs as ``program.rapid_program`` (targets in the base frame, the tool,
          the work object) and the same structure as the RAPID module: set the TCP and payload,
          approach 20 mm back along the tool axis, the path (per-target speeds, the RAPID
          zone's radius as blend, cut to 40 % of the adjacent moves so blends never overlap,
          as the controller requires), retract. The force variant zeroes the sensor at rest and
          presses along each target's tool y axis (the learned path normal Yp, as RAPID's
          ``\\Fy``) with ``force_mode`` type 2 (task frame taken as given) before every move.
SOLUTION  ``urscript_program(targets, tool, workpiece, ...) -> str`` and ``script_poses(text)``
          (the poses of the motion commands, for checks). Fixed decimals: 1e-8 m, 1e-8 rad.

URScript reference: Universal Robots, "The URScript Programming Language" (movel, movec,
set_tcp, set_payload, zero_ftsensor, force_mode, end_force_mode).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np

from ..cell import Tool
from ..errors import InvalidInputError
from ..part import Workpiece
from ..postprocess import Move, Targets, linear_moves, validate_moves
from ..transforms import arc_length_m, make_transform, matrix_from_quaternion, rotation_log
from .urscript_feed import UrFeedLoop, feed_loop_lines

PROGRAM_NAME = "learned_path"
POSE_DECIMALS = 8  # metres and radians: the RAPID module's 0.1 um (in the work object) kept
PATH_ACCELERATION_M_S2 = 0.5
AIR_SPEED_M_S = 0.1
AIR_ACCELERATION_M_S2 = 0.5
APPROACH_OFFSET_M = 0.020
BLEND_RADIUS_M = 0.0005  # the RAPID program's z_path zone (0.5 mm)
BLEND_FRACTION_MAX = 0.4  # of the shorter adjacent move: UR stops on overlapping blends
SETTLE_S = 0.5  # at rest before zero_ftsensor, as RAPID's WaitTime before FCCalib
# force_mode limits: speed along the compliant axis [m/s], deviation along the others [m, rad].
FORCE_SPEED_LIMIT_M_S = 0.02
FORCE_DEVIATION_LIMIT_M = 0.001
FORCE_DEVIATION_LIMIT_RAD = 0.017
_POSE_RE = re.compile(r"p\[([^\]]*)\]")
_MOTION_RE = re.compile(r"^\s*(movel|movec)\((.*)\)\s*$")
_PATH_RE = re.compile(r"^\s*cm_path\s*=\s*\[(.*)\]\s*$")


def pose_literal(T: np.ndarray) -> str:
    """``p[x, y, z, rx, ry, rz]`` of a 4x4 transform (metres, rotation vector in radians)."""
    values = [*np.asarray(T)[:3, 3], *rotation_log(np.asarray(T)[:3, :3])]
    return "p[" + ", ".join(_fixed(v) for v in values) + "]"


def _fixed(x: float, decimals: int = POSE_DECIMALS) -> str:
    return f"{round(float(x), decimals) + 0.0:.{decimals}f}"


def _short(x: float) -> str:
    text = _fixed(x).rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def _comment(text: str) -> str:
    return "".join(ch if " " <= ch <= "~" else "?" for ch in text).rstrip()


def _blend_radii(positions: np.ndarray, moves: Sequence[Move]) -> list[float]:
    """Blend radius of each move: the zone, cut to the adjacent moves' lengths; 0 at the end."""
    ends = [positions[m.to] for m in moves]
    lengths = [0.0] + [
        float(np.linalg.norm(b - a)) for a, b in zip(ends[:-1], ends[1:], strict=True)
    ]
    radii = []
    for k in range(len(moves)):
        if k == len(moves) - 1:
            radii.append(0.0)
            continue
        shorter = min(lengths[k] if k > 0 else math.inf, lengths[k + 1])
        radii.append(min(BLEND_RADIUS_M, BLEND_FRACTION_MAX * shorter))
    return radii


def urscript_program(
    targets: Targets,
    tool: Tool,
    workpiece: Workpiece,
    *,
    force_control_N: float | None = None,
    comment: Sequence[str] = (),
    arcs: Sequence[Move] | None = None,
    feed_loop: UrFeedLoop | None = None,
) -> str:
    """A URScript program moving through the targets (a ``.script`` file's text).

    Args:
        targets: The program's targets (base frame, SI), e.g. ``PostprocessResult.targets``.
        tool: The tool: its TCP and payload are set first.
        workpiece: The part (named in the header; the poses are in the base frame).
        force_control_N: When given, the path is pressed with this force along each target's
            tool y axis (``force_mode``), between ``zero_ftsensor()`` and ``end_force_mode()``.
        comment: Header comment lines.
        arcs: Optional move sequence (``robomach_core.postprocess.arcs``): circular moves become
            ``movec(via, to, ...)``; default a ``movel`` to every target.
        feed_loop: CMRR (``urscript_feed``): the program runs the force-driven feed loop
            along the targets in order (a straight line between each two, as the simulated
            cut), instead of the movel list. Not with ``force_control_N``.

    Raises:
        InvalidInputError: no targets, a non-positive speed or force, or a bad move sequence.
    """
    n = len(targets)
    if n == 0:
        raise InvalidInputError("a URScript program needs at least one target")
    speeds = np.asarray(targets.speed_m_s, dtype=float)
    if not np.all(np.isfinite(speeds)) or np.any(speeds <= 0):
        raise InvalidInputError("every target speed must be > 0 mm/s")
    if force_control_N is not None and not (force_control_N > 0 and math.isfinite(force_control_N)):
        raise InvalidInputError(f"force must be > 0 N, got {force_control_N}")
    moves = validate_moves(linear_moves(n) if arcs is None else arcs, n)
    Ts = [
        make_transform(matrix_from_quaternion(q), p)
        for p, q in zip(targets.position_m, targets.quaternion_wxyz, strict=True)
    ]
    positions = np.asarray(targets.position_m, dtype=float)
    n_arcs = sum(m.via is not None for m in moves)
    lines = [f"def {PROGRAM_NAME}():"]
    body = [
        f"# Generated by robomach: {n} targets, {len(moves)} moves ({n_arcs} circular), "
        f"tool {_comment(tool.name)}, work object {_comment(workpiece.name)}.",
        "# Poses in the robot base frame: p[x, y, z (m), rx, ry, rz (rotation vector, rad)].",
    ]
    body += [f"# {_comment(c)}".rstrip() for c in comment]
    if force_control_N is not None:
        body.append(f"# Force control: press {_short(force_control_N)} N along tool y.")
    cog = ", ".join(_fixed(v) for v in tool.com_m)
    body += [
        f"set_tcp({pose_literal(tool.T_flange_tcp)})",
        f"set_payload({_short(tool.mass_kg)}, [{cog}])",
    ]
    approach = Ts[moves[0].to].copy()
    approach[:3, 3] -= approach[:3, 2] * APPROACH_OFFSET_M
    retract = Ts[moves[-1].to].copy()
    retract[:3, 3] -= retract[:3, 2] * APPROACH_OFFSET_M
    air = f"a={_short(AIR_ACCELERATION_M_S2)}, v={_short(AIR_SPEED_M_S)}"
    body.append(f"movel({pose_literal(approach)}, {air}, r=0)")
    if force_control_N is not None:
        body += [f"sleep({_short(SETTLE_S)})", "zero_ftsensor()"]
    limits = ", ".join(
        [_short(FORCE_DEVIATION_LIMIT_M), _short(FORCE_SPEED_LIMIT_M_S)]
        + [_short(FORCE_DEVIATION_LIMIT_M)]
        + [_short(FORCE_DEVIATION_LIMIT_RAD)] * 3
    )
    if feed_loop is not None and force_control_N is None:
        body += feed_loop_lines(
            feed_loop,
            [pose_literal(T) for T in Ts],
            speeds,
            arc_length_m(positions),
            fixed=_short,
        )
        moves = ()
    for move, radius in zip(moves, _blend_radii(positions, moves), strict=True):
        if force_control_N is not None:
            wrench = f"[0, {_short(force_control_N)}, 0, 0, 0, 0]"
            body.append(
                f"force_mode({pose_literal(Ts[move.to])}, [0, 1, 0, 0, 0, 0], {wrench}, 2, "
                f"[{limits}])"
            )
        motion = (
            f"a={_short(PATH_ACCELERATION_M_S2)}, v={_short(speeds[move.to])}, r={_short(radius)}"
        )
        if move.via is None:
            body.append(f"movel({pose_literal(Ts[move.to])}, {motion})")
        else:
            body.append(
                f"movec({pose_literal(Ts[move.via])}, {pose_literal(Ts[move.to])}, {motion}, "
                "mode=0)"
            )
    if force_control_N is not None:
        body.append("end_force_mode()")
    body.append(f"movel({pose_literal(retract)}, {air}, r=0)")
    lines += [f"  {line}" for line in body]
    lines.append("end")
    return "\n".join(lines) + "\n"


def script_poses(text: str) -> list[tuple[str, list[np.ndarray]]]:
    """The motion commands of a script and their poses: [("movel", [p]), ("movec", [via, to])],
    and a feed loop's path (``urscript_feed``) as ("path", [p1, p2, ...]), in file order.

    Each pose is a (6,) array x, y, z [m], rx, ry, rz [rad].

    Raises:
        InvalidInputError: a motion command's pose is not six numbers.
    """
    out = []
    for line_no, line in enumerate(text.splitlines(), start=1):
        match = _MOTION_RE.match(line)
        path = _PATH_RE.match(line)
        if match:
            body_text = match.group(2)
        elif path:
            body_text = path.group(1)
        else:
            continue
        poses = []
        for body in _POSE_RE.findall(body_text):
            try:
                values = np.array([float(v) for v in body.split(",")])
            except ValueError:
                raise InvalidInputError(f"line {line_no}: pose p[{body}] is not numbers") from None
            if values.shape != (6,):
                raise InvalidInputError(f"line {line_no}: a pose has 6 values, got {len(values)}")
            poses.append(values)
        out.append((match.group(1) if match else "path", poses))
    return out


def script_numbers(text: str, name: str) -> np.ndarray | None:
    """The numbers of a script's list ``name = [..]`` (the first assignment), or None."""
    pattern = re.compile(rf"^\s*{re.escape(name)}\s*=\s*\[([^\]]*)\]\s*$")
    for line in text.splitlines():
        found = pattern.match(line)
        if found:
            return np.array([float(v) for v in found.group(1).split(",") if v.strip()])
    return None
