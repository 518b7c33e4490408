"""ABB RAPID export of a learned machining path.

PROBLEM: the post-processed path is a list of poses in the work-object frame (metres, rotation
matrices) with a joint solution and a feed speed each; an ABB controller wants a RAPID module in mm,
scalar-first quaternions, confdata quadrants and named speed/zone data, optionally wrapped in the
Force Control instructions of the chapter's section 3 (pressure along the path normal) and 4 (CMRR,
ABB's "FC SpeedChange").
STRATEGY: validate everything up front (one clear InvalidInputError), derive every name and number
deterministically (fixed decimals, sorted speeds, q1 >= 0), then emit plain text line by line.
SOLUTION: ``rapid_module(program)`` returns the module text; ``check_rapid_module`` in
``rapid_check`` parses it back and is run on every generated module in the tests.

Force Control syntax used (ABB Application manual "Force Control", as used in public RAPID code):
``FCCalib Load;``, ``FCPress1LStart ToPoint, Speed, \\Fx|\\Fy|\\Fz:=Force, ForceThreshold
[, \\ForceChange:=N/s] [, \\PosSupvDist:=mm], Zone, Tool\\WObj:=...;``,
``FCPressL ToPoint, Speed, Force, Zone, Tool\\WObj:=...;``, ``FCPressEnd ToPoint, Speed,
Tool\\WObj:=...;`` (its ToPoint is the point the robot leaves the surface towards, so it gets the
retract point), ``FCSpdChgTunSet SpeedLevels, SpeedRatioMin;``, ``FCSpdChgAct Reference;``,
``FCSpdChgDeact;``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from robomach_core.errors import InvalidInputError
from robomach_core.postprocess import Move, linear_moves, validate_moves
from robomach_core.robots import ABB_ARMS, ArmSpec
from robomach_core.transforms import quaternions_from_matrices

MAX_IDENTIFIER_LEN = 32
# mm: 0.1 um, so a corrected program's offsets are the simulated ones (a controller's
# float32 holds about 0.1 um at 2 m).
POSITION_DECIMALS = 4
QUATERNION_DECIMALS = 7  # 1e-7: a float32 near 1 holds it; the work object's frame exactly
SPEED_DECIMALS = 2  # mm/s (0.01 mm/s: a machining program's feeds exactly); speeddata names
ORTHONORMAL_TOL = 1e-6
DEFAULT_TOOL_INERTIA_KG_M2 = (0.001, 0.001, 0.001)
SPEEDDATA_V_ORI_DEG_S = 500.0  # reorientation, linear and rotating external axis speeds of
SPEEDDATA_V_LEAX_MM_S = 5000.0  # ABB's predefined v5..v1000, so only v_tcp limits the motion
SPEEDDATA_V_REAX_DEG_S = 1000.0
FCCALIB_SETTLE_S = 0.5  # wait in position before FCCalib so the sensor offset is taken at rest
UNUSED_EXTAX = "[9E9,9E9,9E9,9E9,9E9,9E9]"

RAPID_RESERVED_WORDS = frozenset(
    "ALIAS AND BACKWARD CASE CONNECT CONST DEFAULT DIV DO ELSE ELSEIF ENDFOR ENDFUNC ENDIF "
    "ENDMODULE ENDPROC ENDRECORD ENDTEST ENDTRAP ENDWHILE ERROR EXIT FALSE FOR FROM FUNC GOTO IF "
    "INOUT LOCAL MOD MODULE NOSTEPIN NOT NOVIEW OR PERS PROC RAISE READONLY RECORD RETRY RETURN "
    "STEP SYSMODULE TASK TEST THEN TO TRAP TRUE TRYNEXT UNDO VAR VIEWONLY WHILE WITH XOR".split()
)
_IDENT_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")

APPROACH_NAME = "p_approach"
RETRACT_NAME = "p_retract"
AIR_SPEED_NAME = "v_air"
ZONE_NAME = "z_path"


@dataclass(frozen=True, eq=False)
class RapidTool:
    """A tool (spindle + cutter) as RAPID tooldata held by the robot.

    Attributes:
        name: user name; sanitized into a RAPID identifier on export.
        T_flange_tcp: shape (4, 4), the TCP in the flange (tool0) frame [m].
        mass_kg: tool mass [kg], > 0.
        com_m: shape (3,), centre of mass in the flange frame [m].
        inertia_kg_m2: shape (3,), principal moments ix, iy, iz [kg*m^2] about the COM.
    """

    name: str
    T_flange_tcp: np.ndarray
    mass_kg: float
    com_m: np.ndarray
    inertia_kg_m2: np.ndarray = field(
        default_factory=lambda: np.array(DEFAULT_TOOL_INERTIA_KG_M2, dtype=float)
    )

    def __post_init__(self) -> None:
        _set(self, "T_flange_tcp", _transform(self.T_flange_tcp, "tool T_flange_tcp"))
        _set(self, "mass_kg", _positive(self.mass_kg, "tool mass_kg"))
        _set(self, "com_m", _vector(self.com_m, 3, "tool com_m"))
        inertia = _vector(self.inertia_kg_m2, 3, "tool inertia_kg_m2")
        if np.any(inertia < 0.0):
            raise InvalidInputError(f"tool inertia_kg_m2 must be >= 0, got {inertia.tolist()}")
        _set(self, "inertia_kg_m2", inertia)


@dataclass(frozen=True, eq=False)
class RapidWorkObject:
    """A work object: user frame ``T_base_wobj`` [m], object frame identity."""

    name: str
    T_base_wobj: np.ndarray

    def __post_init__(self) -> None:
        _set(self, "T_base_wobj", _transform(self.T_base_wobj, "work object T_base_wobj"))


@dataclass(frozen=True, eq=False)
class RapidTarget:
    """One path target.

    Attributes:
        T_wobj_target: shape (4, 4), target pose in the work-object frame [m].
        joints_rad: shape (6,), a joint solution reaching the target [rad]; gives the confdata.
        speed_mm_s: TCP speed of the move TO this target [mm/s], > 0.
        cfx: optional override of the configuration case 0..7 (e.g. computed with the real arm's
            geometry); by default it is derived from the joints, see ``confdata_from_joints``.
    """

    T_wobj_target: np.ndarray
    joints_rad: np.ndarray
    speed_mm_s: float
    cfx: int | None = None

    def __post_init__(self) -> None:
        _set(self, "T_wobj_target", _transform(self.T_wobj_target, "target T_wobj_target"))
        _set(self, "joints_rad", _vector(self.joints_rad, 6, "target joints_rad"))
        _set(self, "speed_mm_s", _positive(self.speed_mm_s, "target speed_mm_s"))
        if self.cfx is not None and (isinstance(self.cfx, bool) or self.cfx not in range(8)):
            raise InvalidInputError(f"target cfx must be an integer 0..7, got {self.cfx!r}")


@dataclass(frozen=True)
class ForceControlSettings:
    """Pressure (constant contact force) along the path, ABB FC Pressure.

    Attributes:
        force_N: contact force to press with [N], > 0, in the + direction of the tool axis below.
        force_direction: tool-frame axis the force acts along (the path normal Yp by default).
        load_name: name of the loaddata that FCCalib uses (the load on the sensor: the tool).
        force_threshold_percent: FCPress1LStart starts moving along the path when the contact
            force reaches this percentage of ``force_N``.
        force_change_N_s: force ramp rate at the start of pressing [N/s]; None leaves the default.
        pos_supv_dist_mm: position supervision distance of FCPress1LStart [mm]; None leaves it off.
    """

    force_N: float
    force_direction: Literal["x", "y", "z"] = "y"
    load_name: str = "load_fc"
    force_threshold_percent: float = 90.0
    force_change_N_s: float | None = 100.0
    pos_supv_dist_mm: float | None = None

    def __post_init__(self) -> None:
        _positive(self.force_N, "force_control force_N")
        if self.force_direction not in ("x", "y", "z"):
            raise InvalidInputError(
                f"force_direction must be 'x', 'y' or 'z', got {self.force_direction!r}"
            )
        pct = _finite(self.force_threshold_percent, "force_threshold_percent")
        if not 0.0 < pct <= 100.0:
            raise InvalidInputError(f"force_threshold_percent must be in (0, 100], got {pct}")
        if self.force_change_N_s is not None:
            _positive(self.force_change_N_s, "force_change_N_s")
        if self.pos_supv_dist_mm is not None:
            _positive(self.pos_supv_dist_mm, "pos_supv_dist_mm")


@dataclass(frozen=True)
class SpeedChangeSettings:
    """Feed-rate control (CMRR) by ABB FC SpeedChange: FCSpdChgTunSet + FCSpdChgAct.

    The controller lowers the programmed speed in ``speed_levels`` stages down to
    ``min_speed_ratio`` * programmed speed to keep the measured force at ``reference_force_N``
    (the paper's staged speed ratio, five stages 0.2..1.0 by default).

    Attributes:
        reference_force_N: force the feed-rate control holds [N], > 0.
        speed_levels: number of speed stages, >= 2 (2 = the two-stage switching control).
        min_speed_ratio: lowest speed as a fraction of the programmed speed, in (0, 1).
        load_name: loaddata for FCCalib when no ForceControlSettings gives one.
    """

    reference_force_N: float
    speed_levels: int = 5
    min_speed_ratio: float = 0.2
    load_name: str = "load_fc"

    def __post_init__(self) -> None:
        _positive(self.reference_force_N, "speed_change reference_force_N")
        if isinstance(self.speed_levels, bool) or not isinstance(self.speed_levels, int):
            raise InvalidInputError(f"speed_levels must be an integer, got {self.speed_levels!r}")
        if self.speed_levels < 2:
            raise InvalidInputError(f"speed_levels must be >= 2, got {self.speed_levels}")
        ratio = _finite(self.min_speed_ratio, "min_speed_ratio")
        if not 0.0 < ratio < 1.0:
            raise InvalidInputError(f"min_speed_ratio must be in (0, 1), got {ratio}")


@dataclass(frozen=True, eq=False)
class RapidProgram:
    """Everything one RAPID module needs.

    Attributes:
        module_name: user name of the module; sanitized.
        tool, wobj: the tooldata and wobjdata to declare and move with.
        targets: the path, at least one target.
        zone_mm: path zone radius [mm]; 0 means ``fine`` (stop at every target).
        approach_offset_mm: approach and retract points lie this far back along the tool z axis
            from the first and last target [mm].
        approach_speed_mm_s: speed of the approach and retract moves in the air [mm/s].
        max_moves_per_proc: longer paths are split into PROCs path_1, path_2, ... called from main.
        force_control: when set, the path is pressed with FCPress1LStart/FCPressL/FCPressEnd.
        speed_change: when set, the path moves are wrapped in FCSpdChgAct ... FCSpdChgDeact.
        monitor_config: False emits ``ConfL \\Off;`` so the controller does not stop on confdata
            mismatches (our confdata comes from the simulated arm); True keeps the ABB default.
        comment: header comment lines (generator, settings, ...).
        arm: the ABB arm whose geometry gives cfx (``confdata_from_joints``); None keeps the
            UR-branch rule.
        moves: optional motion sequence over the targets (``robomach_core.postprocess.Move``): a
            circular move to target k through via target j emits ``MoveC pj, pk``; None moves
            linearly to every target in order.
    """

    module_name: str
    tool: RapidTool
    wobj: RapidWorkObject
    targets: Sequence[RapidTarget]
    zone_mm: float = 0.5
    approach_offset_mm: float = 20.0
    approach_speed_mm_s: float = 100.0
    max_moves_per_proc: int = 200
    force_control: ForceControlSettings | None = None
    speed_change: SpeedChangeSettings | None = None
    monitor_config: bool = False
    comment: Sequence[str] = ()
    arm: str | None = None
    moves: Sequence[Move] | None = None

    def __post_init__(self) -> None:
        targets = tuple(self.targets)
        if not targets:
            raise InvalidInputError("a RAPID program needs at least one target")
        for i, target in enumerate(targets):
            if not isinstance(target, RapidTarget):
                raise InvalidInputError(f"target {i} is a {type(target).__name__}, not RapidTarget")
        _set(self, "targets", targets)
        if _finite(self.zone_mm, "zone_mm") < 0.0:
            raise InvalidInputError(f"zone_mm must be >= 0, got {self.zone_mm}")
        if _finite(self.approach_offset_mm, "approach_offset_mm") < 0.0:
            raise InvalidInputError(
                f"approach_offset_mm must be >= 0, got {self.approach_offset_mm}"
            )
        _positive(self.approach_speed_mm_s, "approach_speed_mm_s")
        n = self.max_moves_per_proc
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise InvalidInputError(f"max_moves_per_proc must be an integer >= 1, got {n!r}")
        if self.arm is not None:
            from robomach_core.cell import ROBOT_URDFS

            if self.arm.lower() not in ROBOT_URDFS:
                raise InvalidInputError(
                    f"unknown arm {self.arm!r} for confdata; choose one of "
                    f"{', '.join(sorted(ROBOT_URDFS))}"
                )
        moves = linear_moves(len(targets)) if self.moves is None else self.moves
        _set(self, "moves", validate_moves(moves, len(targets)))
        if isinstance(self.comment, str):
            _set(self, "comment", (self.comment,))
        else:
            _set(self, "comment", tuple(str(line) for line in self.comment))


# ---------------------------------------------------------------------------------------------
# Names, numbers, orientations


def rapid_identifier(name: str, *, prefix: str = "n") -> str:
    """Turn a user name into a valid RAPID identifier.

    Characters outside [A-Za-z0-9_] become '_'; a name not starting with a letter gets
    ``prefix + '_'`` in front; the result is cut to 32 characters; a reserved word gets a '_'
    appended.

    Raises:
        InvalidInputError: the name has no letter or digit (e.g. empty), or prefix is invalid.
    """
    if not isinstance(name, str):
        raise InvalidInputError(f"a RAPID name must be a string, got {type(name).__name__}")
    if not _IDENT_RE.match(prefix):
        raise InvalidInputError(f"identifier prefix {prefix!r} must start with a letter")
    text = re.sub(r"[^A-Za-z0-9_]", "_", name.strip())
    if not re.search(r"[A-Za-z0-9]", text):
        raise InvalidInputError(
            f"name {name!r} has no letter or digit and cannot be made a RAPID identifier"
        )
    if not ("a" <= text[0].lower() <= "z"):
        text = f"{prefix}_{text.lstrip('_')}"
    text = text[:MAX_IDENTIFIER_LEN]
    if text.upper() in RAPID_RESERVED_WORDS:
        text = text[: MAX_IDENTIFIER_LEN - 1] + "_"
    return text


def rapid_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix, RAPID sign convention.

    The sign is fixed so that the first component that is non-zero at ``QUATERNION_DECIMALS``
    decimals is positive (normally q1 = w >= 0), which makes the text output deterministic.

    Args:
        R: shape (3, 3), a proper rotation matrix.

    Returns:
        Shape (4,), q1..q4 with q1 = w.
    """
    return rapid_quaternions(np.asarray(R, dtype=float)[None])[0]


def rapid_quaternions(Rs: np.ndarray) -> np.ndarray:
    """``rapid_quaternion`` of each of (n, 3, 3) rotations, in one conversion: shape (n, 4)."""
    quats = quaternions_from_matrices(Rs)
    rounded = np.round(quats, QUATERNION_DECIMALS)
    for k, row in enumerate(rounded):
        for value in row:
            if value != 0.0:
                if value < 0.0:
                    quats[k] = -quats[k]
                break
    return quats


def confdata_from_joints(
    joints_rad: np.ndarray, *, cfx: int | None = None, arm: str | None = None
) -> tuple[int, ...]:
    """ABB confdata [cf1, cf4, cf6, cfx] from a joint solution.

    cf1, cf4, cf6 are the quadrants of axes 1, 4 and 6 as ABB defines them (RAPID reference,
    confdata): ``floor(angle_deg / 90)``, so 0..90 deg -> 0, 90..180 -> 1, -90..0 -> -1,
    -180..-90 -> -2 and 180..270 -> 2.

    cfx is ABB's configuration case 0..7 = 4*b + 2*e + w (``abb_cfx``): b = wrist centre behind
    axis 1, e = wrist centre behind the lower arm, w = axis 5 negative. With ``arm`` the name
    of an ABB arm (``"irb4400"``), they come from that arm's geometry. Without it (the UR arms,
    DH a2, a3 < 0), the UR analytic-IK branch is written in ABB's numbering:

    - b = 1 when ``cos(q2) + cos(q2 + q3) > 0``: the wrist centre's radial coordinate in the
      axis-1 frame, a2*cos(q2) + a3*cos(q2+q3), is negative (equal-link approximation of
      a2 ~ a3, exact in sign unless the arm is folded almost straight up);
    - e = 1 when ``sin(q3) < 0`` (elbow angle in (-180, 0) deg: UR's "elbow down" branch);
    - w = 1 when ``sin(q5) < 0`` (wrist flip).

    Args:
        joints_rad: shape (6,), joint angles [rad] in the arm's own zeros and directions.
        cfx: optional override of the configuration case.
        arm: an ABB arm name of ``robomach_core.robots.ABB_ARMS``; a UR arm or None keeps the
            UR rule above.

    Returns:
        (cf1, cf4, cf6, cfx) as ints.
    """
    q = _vector(joints_rad, 6, "joints_rad")
    cf1, cf4, cf6 = (int(math.floor(math.degrees(q[i]) / 90.0)) for i in (0, 3, 5))
    if cfx is None and arm is not None and arm.lower() in ABB_ARMS:
        cfx = abb_cfx(q, ABB_ARMS[arm.lower()])
    if cfx is None:
        behind = math.cos(q[1]) + math.cos(q[1] + q[2]) > 0.0
        elbow = math.sin(q[2]) < 0.0
        wrist = math.sin(q[4]) < 0.0
        cfx = 4 * int(behind) + 2 * int(elbow) + int(wrist)
    return (cf1, cf4, cf6, int(cfx))


def abb_wrist_centre_in_arm_plane(joints_rad: np.ndarray, arm: ArmSpec) -> np.ndarray:
    """(x, z) [m] of the wrist centre (axis 5) in the plane of the arm, x along axis 1's heading.

    Axis 2 sits at (sx, base_height + sz); the lower arm points along u = (sin q2, cos q2); the
    forearm, at angle q2 + q3, adds R_y(q2 + q3) (forearm, 0, elbow_offset) (module
    ``robots.abb`` gives the chain).
    """
    q = np.asarray(joints_rad, dtype=float)
    sx, sz = arm.shoulder_m
    t2, t23 = q[1], q[1] + q[2]
    return np.array(
        [
            sx
            + arm.upper_arm_m * math.sin(t2)
            + arm.elbow_offset_m * math.sin(t23)
            + arm.forearm_m * math.cos(t23),
            arm.base_height_m
            + sz
            + arm.upper_arm_m * math.cos(t2)
            + arm.elbow_offset_m * math.cos(t23)
            - arm.forearm_m * math.sin(t23),
        ]
    )


def abb_cfx(joints_rad: np.ndarray, arm: ArmSpec) -> int:
    """ABB's configuration case 0..7 of a joint solution on an ABB arm (RAPID confdata cfx).

    cfx = 4*b + 2*e + w, ABB's table: 0 = wrist centre in front of axis 1, in front of the lower
    arm, axis 5 positive; 1 = same with axis 5 negative; 2, 3 = behind the lower arm; 4..7 =
    behind axis 1. With w the wrist centre in the arm plane (``abb_wrist_centre_in_arm_plane``):
    b = 1 when w_x < 0; e = 1 when w lies behind the line of the lower arm (axis 2 -> axis 3),
    (w - p2) . n < 0 with the forward normal n = (cos q2, -sin q2); w = 1 when q5 < 0.
    """
    q = np.asarray(joints_rad, dtype=float)
    wrist = abb_wrist_centre_in_arm_plane(q, arm)
    shoulder = np.array([arm.shoulder_m[0], arm.base_height_m + arm.shoulder_m[1]])
    normal = np.array([math.cos(q[1]), -math.sin(q[1])])
    behind_axis1 = wrist[0] < 0.0
    behind_lower_arm = float((wrist - shoulder) @ normal) < 0.0
    axis5_negative = q[4] < 0.0
    return 4 * int(behind_axis1) + 2 * int(behind_lower_arm) + int(axis5_negative)


def _fixed(x: float, decimals: int) -> str:
    """Fixed-point text without a negative zero."""
    value = round(float(x), decimals) + 0.0
    return f"{value:.{decimals}f}"


def _short(x: float, decimals: int = 6) -> str:
    """Shortest fixed-point text up to ``decimals`` decimals ('5', '0.75', '-1.5')."""
    text = _fixed(x, decimals)
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _pose_literal(T: np.ndarray, q: np.ndarray | None = None) -> str:
    """``[[x,y,z],[q1,q2,q3,q4]]`` of a transform [m] in mm; ``q`` its ``rapid_quaternion``
    when already converted (a module's robtargets are converted together)."""
    pos = ",".join(_fixed(v * 1000.0, POSITION_DECIMALS) for v in T[:3, 3])
    q = rapid_quaternion(T[:3, :3]) if q is None else q
    quat = ",".join(_fixed(v, QUATERNION_DECIMALS) for v in q)
    return f"[[{pos}],[{quat}]]"


def _robtarget_literal(T: np.ndarray, conf: tuple[int, ...], q: np.ndarray | None = None) -> str:
    return f"[{_pose_literal(T, q)[1:-1]},[{','.join(str(c) for c in conf)}],{UNUSED_EXTAX}]"


def _loaddata_literal(tool: RapidTool) -> str:
    cog = ",".join(_fixed(v * 1000.0, POSITION_DECIMALS) for v in tool.com_m)
    inertia = ",".join(_short(v) for v in tool.inertia_kg_m2)
    return f"[{_short(tool.mass_kg, 3)},[{cog}],[1,0,0,0],{inertia}]"


def _speeddata_literal(v_tcp_mm_s: float) -> str:
    parts = (v_tcp_mm_s, SPEEDDATA_V_ORI_DEG_S, SPEEDDATA_V_LEAX_MM_S, SPEEDDATA_V_REAX_DEG_S)
    return "[" + ",".join(_short(p, SPEED_DECIMALS) for p in parts) + "]"


def _zonedata_literal(zone_mm: float) -> str:
    """Zone scaled like ABB's predefined z5..z200: orientation/axis zones 1.5x, angle 0.15x."""
    z = zone_mm
    values = (z, 1.5 * z, 1.5 * z, 0.15 * z, 1.5 * z, 0.15 * z)
    return "[FALSE," + ",".join(_short(v, 4) for v in values) + "]"


def _speed_key(speed_mm_s: float) -> float:
    """The speed rounded half up to ``SPEED_DECIMALS`` (7.25 -> 7.3, not banker's 7.2)."""
    scale = 10.0**SPEED_DECIMALS
    key = math.floor(speed_mm_s * scale + 0.5) / scale
    if key <= 0.0:
        raise InvalidInputError(
            f"speed {speed_mm_s} mm/s rounds to 0 at {SPEED_DECIMALS} decimal(s); use a larger one"
        )
    return key


def _speed_name(key: float) -> str:
    return "vp" + _short(key, SPEED_DECIMALS).replace(".", "_")


def _backed_off(T: np.ndarray, offset_mm: float) -> np.ndarray:
    """The pose moved back along its own z axis (the tool axis) by ``offset_mm``."""
    out = T.copy()
    out[:3, 3] = T[:3, 3] - T[:3, 2] * (offset_mm / 1000.0)
    return out


def _comment(text: str) -> str:
    """One RAPID comment line body: printable ASCII only."""
    return "".join(ch if " " <= ch <= "~" else "?" for ch in text).rstrip()


# ---------------------------------------------------------------------------------------------
# The generator


def rapid_module(program: RapidProgram) -> str:
    """The complete RAPID module text of a program (deterministic, ASCII, LF line ends).

    Args:
        program: the validated program description.

    Returns:
        Module text ending with a newline.

    Raises:
        InvalidInputError: a name cannot be made valid or collides with a generated name, or a
            speed rounds to zero.
    """
    fc, sc = program.force_control, program.speed_change
    module = rapid_identifier(program.module_name, prefix="m")
    tool = rapid_identifier(program.tool.name, prefix="t")
    wobj = rapid_identifier(program.wobj.name, prefix="w")
    load = None
    if fc is not None:
        load = rapid_identifier(fc.load_name, prefix="l")
    elif sc is not None:
        load = rapid_identifier(sc.load_name, prefix="l")

    assert program.moves is not None  # __post_init__ fills None with one MoveL per target
    targets = program.targets
    n = len(targets)
    n_moves = len(program.moves)
    chunks = [
        range(i, min(i + program.max_moves_per_proc, n_moves))
        for i in range(0, n_moves, program.max_moves_per_proc)
    ]
    speed_keys = sorted({_speed_key(t.speed_mm_s) for t in targets})
    air_key = _speed_key(program.approach_speed_mm_s)
    zone = ZONE_NAME if program.zone_mm > 0.0 else "fine"

    generated = ["fine", "tool0", "wobj0", "load0", "main"]
    generated += [APPROACH_NAME, RETRACT_NAME, AIR_SPEED_NAME, ZONE_NAME]
    generated += [f"p{i + 1}" for i in range(n)] + [_speed_name(k) for k in speed_keys]
    if len(chunks) > 1:
        generated += [f"path_{k + 1}" for k in range(len(chunks))]
    _check_collisions(
        {"module": module, "tool": tool, "work object": wobj, "load": load}, generated
    )

    lines = [f"MODULE {module}"]
    lines += _header_lines(program, tool, wobj)
    lines += _data_lines(program, tool, wobj, load, air_key, speed_keys, zone)
    tool_arg = f"{tool}\\WObj:={wobj}"
    moves = [_move_line(move, targets, zone, tool_arg, fc) for move in program.moves]
    lines.append("")
    lines += _proc("main", _main_body(program, tool_arg, load, moves, len(chunks)))
    if len(chunks) > 1:
        for k, chunk in enumerate(chunks):
            lines.append("")
            lines += _proc(f"path_{k + 1}", [moves[i] for i in chunk])
    lines.append("ENDMODULE")
    return "\n".join(lines) + "\n"


def _header_lines(program: RapidProgram, tool: str, wobj: str) -> list[str]:
    fc, sc = program.force_control, program.speed_change
    n = len(program.targets)
    assert program.moves is not None  # __post_init__ fills None with one MoveL per target
    n_arcs = sum(move.via is not None for move in program.moves)
    lines = [f"  ! Generated by robomach: {n} targets, tool {tool}, work object {wobj}."]
    if n_arcs:
        lines.append(f"  ! {len(program.moves)} moves, {n_arcs} of them circular (MoveC).")
    lines += [f"  ! {_comment(c)}".rstrip() for c in program.comment]
    if fc is not None:
        lines.append(
            f"  ! Force control: press {_short(fc.force_N)} N along tool {fc.force_direction}."
        )
    if sc is not None:
        lines.append(
            f"  ! Speed change: reference {_short(sc.reference_force_N)} N, "
            f"{sc.speed_levels} levels, min ratio {_short(sc.min_speed_ratio)}."
        )
    return lines


def _data_lines(
    program: RapidProgram,
    tool: str,
    wobj: str,
    load: str | None,
    air_key: float,
    speed_keys: list[float],
    zone: str,
) -> list[str]:
    """Declarations: tooldata, wobjdata, loaddata, speeddata, zonedata, robtargets."""
    t = program.tool
    tframe = _pose_literal(t.T_flange_tcp)[1:-1]
    uframe = _pose_literal(program.wobj.T_base_wobj)
    lines = [
        f"  PERS tooldata {tool} := [TRUE,[{tframe}],{_loaddata_literal(t)}];",
        f'  PERS wobjdata {wobj} := [FALSE,TRUE,"",{uframe},[[0,0,0],[1,0,0,0]]];',
    ]
    if load is not None:
        lines.append(f"  PERS loaddata {load} := {_loaddata_literal(t)};")
    lines.append(f"  CONST speeddata {AIR_SPEED_NAME} := {_speeddata_literal(air_key)};")
    for key in speed_keys:
        lines.append(f"  CONST speeddata {_speed_name(key)} := {_speeddata_literal(key)};")
    if zone != "fine":
        lines.append(f"  CONST zonedata {ZONE_NAME} := {_zonedata_literal(program.zone_mm)};")

    targets = program.targets
    first, last = targets[0], targets[-1]
    offset = program.approach_offset_mm
    named = [(APPROACH_NAME, _backed_off(first.T_wobj_target, offset), first)]
    named += [(f"p{i + 1}", t.T_wobj_target, t) for i, t in enumerate(targets)]
    named.append((RETRACT_NAME, _backed_off(last.T_wobj_target, offset), last))
    quats = rapid_quaternions(np.array([T[:3, :3] for _, T, _ in named]))
    for (name, T, target), q in zip(named, quats, strict=True):
        conf = confdata_from_joints(target.joints_rad, cfx=target.cfx, arm=program.arm)
        lines.append(f"  CONST robtarget {name} := {_robtarget_literal(T, conf, q)};")
    return lines


def _main_body(
    program: RapidProgram, tool_arg: str, load: str | None, moves: list[str], n_procs: int
) -> list[str]:
    """PROC main: approach, FC calibration, speed change on, the path, off, retract."""
    fc, sc = program.force_control, program.speed_change
    body = [] if program.monitor_config else ["ConfL \\Off;"]
    body.append(f"MoveJ {APPROACH_NAME}, {AIR_SPEED_NAME}, fine, {tool_arg};")
    if load is not None:
        body.append(f"WaitTime \\InPos, {_short(FCCALIB_SETTLE_S)};")
        body.append(f"FCCalib {load};")
    if sc is not None:
        body.append(f"FCSpdChgTunSet {sc.speed_levels}, {_short(sc.min_speed_ratio)};")
        body.append(f"FCSpdChgAct {_short(sc.reference_force_N)};")
    body += moves if n_procs == 1 else [f"path_{k + 1};" for k in range(n_procs)]
    if sc is not None:
        body.append("FCSpdChgDeact;")
    if fc is not None:
        body.append(f"FCPressEnd {RETRACT_NAME}, {AIR_SPEED_NAME}, {tool_arg};")
    else:
        body.append(f"MoveL {RETRACT_NAME}, {AIR_SPEED_NAME}, fine, {tool_arg};")
    return body


def _move_line(
    move: Move,
    targets: Sequence[RapidTarget],
    zone: str,
    tool_arg: str,
    fc: ForceControlSettings | None,
) -> str:
    """The instruction of one move: MoveL / MoveC, or FCPressL / FCPressC when pressing.

    ``MoveC CirPoint, ToPoint, ...`` moves on the circle through the current position, the
    circle point and the end point (RAPID reference, MoveC); ``FCPressC`` is its pressing form.
    """
    i = move.to
    name, speed = f"p{i + 1}", _speed_name(_speed_key(targets[i].speed_mm_s))
    via = None if move.via is None else f"p{move.via + 1}"
    if fc is None:
        if via is not None:
            return f"MoveC {via}, {name}, {speed}, {zone}, {tool_arg};"
        return f"MoveL {name}, {speed}, {zone}, {tool_arg};"
    force = _short(fc.force_N)
    if via is not None:
        return f"FCPressC {via}, {name}, {speed}, {force}, {zone}, {tool_arg};"
    if i > 0:
        return f"FCPressL {name}, {speed}, {force}, {zone}, {tool_arg};"
    options = ""
    if fc.force_change_N_s is not None:
        options += f", \\ForceChange:={_short(fc.force_change_N_s)}"
    if fc.pos_supv_dist_mm is not None:
        options += f", \\PosSupvDist:={_short(fc.pos_supv_dist_mm)}"
    direction = "\\F" + fc.force_direction
    threshold = _short(fc.force_threshold_percent)
    return (
        f"FCPress1LStart {name}, {speed}, {direction}:={force}, {threshold}{options}, "
        f"{zone}, {tool_arg};"
    )


def _proc(name: str, body: list[str]) -> list[str]:
    return [f"  PROC {name}()"] + [f"    {line}" for line in body] + ["  ENDPROC"]


def _check_collisions(user: dict[str, str | None], generated: list[str]) -> None:
    """RAPID names are case-insensitive: user names must differ from each other and ours."""
    taken = {g.upper(): f"the generated name {g!r}" for g in generated}
    for role, name in user.items():
        if name is None:
            continue
        if name.upper() in taken:
            raise InvalidInputError(
                f"{role} name {name!r} collides with {taken[name.upper()]} (RAPID names ignore "
                "case); choose another name"
            )
        taken[name.upper()] = f"the {role} name {name!r}"


def write_rapid_module(program: RapidProgram, path: str | Path) -> Path:
    """Write ``rapid_module(program)`` to ``path`` (ASCII, LF line ends) and return the path."""
    out = Path(path)
    out.write_text(rapid_module(program), encoding="ascii", newline="\n")
    return out


# ---------------------------------------------------------------------------------------------
# Validation helpers


def _set(obj: object, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)


def _finite(x: float, what: str) -> float:
    try:
        value = float(x)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what} must be a number, got {x!r}") from exc
    if not math.isfinite(value):
        raise InvalidInputError(f"{what} must be finite, got {value}")
    return value


def _positive(x: float, what: str) -> float:
    value = _finite(x, what)
    if value <= 0.0:
        raise InvalidInputError(f"{what} must be > 0, got {value}")
    return value


def _vector(x: np.ndarray, n: int, what: str) -> np.ndarray:
    try:
        arr = np.array(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what} must be {n} numbers") from exc
    if arr.shape != (n,):
        raise InvalidInputError(f"{what} must have shape ({n},), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"{what} must be finite, got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


def _transform(T: np.ndarray, what: str) -> np.ndarray:
    """A read-only copy of a 4x4 homogeneous transform with a proper rotation."""
    try:
        arr = np.array(T, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what} must be a 4x4 matrix") from exc
    if arr.shape != (4, 4):
        raise InvalidInputError(f"{what} must have shape (4, 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"{what} has non-finite entries")
    if np.max(np.abs(arr[3] - (0.0, 0.0, 0.0, 1.0))) > ORTHONORMAL_TOL:
        raise InvalidInputError(f"{what} last row must be [0, 0, 0, 1], got {arr[3].tolist()}")
    R = arr[:3, :3]
    err = float(np.max(np.abs(R.T @ R - np.eye(3))))
    if err > ORTHONORMAL_TOL:
        raise InvalidInputError(
            f"{what} rotation is not orthonormal (max |R^T R - I| = {err:.3g} > "
            f"{ORTHONORMAL_TOL:g})"
        )
    if np.linalg.det(R) < 0.0:
        raise InvalidInputError(f"{what} rotation is a reflection (det = -1), not a rotation")
    arr.setflags(write=False)
    return arr
