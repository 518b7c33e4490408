"""Guide points as a person leaves them: a seeded generator for the learning tests (issue 14).

A person teaching a wall records 6-14 points along it, wherever they happen to stop: on straight
runs, at the flank of a boss, near a corner, but never a point of their own at each outside
corner. Each point is 0-3 mm from the wall with the cutter free, or touching it (with or
without a push), at any height from resting on the floor (where a touch-off -Z leaves it) to
1 mm below the top, the tool tilted up to 8 deg and turned about its axis up to 25 deg.

The points are made directly (the pose, its joints by the inverse kinematics, the force the
wall or floor pushes back with from the contact model, plus the sensor's noise), not by a
simulated lead-through: the learning is under test here, the pushes have tests of their own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from robomach_core.cell import TOOL_DOWN, Cell, GuidePoint, cell_supervisor
from robomach_core.cell.simulator import CONTROL_PERIOD_S
from robomach_core.errors import RobomachError
from robomach_core.part import Contour, Workpiece

SENSOR_NOISE_N = 0.3
CLEARANCE_M = 0.003  # the spindle and shank stay this far from the part (supervision slows)


@dataclass(frozen=True)
class SloppySet:
    """One person's guide points and how they were made.

    Attributes:
        guides: The guide points in the order taught.
        forward: True when taught along the contour's stored direction (wall on the right).
        wall_side: The side the person says ("left"/"right"), or "auto".
        true_side: The side of the taught wall ("left"/"right") relative to travel.
        description: One line per point, for failure messages.
    """

    guides: list[GuidePoint]
    forward: bool
    wall_side: str
    true_side: str
    description: str


def _contour_point(contour: Contour, s: float) -> tuple[np.ndarray, np.ndarray]:
    """Point and unit tangent at arc length ``s`` (wrapped on a closed contour)."""
    if contour.closed:
        s = s % contour.length
    for piece in contour.pieces:
        if s <= piece.length or piece is contour.pieces[-1]:
            s_here = min(max(s, 0.0), piece.length)
            p = piece.point_at(np.array([s_here]))[0]
            q = piece.point_at(np.array([min(s_here + 1e-5, piece.length)]))[0]
            r = piece.point_at(np.array([max(s_here - 1e-5, 0.0)]))[0]
            t = q - r
            return p, t / np.linalg.norm(t)
        s -= piece.length
    raise AssertionError("unreachable")


def sloppy_guides(
    cell: Cell,
    rng: np.random.Generator,
    *,
    closed: bool = True,
    count: tuple[int, int] = (6, 14),
    max_gap_m: float = 0.003,
    max_tilt_deg: float = 8.0,
    max_yaw_deg: float = 25.0,
    floor_z_m: float | None = None,
    top_margin_m: float = 0.001,
    side_mode: str = "given",
    span_m: tuple[float, float] | None = None,
    yaw_follows_wall: bool = False,
) -> SloppySet:
    """A seeded set of sloppy guide points on ``cell.workpiece``'s known wall.

    Args:
        cell: The cell (its robot solves each point's joints, its contact model the force).
        rng: The seed's generator.
        closed: The whole loop (True) or an open stretch of it.
        count: Least and most points.
        max_gap_m: Largest gap between the cutter and the wall for a free point.
        max_tilt_deg: Largest tilt of the tool axis from the vertical.
        max_yaw_deg: Largest turn about the tool axis from the set's own orientation.
        floor_z_m: The lowest a point can rest, wobj z of the cutter's bottom (default: the
            wall's foot).
        top_margin_m: The highest a point sits below the top of the wall.
        side_mode: "given" (the person states the side) or "auto".
        span_m: For an open stretch, the arc-length range along the wall to teach.
        yaw_follows_wall: Turn the tool about its axis with the wall (its y axis towards the
            wall at every point, the old docs' rule): the wrist turns a full circle round a
            loop.
    """
    wp: Workpiece = cell.workpiece
    contour = wp.wall
    assert contour is not None, "sloppy guide points need a workpiece with a known wall"
    r = cell.tool.radius_m
    k_c = wp.contact_stiffness_N_m
    z_lo, z_hi = wp.wall_z_m
    floor = z_lo if floor_z_m is None else floor_z_m
    n = int(rng.integers(count[0], count[1] + 1))
    forward = bool(rng.random() < 0.5)
    L = contour.length
    if closed:
        start = rng.uniform(0.0, L)
        base = start + (np.arange(n) + rng.uniform(-0.3, 0.3, n)) * L / n
    else:
        lo, hi = span_m if span_m is not None else (0.008, L - 0.008)
        base = np.sort(rng.uniform(lo, hi, n))
        base[0], base[-1] = lo, hi
    if not forward:
        base = base[::-1] if not closed else (start - (base - start))
    # The person's own orientation for the whole set: yaw about the vertical, then per-point
    # sloppiness (tilt up to max_tilt_deg, turn up to max_yaw_deg).
    set_yaw = rng.uniform(-math.pi, math.pi)
    R_set = Rotation.from_euler("z", set_yaw) * Rotation.from_matrix(TOOL_DOWN)
    T = wp.T_base_wobj
    supervisor = cell_supervisor(cell)
    q_prev = cell.robot.home_rad.copy()
    guides: list[GuidePoint] = []
    lines = []
    for k, s in enumerate(base):
        c, t = _contour_point(contour, float(s))
        right = np.array([t[1], -t[0]])  # material side
        mode = rng.choice(["free", "free", "touch", "push"])
        if mode == "free":
            gap = rng.uniform(0.0, max_gap_m)
        elif mode == "touch":
            gap = rng.uniform(-0.00002, 0.0)
        else:
            gap = -rng.uniform(2.0, 10.0) / k_c
        height = rng.choice(["floor", "any"])
        if height == "floor":
            z = floor + r - rng.uniform(0.0, 5.0) / k_c  # resting, or pressed by a touch-off
        else:
            z = rng.uniform(floor + r, z_hi - top_margin_m)
        p_wobj = np.array([*(c - right * (r + gap)), z])
        tilt_axis = rng.uniform(-math.pi, math.pi)
        tilt = math.radians(rng.uniform(0.0, max_tilt_deg))
        R_tilt = Rotation.from_rotvec(
            tilt * np.array([math.cos(tilt_axis), math.sin(tilt_axis), 0])
        )
        yaw = math.radians(rng.uniform(-max_yaw_deg, max_yaw_deg))
        R_point = R_set
        if yaw_follows_wall:  # tool y towards the wall: x = y x z with y = right, z down
            y_tool = np.array([right[0], right[1], 0.0])
            z_tool = np.array([0.0, 0.0, -1.0])
            R_point = Rotation.from_matrix(
                np.column_stack([np.cross(y_tool, z_tool), y_tool, z_tool])
            )
        R_wobj = R_tilt * R_point * Rotation.from_euler("z", yaw)
        T_base_tcp = np.eye(4)
        T_base_tcp[:3, :3] = T[:3, :3] @ R_wobj.as_matrix()
        T_base_tcp[:3, 3] = T[:3, :3] @ p_wobj + T[:3, 3]
        q = None
        for _ in range(40):  # supervision stops the person's hand short of a collision
            try:
                q = cell.robot.ik(T_base_tcp, q_prev)
            except RobomachError:
                q = None
                break
            if float(supervisor.margins(q)[9:].min()) > CLEARANCE_M:
                break
            z += 0.001
            T_base_tcp[:3, 3] = T[:3, :3] @ np.array([*p_wobj[:2], z]) + T[:3, 3]
            q = None
        if q is None or z > z_hi:
            continue  # a point the person could not reach: they would move on
        q_prev = q
        T_meas = cell.robot.fk(q)
        contact = cell.contact_model.evaluate(T_meas, np.zeros(3), 0.0, CONTROL_PERIOD_S)
        force = contact.wrench[:3] + rng.normal(0.0, SENSOR_NOISE_N, 3)
        guides.append(GuidePoint(T_meas.copy(), q.copy(), float(k), force))
        lines.append(
            f"G{len(guides)}: s={s * 1e3:.0f} mm {mode} gap={gap * 1e3:.2f} mm "
            f"z={z * 1e3:.1f} mm tilt={math.degrees(tilt):.1f} yaw={math.degrees(yaw):.0f} "
            f"|F|={np.linalg.norm(contact.wrench[:3]):.1f} N"
        )
    true_side = "right" if forward else "left"
    wall_side = true_side if side_mode == "given" else "auto"
    return SloppySet(guides, forward, wall_side, true_side, "\n".join(lines))


def cornered_boss_stl() -> tuple[bytes, Contour]:
    """An uploaded part with sharp outside corners: a T-shaped boss, 8 mm high, on a plate.

    The boss's outline has six sharp outside corners (no fillet: the cutter rolls round them)
    and two inside corners filleted at 3 mm (larger than the cutter, as a casting has them).
    Returns the binary STL (mm) and the true wall in the work-object x-y plane (metres),
    travelled with the material on the right (clockwise round the boss).
    """
    import shapely.geometry
    import trimesh

    from robomach_core.part.contour import filleted_polygon

    # Clockwise outline of the T (metres); its corners' fillets: sharp outside, 3 mm inside.
    corners = np.array(
        [
            [-0.050, 0.010],
            [-0.050, 0.030],
            [0.050, 0.030],
            [0.050, 0.010],
            [0.012, 0.010],
            [0.012, -0.035],
            [-0.012, -0.035],
            [-0.012, 0.010],
        ]
    )
    radii = np.array([1e-5, 1e-5, 1e-5, 1e-5, 0.003, 1e-5, 1e-5, 0.003])
    outline = filleted_polygon(corners, radii)
    boss = trimesh.creation.extrude_polygon(shapely.geometry.Polygon(outline.sample(0.0004)), 0.008)
    boss.apply_translation([0.0, 0.0, 0.010])
    plate = trimesh.creation.box(extents=(0.14, 0.10, 0.010))
    plate.apply_translation([0.0, 0.0, 0.005])
    mesh = trimesh.util.concatenate([plate, boss])
    mesh.apply_scale(1e3)  # the file is in mm
    data = mesh.export(file_type="stl")
    # Travelled clockwise, the boss's material is on the right of travel.
    return data, outline
