"""Supervision of every commanded motion, as a robot controller has it.

PROBLEM   A person pushing or jogging the arm must never drive it through a joint limit, a
          singularity, the edge of its reach or into the table, the fixture or the part: at a
          singularity the one-step inverse kinematics asks for huge joint steps, jumps to another
          branch and the arm flips. A real controller slows down near such a limit and stops
          before it with a message that names the cause and the axis.
STRATEGY  Every limit is a margin m(q) >= 0 that shrinks towards it (a distance or an angle):
            - joint limits: min(q_i - lower_i, upper_i - q_i), and the combined limits of
              a parallel-bar arm (``Robot.couplings``: ABB's axis 3 = q2 + q3 in its range);
            - wrist singularity: the angle between axes 4 and 6 (parallel when axis 5 is at 0);
            - elbow singularity (the arm stretched, the edge of its reach): the angle between
              the upper arm and the forearm in the arm plane;
            - shoulder singularity: the distance of the wrist centre from the axis-1 line, in
              the arm plane (UR: sqrt(px^2 + py^2) = d4 in the analytic IK);
            - collisions: capsule clearances of the arm links and the tool (spindle, shank,
              cutter) to the table plane, the fixture boxes and the part's convex hull (GJK in
              the compiled period, ``_kernels.convex_clearance``; coal's depth when they
              overlap); the cutter against the part is contact, which pushes back
              (``contact.py``).
          A candidate step q -> q+ that shrinks a margin inside its slow zone [stop, slow] is
          scaled by ramp(m) = clip((m - stop) / (slow - stop), min_scale, 1); one that would
          end below ``stop`` while shrinking the margin is refused. Moving away from a limit is
          never slowed nor refused, so the user can always push back out. The inverse
          kinematics stays on its branch: no joint may move more than its velocity limit times
          the period in one step (the step is scaled down to fit, and refused if it cannot be),
          and a reference the arm cannot follow within ``tracking_stop_m`` is the edge of reach.
SOLUTION  ``Supervisor.supervise(q_now, propose) -> Supervised`` scales and checks one step of
          any controller (lead-through, jogging, path learning, MoveL); ``SupervisionStop``
          names the cause and its ``error()`` is the ``SupervisionError`` the API answers 409.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from ...errors import InvalidInputError, SupervisionError
from ...part import Workpiece
from ...part.bvh import placed_convex_hull
from ...robots.registry import DEFAULT_LINK_RADIUS_M
from ..clock import CONTROL_PERIOD_S
from ..robot import IK_STEP_DAMPING, Robot
from ..tool import Tool
from ._kernels import (
    MEMORY_MARGINS,
    chain_placements,
    decide,
    increment_proposal,
    margins_at,
    pack_model,
    supervise_increment,
)

SupervisionCause = Literal[
    "joint limit",
    "wrist singularity",
    "elbow singularity",
    "shoulder singularity",
    "edge of reach",
    "joint speed",
    "collision",
]
ARM_LINK_NAMES = ("upper arm", "forearm", "wrist 1", "wrist 2", "wrist 3")
GJK_MAX_CORNERS = 500  # a hull with more corners is measured by coal (``_measure_near``)
SPINDLE_RADIUS_M = 0.03  # the spindle body the GUIs draw (app/gui/arm.py ``tool_mesh``)
SHANK_LENGTH_M = 0.01  # between the cutter's flutes and the spindle body
SHANK_RADIUS_FRACTION = 0.8  # of the cutter radius
_NO_REFERENCE = np.eye(4)


@dataclass(frozen=True)
class SupervisionLimits:
    """Where supervision slows the motion down and where it stops it (SI units).

    Each limit has a stop value (refuse a step that would go past it) and a slow value (start
    scaling the speed down, linearly to ``min_speed_scale`` at the stop value).

    Attributes:
        joint_stop_rad / joint_slow_rad: Distance to a joint limit.
        wrist_stop_rad / wrist_slow_rad: Angle of axis 5 from 0 (axes 4 and 6 parallel).
        elbow_stop_rad / elbow_slow_rad: Angle of axis 3 from the stretched arm.
        shoulder_stop_m / shoulder_slow_m: Wrist centre's distance from the axis-1 line.
        arm_stop_m / arm_slow_m: Clearance of the arm links to the table, fixture and part.
        tool_stop_m / tool_slow_m: Clearance of the tool (cutter, shank, spindle body) to the
            table and fixture, and of its shank and body to the part.
        tracking_stop_m / tracking_stop_rad: The arm cannot follow its reference by more than
            this: the edge of reach.
        joint_speed_fraction: A step may move each joint by this fraction of its velocity
            limit times the period; more would leave the inverse kinematics' branch.
        min_speed_scale: The slowest speed, as a fraction, at a stop value (so the motion
            reaches the stop and is refused there instead of creeping towards it forever).
    """

    joint_stop_rad: float = math.radians(2.0)
    joint_slow_rad: float = math.radians(12.0)
    wrist_stop_rad: float = math.radians(3.0)
    wrist_slow_rad: float = math.radians(15.0)
    elbow_stop_rad: float = math.radians(5.0)
    elbow_slow_rad: float = math.radians(20.0)
    shoulder_stop_m: float = 0.05
    shoulder_slow_m: float = 0.20
    arm_stop_m: float = 0.01
    arm_slow_m: float = 0.04
    tool_stop_m: float = 0.0005
    tool_slow_m: float = 0.005
    tracking_stop_m: float = 0.002
    tracking_stop_rad: float = math.radians(2.0)
    joint_speed_fraction: float = 1.0
    min_speed_scale: float = 0.1

    def __post_init__(self) -> None:
        pairs = (
            ("joint", self.joint_stop_rad, self.joint_slow_rad),
            ("wrist", self.wrist_stop_rad, self.wrist_slow_rad),
            ("elbow", self.elbow_stop_rad, self.elbow_slow_rad),
            ("shoulder", self.shoulder_stop_m, self.shoulder_slow_m),
            ("arm", self.arm_stop_m, self.arm_slow_m),
            ("tool", self.tool_stop_m, self.tool_slow_m),
        )
        for name, stop, slow in pairs:
            if not (0.0 <= stop < slow and math.isfinite(slow)):
                raise InvalidInputError(
                    f"{name} supervision: the stop value must be >= 0 and below the slow value"
                )
        if not (0.0 < self.min_speed_scale <= 1.0):
            raise InvalidInputError("min_speed_scale must be in (0, 1]")
        if not (0.0 < self.joint_speed_fraction <= 1.0):
            raise InvalidInputError("joint_speed_fraction must be in (0, 1]")


@dataclass(frozen=True)
class FixtureBox:
    """A box of the fixture (clamps, vice, pallet): an obstacle for the arm and the tool.

    Attributes:
        size_m: (3,) edge lengths.
        T_base_box: 4x4 pose of the box centre in the robot base frame.
        name: Named in the stop message ("collision: tool with the {name}").
    """

    size_m: tuple[float, float, float]
    T_base_box: np.ndarray = field(default_factory=lambda: np.eye(4))
    name: str = "fixture"

    def __post_init__(self) -> None:
        if len(self.size_m) != 3 or not all(s > 0 and math.isfinite(s) for s in self.size_m):
            raise InvalidInputError("a fixture box has three positive, finite edge lengths")
        T = np.asarray(self.T_base_box, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InvalidInputError("a fixture box pose must be a finite 4x4 transform")


@dataclass(frozen=True)
class SupervisionStop:
    """Why supervision refused a step.

    Attributes:
        cause: The kind of limit.
        message: One line for the user, naming the cause and the axis or the bodies.
        axis: The axis concerned, 1-based (None for collisions and the edge of reach).
        value: The margin left at the refused step, in ``unit``.
        unit: ``"deg"`` or ``"mm"``.
    """

    cause: SupervisionCause
    message: str
    axis: int | None = None
    value: float = math.nan
    unit: str = ""

    def __str__(self) -> str:
        return self.message

    def error(self, state: Any = None) -> SupervisionError:
        """The ``SupervisionError`` of this stop, carrying ``state`` (the last safe state)."""
        return SupervisionError(
            self.message, cause=self.cause, axis=self.axis, stop=self, state=state
        )


class Supervised(NamedTuple):
    """One supervised step: the speed scale used, the reference and joints, or the stop."""

    scale: float
    T_ref: np.ndarray
    q_next: np.ndarray
    stop: SupervisionStop | None


@dataclass
class _Body:
    name: str
    joint: int  # pinocchio joint index the capsule is fixed to
    a: np.ndarray  # (3,) end points in the joint frame
    b: np.ndarray
    radius: float
    tool: bool
    touches_part: bool  # False for the cutter: its contact with the part is the contact model
    flat: bool  # a flat-ended cylinder (spindle, shank, cylinder cutter), else a capsule


@dataclass
class _Margin:
    kind: str  # "joint", "wrist", "elbow", "shoulder", "collision" or "coupling"
    stop: float
    slow: float
    index: int = -1  # joint index (0-based) or body index
    obstacle: int = -1  # -1 the table, then the part's hull (if any), then the fixture boxes


def _frame_of(axis: np.ndarray) -> np.ndarray:
    """A rotation whose z column is the unit ``axis`` (for coal's z-aligned capsules)."""
    z = axis
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _joint_axis_local(data: pin.Data, joint: int) -> np.ndarray:
    S = np.asarray(data.joints[joint].S).reshape(6, -1)[:, 0]
    w = S[3:]
    if np.linalg.norm(w) < 0.5:
        raise InvalidInputError(f"axis {joint} of the robot is not revolute; cannot supervise it")
    return w / np.linalg.norm(w)


class Supervisor:
    """Joint limits, singularities, reach and collisions of one robot in one cell.

    Holds its own kinematic data and coal shapes, built once. Thread-safe.

    Args:
        robot: The arm (its model, joint limits, velocity limits and TCP frame).
        tool: The tool: cutter radius, flute length and TCP offset give its capsules.
        workpiece: The part: its convex hull is an obstacle for the arm, the shank and the
            spindle; the lowest point of its mesh is the table height unless ``table_z_m``.
        limits: Slow and stop values.
        fixture: Boxes of the fixture.
        table_z_m: Height of the table plane in the base frame.
        dt: The control period the joint-speed bound is counted in.
    """

    def __init__(
        self,
        robot: Robot,
        tool: Tool | None = None,
        workpiece: Workpiece | None = None,
        *,
        limits: SupervisionLimits | None = None,
        fixture: Sequence[FixtureBox] = (),
        table_z_m: float | None = None,
        dt: float = CONTROL_PERIOD_S,
    ) -> None:
        model = robot.model
        if robot.nq != 6 or list(model.parents)[1:] != [0, 1, 2, 3, 4, 5]:
            raise InvalidInputError("supervision needs a serial 6-axis arm")
        self.robot = robot
        self.tool = tool or Tool()
        self.workpiece = workpiece
        self.limits = lim = limits or SupervisionLimits()
        self.fixture = tuple(fixture)
        self.dt = dt
        self._lock = threading.Lock()  # coal's request and result objects
        # The latest evaluations (joints' bytes, margins, TCP pose), newest first; replaced
        # whole, so threads share it without a lock.
        self._recent: tuple[tuple[bytes, np.ndarray, np.ndarray], ...] = ()
        # ``supervise_increment``'s own memory of its last step (joints, margins).
        self._memory_lock = threading.Lock()
        data = model.createData()
        pin.forwardKinematics(model, data, np.zeros(6))
        self._axes = np.array([_joint_axis_local(data, j) for j in range(1, 7)])
        self._placements = np.array([model.jointPlacements[j].homogeneous for j in range(1, 7)])
        tcp_frame = model.frames[robot.tcp_frame_id]
        flange_frame = model.frames[robot.flange_frame_id]
        if tcp_frame.parentJoint != 6 or flange_frame.parentJoint != 6:
            raise InvalidInputError("the TCP must sit on the sixth axis to be supervised")
        self._M_tcp = tcp_frame.placement.homogeneous.copy()
        self._step_bound = robot.velocity_limit_rad_s * dt * lim.joint_speed_fraction
        # UR-type arms have axis 4 parallel to axis 2: the elbow angle is measured to the
        # origin of axis 4; arms with a spherical wrist (axis 4 along the forearm): to the
        # wrist centre.
        z2 = data.oMi[2].rotation @ self._axes[1]
        z4 = data.oMi[4].rotation @ self._axes[3]
        self._elbow_to_axis4 = abs(float(z2 @ z4)) > 0.9
        self._bodies = self._make_bodies(flange_frame.placement.translation.copy())
        self._shapes = []
        self._body_frames = []  # (rotation taking z to the body axis, centre), joint frame
        for body in self._bodies:
            d = body.b - body.a
            length = float(np.linalg.norm(d))
            axis = d / length if length > 1e-9 else np.array([0.0, 0.0, 1.0])
            shape = coal.Cylinder if body.flat else coal.Capsule
            self._shapes.append(shape(body.radius, max(length, 1e-6)))
            self._body_frames.append((_frame_of(axis), 0.5 * (body.a + body.b)))
        vertices = None  # the part's vertices in the base frame: its hull is an obstacle
        if workpiece is not None:
            T_base_wobj = np.asarray(workpiece.T_base_wobj, dtype=float)
            vertices = workpiece.mesh.vertices @ T_base_wobj[:3, :3].T + T_base_wobj[:3, 3]
            if table_z_m is None:  # the part sits on the table
                table_z_m = float(vertices[workpiece.mesh.referenced_vertices, 2].min())
        self._table_z = float(table_z_m or 0.0)
        self._obstacles: list[tuple[str, Any, coal.Transform3s, np.ndarray]] = []
        self._corners: list[np.ndarray] = []  # per obstacle (N_o, 3): it is their convex hull
        if workpiece is not None and vertices is not None:
            # qhull's corners as the isolated mesh check found them on the part's own vertices
            hull, corners = placed_convex_hull(workpiece.mesh.vertices, vertices)
            box = np.concatenate([corners.min(axis=0), corners.max(axis=0)])
            self._obstacles.append(("workpiece", hull, coal.Transform3s(), box))
            # GJK's support point walks every corner; past a few hundred coal's is quicker.
            self._corners.append(corners if len(corners) <= GJK_MAX_CORNERS else corners[:0])
        for fixture_box in self.fixture:
            T = np.asarray(fixture_box.T_base_box, dtype=float)
            half = 0.5 * np.asarray(fixture_box.size_m, dtype=float)
            signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
            corners = (signs * half) @ T[:3, :3].T + T[:3, 3]
            self._corners.append(corners)
            self._obstacles.append(
                (
                    fixture_box.name,
                    coal.Box(*(2 * half)),
                    coal.Transform3s(T[:3, :3].copy(), T[:3, 3].copy()),
                    np.concatenate([corners.min(axis=0), corners.max(axis=0)]),
                )
            )
        self._couplings = robot.couplings
        self._margin_defs = self._make_margins()
        pairs = [(m.index, m.obstacle, m.slow) for m in self._margin_defs if m.kind == "collision"]
        firsts = np.cumsum([0, *(len(c) for c in self._corners)])[:-1]  # each obstacle's corners
        self._model = pack_model(
            placements=self._placements,
            axes=self._axes,
            limits=np.array([robot.lower_rad, robot.upper_rad]),
            M_tcp=self._M_tcp,
            step_bound=self._step_bound,
            tracking=np.array([lim.tracking_stop_m, lim.tracking_stop_rad]),
            bodies=np.array(
                [[b.joint - 1, *b.a, *b.b, b.radius, float(b.flat)] for b in self._bodies]
            ),
            pairs=np.array(pairs, dtype=float).reshape(-1, 3),
            obstacles=np.array(
                [
                    [*o[3], first, len(c)]
                    for o, c, first in zip(self._obstacles, self._corners, firsts, strict=True)
                ]
            ).reshape(-1, 8),
            vertices=np.concatenate([*self._corners, np.empty((0, 3))]),
            couplings=np.array(
                [[*c.coefficients, c.lower_rad, c.upper_rad] for c in self._couplings]
            ).reshape(-1, 8),
            thresholds=np.array(
                [[m.stop for m in self._margin_defs], [m.slow for m in self._margin_defs]]
            ),
            elbow_to_axis4=self._elbow_to_axis4,
            table_z=self._table_z,
            min_scale=lim.min_speed_scale,
            ik_damping=IK_STEP_DAMPING,
        )
        self._memory = np.full(MEMORY_MARGINS + len(self._margin_defs), np.nan)
        self._request = coal.DistanceRequest()
        self._result = coal.DistanceResult()
        self._T_capsule = coal.Transform3s()

    # --- construction --------------------------------------------------------------------

    def _make_bodies(self, flange_in_joint6: np.ndarray) -> list[_Body]:
        model, robot, tool = self.robot.model, self.robot, self.tool
        # The arm's capsules (upper arm, forearm, wrists 1-3): its record's radii.
        radii = robot.record.link_radii_m or (DEFAULT_LINK_RADIUS_M,) * 5
        bodies = []
        for k, name in enumerate(ARM_LINK_NAMES):
            joint = k + 2
            end = model.jointPlacements[joint + 1].translation.copy() if joint < 6 else None
            end = flange_in_joint6 if end is None else end
            bodies.append(_Body(name, joint, np.zeros(3), end, radii[k], False, True, False))
        # The tool, in the TCP frame (tool axis +z, the body towards -z), as the GUIs draw it:
        # cutter (the ball's capsule, or a cylinder), a thinner shank, the spindle body.
        M = self._M_tcp

        def in_joint6(p: np.ndarray) -> np.ndarray:
            return M[:3, :3] @ p + M[:3, 3]

        flange_in_tcp = np.linalg.inv(tool.T_flange_tcp)[:3, 3]
        cutter_top = np.array([0.0, 0.0, -tool.flute_length_m])
        shank_top = np.array([0.0, 0.0, -(tool.flute_length_m + SHANK_LENGTH_M)])
        r = tool.radius_m
        if float(np.linalg.norm(flange_in_tcp)) > float(np.linalg.norm(shank_top)) + 1e-3:
            bodies.append(
                _Body(
                    "tool (spindle)",
                    6,
                    in_joint6(flange_in_tcp),
                    in_joint6(shank_top),
                    SPINDLE_RADIUS_M,
                    True,
                    True,
                    True,
                )
            )
        bodies.append(
            _Body(
                "tool (shank)",
                6,
                in_joint6(cutter_top),
                in_joint6(shank_top),
                SHANK_RADIUS_FRACTION * r,
                True,
                # Not against the part: the shank is thinner than the cutter just below it, so
                # when the cutter presses on the wall the shank is 0.2 r from it; a slow zone
                # there would stop every approach to the wall short of contact.
                False,
                True,
            )
        )
        bodies.append(
            _Body(
                "tool",
                6,
                in_joint6(np.zeros(3)),
                in_joint6(cutter_top),
                r,
                True,
                False,
                tool.shape != "ball",
            )
        )
        return bodies

    def _make_margins(self) -> list[_Margin]:
        lim = self.limits
        defs = [_Margin("joint", lim.joint_stop_rad, lim.joint_slow_rad, j) for j in range(6)]
        defs.append(_Margin("wrist", lim.wrist_stop_rad, lim.wrist_slow_rad, 4))
        defs.append(_Margin("elbow", lim.elbow_stop_rad, lim.elbow_slow_rad, 2))
        defs.append(_Margin("shoulder", lim.shoulder_stop_m, lim.shoulder_slow_m, 0))
        for k, body in enumerate(self._bodies):
            stop, slow = (
                (lim.tool_stop_m, lim.tool_slow_m)
                if body.tool
                else (lim.arm_stop_m, lim.arm_slow_m)
            )
            defs.append(_Margin("collision", stop, slow, k, -1))
            for o in range(len(self._obstacles)):
                if o == 0 and self.workpiece is not None and not body.touches_part:
                    continue  # the cutter against the part is contact, not a collision
                defs.append(_Margin("collision", stop, slow, k, o))
        # Combined joint limits come last, after the kernel's margins (``_compute``).
        for k in range(len(self._couplings)):
            defs.append(_Margin("coupling", lim.joint_stop_rad, lim.joint_slow_rad, k))
        return defs

    @property
    def table_z_m(self) -> float:
        """Height of the table plane in the base frame."""
        return self._table_z

    # --- evaluation ----------------------------------------------------------------------

    def _evaluate(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(margins, TCP pose) at ``q``; a step's q_now and q_next are remembered."""
        key = q.tobytes()
        recent = self._recent
        for known, margins, T_tcp in recent:
            if known == key:
                return margins, T_tcp
        margins, T_tcp, _, n_near = margins_at(q, self._model)
        if n_near:
            self._measure_near(margins, T_tcp, q)
        self._recent = ((key, margins, T_tcp), *recent[:2])
        return margins, T_tcp

    def _measure_near(self, margins: np.ndarray, T_tcp: np.ndarray, q: np.ndarray) -> None:
        """Where the kernel left a clearance NaN (the body overlaps the obstacle, or the hull
        has too many corners for the kernel's GJK): coal's, a penetration depth when negative."""
        Ts = chain_placements(q, self._placements, self._axes)
        with self._lock:
            for i in np.flatnonzero(np.isnan(margins)):
                definition = self._margin_defs[i]
                body = self._bodies[definition.index]
                _, shape, T_obstacle, _ = self._obstacles[definition.obstacle]
                R_body, centre = self._body_frames[definition.index]
                T_joint = Ts[body.joint - 1]
                self._T_capsule.setRotation(T_joint[:3, :3] @ R_body)
                self._T_capsule.setTranslation(T_joint[:3, :3] @ centre + T_joint[:3, 3])
                self._result.clear()
                margins[i] = coal.distance(
                    shape,
                    T_obstacle,
                    self._shapes[definition.index],
                    self._T_capsule,
                    self._request,
                    self._result,
                )

    def joint_placements(self, q: np.ndarray) -> np.ndarray:
        """(6, 4, 4) placements of the joint frames in the base frame at ``q`` (rad)."""
        return chain_placements(np.asarray(q, dtype=float), self._placements, self._axes)

    def margins(self, q: np.ndarray) -> np.ndarray:
        """All margins at joints ``q`` (rad): joints (6), wrist, elbow, shoulder, clearances,
        then the combined joint limits (``Robot.couplings``) if the arm has any.

        Angles in radians, distances in metres; the clearances of far bodies are lower bounds
        (their bounding-box distance), exact within the slow zone.
        """
        q = np.asarray(q, dtype=float)
        if q.shape != (6,) or not np.all(np.isfinite(q)):
            raise InvalidInputError("joints must be 6 finite values [rad]")
        return self._evaluate(q)[0].copy()

    def limit_at(self, q: np.ndarray) -> SupervisionStop | None:
        """The limit a pose at joints ``q`` stands past (the stop a motion into it meets, named
        as ``supervise`` names it), or None when every margin is above its stop value: the
        smallest margin relative to its stop when several are crossed."""
        m = self.margins(q)
        stops = np.array([d.stop for d in self._margin_defs])
        over = (m - stops) / np.maximum(stops, 1e-9)
        i = int(np.argmin(over))
        if over[i] >= 0.0:
            return None
        return self._stop_for(2, i, float(m[i]), np.asarray(q, dtype=float))

    def describe(self, q: np.ndarray) -> dict[str, float]:
        """The nearest limits at ``q`` for a display: angles in deg, distances in mm."""
        m = self.margins(q)
        n_coupled = len(self._couplings)
        clearances = m[9 : len(m) - n_coupled]
        return {
            "joint_limit_deg": math.degrees(
                float(min([m[:6].min(), *(m[len(m) - n_coupled :] if n_coupled else ())]))
            ),
            "wrist_axis5_deg": math.degrees(float(m[6])),
            "elbow_axis3_deg": math.degrees(float(m[7])),
            "shoulder_mm": float(m[8]) * 1e3,
            "clearance_mm": float(clearances.min()) * 1e3 if len(clearances) else math.inf,
        }

    # --- the decision --------------------------------------------------------------------

    def _judge(
        self, q0: np.ndarray, q1: np.ndarray, T_ref: np.ndarray | None
    ) -> tuple[float, SupervisionStop | None]:
        if q1.shape != (6,) or not math.isfinite(float(q1 @ q1)):
            return 1.0, SupervisionStop(
                "edge of reach", "edge of reach: the inverse kinematics found no finite solution"
            )
        m1, T_tcp = self._evaluate(q1)
        track = T_ref is not None
        reference = _NO_REFERENCE if T_ref is None else T_ref
        scale, code, index, value = decide(
            self._evaluate(q0)[0], m1, q0, q1, reference, T_tcp, track,
            self._model,
        )  # fmt: skip
        return scale, None if code == 0 else self._stop_for(code, index, value, q1)

    def speed_scale(self, q_now: np.ndarray, q_next: np.ndarray) -> float:
        """Speed factor in (0, 1] for the step q_now -> q_next.

        The slow zones: ramp(m) = clip((m - stop) / (slow - stop), min_scale, 1) at the current
        margin of every limit the step approaches; and the joint-speed bound: a step that moves
        a joint further than its velocity limit in one period is scaled to fit it.
        """
        return self._judge(np.asarray(q_now, float), np.asarray(q_next, float), None)[0]

    def check(
        self, q_now: np.ndarray, q_next: np.ndarray, T_ref: np.ndarray | None = None
    ) -> SupervisionStop | None:
        """None when the step q_now -> q_next is allowed, else why it is refused.

        Refused: a non-finite or too large joint step (the IK would leave its branch); a step
        that ends past a stop value while it shrinks that margin; a reference ``T_ref`` the
        arm at ``q_next`` does not follow (the edge of reach).
        """
        T = None if T_ref is None else np.asarray(T_ref, dtype=float)
        return self._judge(np.asarray(q_now, float), np.asarray(q_next, float), T)[1]

    def supervise(
        self,
        q_now: np.ndarray,
        propose: Callable[[float], tuple[np.ndarray, np.ndarray]],
    ) -> Supervised:
        """Scale and check one controller step.

        Args:
            q_now: (6,) current motor-side joints.
            propose: ``propose(scale) -> (T_ref, q_next)``: the controller's reference and IK
                step when its motion this period is scaled by ``scale`` (1: as it wants).

        Returns:
            The scale used, the reference and joints to command, and the stop (None when the
            step is allowed; otherwise command nothing and stay at ``q_now``).
        """
        q0 = np.asarray(q_now, dtype=float)
        T_ref, q_next = propose(1.0)
        scale, stop = self._judge(q0, q_next, T_ref)
        if scale < 1.0:
            T_ref, q_next = propose(scale)
            stop = self._judge(q0, q_next, T_ref)[1]
        return Supervised(scale, T_ref, q_next, stop)

    def supervise_increment(
        self, q_now: np.ndarray, T_ref: np.ndarray, step: np.ndarray, turn: np.ndarray
    ) -> Supervised:
        """``supervise`` of a motion that moves the reference ``T_ref`` by ``step`` [m] and
        turns it by ``turn`` [rad, in its own axes], both scaled together, with one IK step
        from ``q_now`` (``_kernels.increment_proposal``): compiled whole, as path learning runs
        it every period; the same result as ``supervise``."""
        status = -1
        if self._memory_lock.acquire(blocking=False):  # else another thread runs it: Python
            try:
                status, scale, code, index, value, T_next, q_next = supervise_increment(
                    q_now, T_ref, step, turn, self._model, self._memory
                )
            finally:
                self._memory_lock.release()
        if status < 0:  # not finite, or near an obstacle: coal's clearance, in Python
            model = self._model
            T0, J0 = self.robot.fk_and_jacobian(q_now)

            def propose(scale: float) -> tuple[np.ndarray, np.ndarray]:
                return increment_proposal(q_now, T0, J0, T_ref, step, turn, scale, model)

            return self.supervise(q_now, propose)
        stop = None if code == 0 else self._stop_for(code, index, value, q_next)
        return Supervised(scale, T_next, q_next, stop)

    def _stop_for(self, code: int, i: int, value: float, q: np.ndarray) -> SupervisionStop:
        """The stop of a ``decide`` verdict ``code`` (1 joint speed, 2 margin, 3 tracking)."""
        if code == 1:
            return SupervisionStop(
                "joint speed",
                f"joint speed: axis {i + 1} would turn {math.degrees(value):.1f} deg in one "
                f"{self.dt * 1e3:.0f} ms period (limit {math.degrees(self._step_bound[i]):.2f} "
                "deg); refused to keep the arm on its inverse-kinematics branch",
                i + 1,
                math.degrees(value),
                "deg",
            )
        if code == 3:
            text = f"{value * 1e3:.1f} mm" if i == 0 else f"{math.degrees(value):.1f} deg"
            return SupervisionStop(
                "edge of reach",
                f"edge of reach: the arm cannot follow the tool's reference ({text} away)",
                None,
                value * 1e3 if i == 0 else math.degrees(value),
                "mm" if i == 0 else "deg",
            )
        m = self._margin_defs[i]
        if m.kind == "joint":
            j = m.index
            deg = math.degrees(float(q[j]))
            near_upper = q[j] - self.robot.lower_rad[j] > self.robot.upper_rad[j] - q[j]
            limit = self.robot.upper_rad[j] if near_upper else self.robot.lower_rad[j]
            return SupervisionStop(
                "joint limit",
                f"joint limit: axis {j + 1} at {deg:.1f} deg (limit {math.degrees(limit):.0f} deg)",
                j + 1,
                deg,
                "deg",
            )
        if m.kind == "coupling":
            c = self._couplings[m.index]
            deg = math.degrees(c.value(q))
            near_upper = c.upper_rad - c.value(q) < c.value(q) - c.lower_rad
            limit = math.degrees(c.upper_rad if near_upper else c.lower_rad)
            return SupervisionStop(
                "joint limit",
                f"joint limit: {c.description} at {deg:.1f} deg (limit {limit:.0f} deg)",
                c.axis,
                deg,
                "deg",
            )
        if m.kind == "wrist":
            deg = math.degrees(float(q[4]))
            return SupervisionStop(
                "wrist singularity", f"wrist singularity: axis 5 at {deg:.1f} deg", 5, deg, "deg"
            )
        if m.kind == "elbow":
            deg = math.degrees(float(q[2]))
            return SupervisionStop(
                "elbow singularity",
                f"elbow singularity (arm stretched, edge of reach): axis 3 at {deg:.1f} deg",
                3,
                deg,
                "deg",
            )
        if m.kind == "shoulder":
            deg = math.degrees(float(q[0]))
            return SupervisionStop(
                "shoulder singularity",
                f"shoulder singularity: wrist centre {value * 1e3:.0f} mm from the axis-1 line "
                f"(axis 1 at {deg:.1f} deg)",
                1,
                value * 1e3,
                "mm",
            )
        body = self._bodies[m.index].name
        obstacle = "table" if m.obstacle < 0 else self._obstacles[m.obstacle][0]
        return SupervisionStop(
            "collision",
            f"collision: {body} with the {obstacle} ({value * 1e3:.1f} mm clearance)",
            None,
            value * 1e3,
            "mm",
        )


_SUPERVISORS_LOCK = threading.Lock()
# The attribute of a ``Robot`` that keeps its cell's supervisor: (tool, workpiece, supervisor).
_KEPT_ON_ROBOT = "_cell_supervisor"


def cell_supervisor(cell: Any) -> Supervisor:
    """The supervisor of a cell's robot, tool and workpiece (built once per robot, reused).

    ``cell`` is a ``Cell`` or anything with its ``robot``, ``tool`` and ``workpiece``. The
    supervisor is kept on the robot itself, so it goes with the robot when the cell changes:
    a ``WeakKeyDictionary`` keyed by the robot kept every one, its value (the supervisor)
    holding its key (issue 32: 60 cell changes kept 61 supervisors and workpieces).
    """
    robot, tool, workpiece = cell.robot, cell.tool, cell.workpiece
    with _SUPERVISORS_LOCK:
        cached = getattr(robot, _KEPT_ON_ROBOT, None)
        if cached is not None and cached[0] is tool and cached[1] is workpiece:
            return cached[2]
        supervisor = Supervisor(robot, tool, workpiece)
        setattr(robot, _KEPT_ON_ROBOT, (tool, workpiece, supervisor))
        return supervisor


def forget_supervisor(robot: Any) -> None:
    """Drop the supervisor ``cell_supervisor`` kept on ``robot``, when its cell is replaced
    by one with another robot. The supervisor holds the robot, so the two (and the part's
    mesh and trees) form a cycle that only a full collection frees, and a server freezes its
    startup heap out of those (``gc.freeze``): the first cell's robot, supervisor and part
    stayed for the life of the server."""
    with _SUPERVISORS_LOCK:
        if hasattr(robot, _KEPT_ON_ROBOT):
            delattr(robot, _KEPT_ON_ROBOT)


def interpolate_pose(T0: np.ndarray, T1: np.ndarray, fraction: float) -> np.ndarray:
    """The pose ``fraction`` of the way from T0 to T1: p0 + f (p1 - p0), R0 exp(f log(R0^T R1))."""
    T = np.eye(4)
    T[:3, 3] = T0[:3, 3] + fraction * (T1[:3, 3] - T0[:3, 3])
    R0 = T0[:3, :3]
    T[:3, :3] = R0 @ pin.exp3(fraction * pin.log3(R0.T @ T1[:3, :3]))
    return T
