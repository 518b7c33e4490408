"""People's guide points on any generated part (issue 28): tests/sloppy_guides.py generalised
from the built-in contour to every wall of ``envelope_parts``.

A person teaching a wall records 6-14 points along it (a loop, or a stretch of it), wherever
they stop, with no point of their own at corners. Each point is 0-3 mm off the wall with the
cutter free, touching it, or pushing 2-10 N; from resting on the floor (a touch-off leaves it
pressed) to 1 mm below the top; the tool tilted up to 8 deg and turned up to 25 deg about its
axis, whose nominal direction is the job's (vertical, or normal to a tilted plate). The side is
given or left to "auto". Some sets are sparse (4-5 points on a loop); in a groove, some have
points nearer the other wall (the side then given: the explicit setting names the taught wall).

Points are made directly (pose, joints by the inverse kinematics, the force the part pushes
back with from the contact model plus the sensor's noise), not by a simulated lead-through.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from robomach_core.cell import TOOL_DOWN, Cell, GuidePoint, cell_supervisor
from robomach_core.cell.simulator import CONTROL_PERIOD_S
from robomach_core.errors import RobomachError
from tests.envelope_parts import EnvelopePart, TrueWall

SENSOR_NOISE_N = 0.3
CLEARANCE_M = 0.003  # the spindle and shank stay this far from the part (supervision slows)
FLOOR_CLEARANCE_MM = 0.5  # PathLearningSettings' default: a point on the floor is taught there
OTHER_MARGIN_MM = 0.15  # a point "nearer the other wall" is nearer it by at least this


@dataclass(frozen=True)
class PeopleSet:
    """One person's guide points and how they were made.

    Attributes:
        guides: The guide points in the order taught.
        part: The part's name.
        wall: The taught wall's name.
        closed: Learned as a loop (the learning setting).
        wall_side: The side the person says ("left"/"right") or "auto".
        true_side: The taught wall's side of travel.
        s_mm: (n,) arc length along the taught wall of each point's foot.
        heights_mm: (n,) each point's height in the part's frame (lifted off the floor by the
            floor clearance, as taught for machining).
        description: One line for the set and one per point, for failure messages.
        stretch_mm: (s0, s1) the stretch of the wall taught, in the wall's own direction
            from its first point's foot to its last's; None: the whole loop.
    """

    guides: list[GuidePoint]
    part: str
    wall: str
    closed: bool
    wall_side: str
    true_side: str
    s_mm: np.ndarray
    heights_mm: np.ndarray
    description: str
    stretch_mm: tuple[float, float] | None = None


def nominal_rotation(part: EnvelopePart, cell: Cell) -> np.ndarray:
    """The job's tool orientation (base frame): the example operator's, its axis along the
    part's tool axis (vertical, or normal to the plate)."""
    if part.tool_axis == "vertical":
        return TOOL_DOWN.copy()
    return part.R_base_part(cell.workpiece) @ TOOL_DOWN


def place_points(
    part: EnvelopePart,
    cell: Cell,
    wall_name: str,
    s_mm: np.ndarray,
    gaps_mm: np.ndarray,
    heights_mm: np.ndarray,
    rotations: list[np.ndarray],
    rng: np.random.Generator,
) -> tuple[list[GuidePoint], list[int], list[str]]:
    """Guide points whose cutters stand ``gaps_mm`` off the wall (negative: pressed into it)
    at part-frame heights ``heights_mm``; a point supervision keeps off the part is raised
    along the part's axis, one the arm cannot reach is dropped (the person moves on).

    Returns the points, the indices of the ``s_mm`` kept, and a line per point."""
    wall = part.walls[wall_name]
    wp = cell.workpiece
    r_mm = cell.tool.radius_m * 1e3
    supervisor = cell_supervisor(cell)
    q_prev = cell.robot.home_rad.copy()
    guides, kept, lines = [], [], []
    for k, s in enumerate(s_mm):
        c, t, floor = wall.at(float(s))
        free = np.array([-t[1], t[0]])
        z = float(heights_mm[k])
        xy = _stand_off(wall, c + free * (r_mm + gaps_mm[k]), r_mm + gaps_mm[k])
        T = np.eye(4)
        T[:3, :3] = rotations[k]
        q = None
        while z <= wall.top_mm:
            T[:3, 3] = part.to_base_m(wp, np.array([[*xy, z]]))[0]
            try:
                q = cell.robot.ik(T, q_prev)
            except RobomachError:
                q = None
                break
            if float(supervisor.margins(q)[9:].min()) > CLEARANCE_M:
                break
            q, z = None, z + 1.0
        if q is None:
            continue
        q_prev = q
        T_meas = cell.robot.fk(q)
        contact = cell.contact_model.evaluate(T_meas, np.zeros(3), 0.0, CONTROL_PERIOD_S)
        force = contact.wrench[:3] + rng.normal(0.0, SENSOR_NOISE_N, 3)
        guides.append(GuidePoint(T_meas.copy(), q.copy(), float(k), force))
        kept.append(k)
        p_part = part.to_part_mm(wp, T_meas[:3, 3][None])
        gap_now = float(wall.signed_distance(p_part)[0][0]) - r_mm
        other = ""
        if wall.other is not None:
            d_other = float(part.walls[wall.other].signed_distance(p_part)[0][0]) - r_mm
            other = f" other={d_other:.2f}"
        lines.append(
            f"G{len(guides)}: s={s:.0f} gap={gap_now:.2f}{other} z={z - floor:.1f} above floor "
            f"|F|={np.linalg.norm(contact.wrench[:3]):.1f} N"
        )
    return guides, kept, lines


def _from_the_feet(
    wall: TrueWall, nominal_mm: tuple[float, float], feet_mm: tuple[float, float]
) -> tuple[float, float]:
    """The taught stretch from its end points' feet (each point's nearest wall vertex): a
    point placed off the wall along the normal at its station can stand nearer another part
    of the wall (in an inside corner's fillet, the next face), and the wall between that foot
    and the station is not taught by it. An end only moves inwards, by under half the
    stretch."""
    s0, s1 = nominal_mm
    length = (s1 - s0) % wall.length_mm if wall.closed else s1 - s0
    wrap = wall.length_mm if wall.closed else math.inf
    into_0 = (feet_mm[0] - s0) % wrap
    into_1 = (s1 - feet_mm[1]) % wrap
    if 0.0 < into_0 < length / 2.0:
        s0 = feet_mm[0]
    if 0.0 < into_1 < length / 2.0:
        s1 = feet_mm[1]
    return (s0, s1)


def _stand_off(wall: TrueWall, xy: np.ndarray, distance_mm: float) -> np.ndarray:
    """``xy`` moved until the nearest point of the wall is ``distance_mm`` away: in an inside
    corner tighter than that, the other side of the corner stops the hand too."""
    for _ in range(8):
        i = wall.nearest(xy)[0]
        xy = wall.xy_mm[i] + wall.free_normals[i] * distance_mm
    return xy


def _sloppy_rotations(
    R_nominal: np.ndarray, n: int, rng: np.random.Generator, max_tilt_deg: float, max_yaw_deg: float
) -> tuple[list[np.ndarray], list[str]]:
    """The set's own turn about the axis, then per point a tilt off it and a turn about it."""
    R_set = R_nominal @ Rotation.from_euler("z", rng.uniform(-math.pi, math.pi)).as_matrix()
    out, notes = [], []
    for _ in range(n):
        phi = rng.uniform(-math.pi, math.pi)
        tilt = math.radians(rng.uniform(0.0, max_tilt_deg))
        u = R_set[:, 0] * math.cos(phi) + R_set[:, 1] * math.sin(phi)
        yaw = math.radians(rng.uniform(-max_yaw_deg, max_yaw_deg))
        R = Rotation.from_rotvec(u * tilt).as_matrix() @ R_set
        out.append(R @ Rotation.from_euler("z", yaw).as_matrix())
        notes.append(f"tilt={math.degrees(tilt):.1f} yaw={math.degrees(yaw):.0f}")
    return out, notes


def _stations(
    wall: TrueWall, rng: np.random.Generator, n: int, closed: bool, span_mm: tuple[float, float]
) -> np.ndarray:
    """Arc lengths of ``n`` points along travel: round the loop, or over ``span_mm``."""
    if closed:
        start = rng.uniform(0.0, wall.length_mm)
        return start + (np.arange(n) + rng.uniform(-0.3, 0.3, n)) * wall.length_mm / n
    lo, hi = span_mm
    s = np.sort(rng.uniform(lo, hi, n))
    s[0], s[-1] = lo, hi
    return s


def people_points(
    part: EnvelopePart,
    cell: Cell,
    rng: np.random.Generator,
    *,
    wall: str,
    closed: bool = True,
    forward: bool | None = None,
    count: tuple[int, int] = (6, 14),
    span_mm: tuple[float, float] | None = None,
    learn_closed: bool | None = None,
    side_mode: str = "given",
    max_gap_mm: float = 3.0,
    nearer_other: int = 0,
    max_tilt_deg: float = 8.0,
    max_yaw_deg: float = 25.0,
    top_margin_mm: float = 1.0,
    pushes: int = 0,
) -> PeopleSet:
    """A seeded set of people's points on ``part``'s wall ``wall`` (module docstring).

    Args:
        wall: The taught wall.
        closed: Points round the whole loop (True) or over ``span_mm`` of the wall.
        forward: Along the wall's travel (the wall on the right); default drawn.
        count: Least and most points.
        span_mm: For an open stretch, the arc lengths taught (default drawn: 60-200 mm).
        learn_closed: The route's setting (default: ``closed``); True on an open stretch is
            an open wall taught as a loop.
        side_mode: "given" (the person states the side) or "auto".
        max_gap_mm: Largest gap between the cutter and the wall; in a groove also less than
            half its free width, so the point is nearer the taught wall.
        nearer_other: Points placed nearer the groove's other wall (free or touching it).
        pushes: At least this many points push the taught wall (drawn among the others).
        max_tilt_deg, max_yaw_deg: Tool tilt off the job's axis and turn about it.
        top_margin_mm: The highest a point sits below the top of the wall.
    """
    w = part.walls[wall]
    r_mm = cell.tool.radius_m * 1e3
    k_c = cell.workpiece.contact_stiffness_N_m * 1e-3  # N/mm
    n = int(rng.integers(count[0], count[1] + 1))
    forward = bool(rng.random() < 0.5) if forward is None else forward
    loop = closed and w.closed
    if not loop and span_mm is None:
        if w.closed:
            lo = rng.uniform(0.0, w.length_mm)
            span_mm = (lo, lo + rng.uniform(60.0, min(200.0, 0.7 * w.length_mm)))
        else:
            span_mm = (8.0, w.length_mm - 8.0)
    s = _stations(w, rng, n, loop, span_mm or (0.0, w.length_mm))
    if not forward:
        s = s[::-1]
    gap_cap = max_gap_mm
    if w.free_mm is not None:
        gap_cap = min(max_gap_mm, (w.free_mm - 2 * r_mm) / 2 - OTHER_MARGIN_MM)
    modes = rng.choice(np.array(["free", "free", "touch", "push"], dtype=object), n)
    if pushes:
        modes[rng.choice(n, size=min(pushes, n), replace=False)] = "push"
    gaps = np.where(
        modes == "free",
        rng.uniform(0.0, gap_cap, n),
        np.where(modes == "touch", rng.uniform(-0.00002, 0.0, n), -rng.uniform(2.0, 10.0, n) / k_c),
    )
    if nearer_other and w.free_mm is not None:
        width = w.free_mm - 2 * r_mm  # the free space the cutter's surface can take
        others = rng.choice(n, size=min(nearer_other, n), replace=False)
        gaps[others] = rng.uniform(width / 2 + OTHER_MARGIN_MM, width, len(others))
        modes[others] = "nearer other"
    floors = np.array([w.at(float(si))[2] for si in s])
    on_floor = rng.random(n) < 0.5
    heights = np.where(
        on_floor,
        floors + r_mm - rng.uniform(0.0, 5.0, n) / k_c,
        rng.uniform(floors + r_mm, w.top_mm - top_margin_mm),
    )
    rotations, notes = _sloppy_rotations(
        nominal_rotation(part, cell), n, rng, max_tilt_deg, max_yaw_deg
    )
    s_all = s % w.length_mm if w.closed else s
    guides, kept, lines = place_points(part, cell, wall, s_all, gaps, heights, rotations, rng)
    true_side = "right" if forward else "left"
    kept_heights = np.maximum(
        [part.to_part_mm(cell.workpiece, g.position_m[None])[0, 2] for g in guides],
        floors[kept] + r_mm + FLOOR_CLEARANCE_MM,
    ) if guides else np.zeros(0)  # fmt: skip
    learn_closed = closed if learn_closed is None else learn_closed
    head = (
        f"{part.name} ({part.description}), wall {wall!r}, "
        f"{'loop' if loop else f'stretch {span_mm[0]:.0f}-{span_mm[1]:.0f} mm'}"
        f"{' learned closed' if learn_closed else ' learned open'}, "
        f"{'forward' if forward else 'reversed'}, side {side_mode} ({true_side}), "
        f"{len(guides)} of {n} points"
    )
    lines = [f"{line} {modes[k]} {notes[k]}" for k, line in zip(kept, lines, strict=True)]
    s_kept = s_all[kept]
    stretch = None
    if not loop and len(s_kept):
        feet = w.project(
            part.to_part_mm(cell.workpiece, np.array([g.position_m for g in guides]))[:, :2]
        )
        ends = (feet[0], feet[-1]) if forward else (feet[-1], feet[0])
        nominal = (s_kept[0], s_kept[-1]) if forward else (s_kept[-1], s_kept[0])
        stretch = _from_the_feet(w, nominal, ends)
    return PeopleSet(
        guides,
        part.name,
        wall,
        learn_closed,
        true_side if side_mode == "given" else "auto",
        true_side,
        s_kept,
        kept_heights,
        "\n".join([head, *lines]),
        stretch,
    )


def hand_points(
    part: EnvelopePart,
    cell: Cell,
    rng: np.random.Generator,
    *,
    wall: str,
    n: int = 14,
    gap_mm: float = 1.0,
    side_mode: str = "given",
) -> PeopleSet:
    """A careful person's points: ``n`` evenly round the loop from a drawn start, the cutter
    ``gap_mm`` off the wall and free, half way up the wall, the tool on the job's axis."""
    w = part.walls[wall]
    r_mm = cell.tool.radius_m * 1e3
    start = rng.uniform(0.0, w.length_mm)
    s = (start + np.arange(n) * w.length_mm / n) % w.length_mm
    floors = np.array([w.at(float(si))[2] for si in s])
    heights = np.maximum(floors + r_mm + 1.0, 0.5 * (floors + w.top_mm))
    R = nominal_rotation(part, cell)
    guides, kept, lines = place_points(
        part, cell, wall, s, np.full(n, gap_mm), heights, [R] * n, rng
    )
    return PeopleSet(
        guides,
        part.name,
        wall,
        True,
        "right" if side_mode == "given" else "auto",
        "right",
        s[kept],
        np.array([part.to_part_mm(cell.workpiece, g.position_m[None])[0, 2] for g in guides]),
        "\n".join([f"{part.name} ({part.description}), wall {wall!r}, {n} hand points", *lines]),
    )
