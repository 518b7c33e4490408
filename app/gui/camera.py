"""Where the workbench's camera stands to show the part: outside the arm, looking down at the
walls, the whole part in view.

PROBLEM: "View the part" must frame the part from a side the arm and its spindle do not
stand in, for any arm, part and placement, without the person turning the view by hand.
STRATEGY: try a short list of directions, beyond the part first (away from the robot's base),
and cast rays from each candidate eye to the part's centre and the corners of its top.
SOLUTION: ``part_view_pose`` returns the first eye no ray of which meets the arm's mesh
(``blocked_rays``), else the one blocked least, at the distance at which the part's bounding
sphere fills the view with a margin. The top view (``top_view_pose``) needs no search: it
looks straight down at the part's top.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh

# View the part: looking down at the walls from beyond the part (away from the robot's base),
# else from the first of these directions the arm does not stand in.
PART_VIEW_ELEVATIONS_DEG = (40.0, 60.0, 25.0, 75.0)
PART_VIEW_AZIMUTHS_DEG = (0.0, 35.0, -35.0, 70.0, -70.0, 110.0, -110.0, 180.0)
PART_VIEW_FILL = 1.15  # the part's bounding sphere fills the view with this margin


def part_view_pose(
    bounds: np.ndarray, fov_rad: float, obstacle: trimesh.Trimesh | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(eye, look-at) framing a part of base-frame ``bounds`` (2, 3): its bounding sphere
    fills the view (``PART_VIEW_FILL``), looking down ``PART_VIEW_ELEVATIONS_DEG`` from a
    side ``PART_VIEW_AZIMUTHS_DEG`` off "beyond the part, away from the robot's base"; the
    first from which no ray to the part's centre or the corners of its top is blocked by
    ``obstacle`` (the arm and its tool), else the one blocked least."""
    lo, hi = np.asarray(bounds, dtype=float)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    distance = PART_VIEW_FILL * radius / math.sin(0.5 * fov_rad)
    xy = centre[:2]
    away = xy / np.linalg.norm(xy) if np.linalg.norm(xy) > 1e-6 else np.array([1.0, 0.0])
    inset = 0.4 * (hi - lo)
    targets = np.array(
        [centre]
        + [[centre[0] + sx * inset[0], centre[1] + sy * inset[1], hi[2]]
           for sx in (-1, 1) for sy in (-1, 1)]
    )  # fmt: skip
    best: np.ndarray | None = None
    fewest: int | None = None
    for el_deg in PART_VIEW_ELEVATIONS_DEG:
        el = math.radians(el_deg)
        for az_deg in PART_VIEW_AZIMUTHS_DEG:
            c, s = math.cos(math.radians(az_deg)), math.sin(math.radians(az_deg))
            horizontal = np.array([c * away[0] - s * away[1], s * away[0] + c * away[1]])
            eye = centre + distance * np.array([*(horizontal * math.cos(el)), math.sin(el)])
            blocked = 0 if obstacle is None else blocked_rays(obstacle, eye, targets)
            if blocked == 0:
                return eye, centre
            if fewest is None or blocked < fewest:
                best, fewest = eye, blocked
    assert best is not None  # the first direction tried sets it (the lists are not empty)
    return best, centre


def blocked_rays(obstacle: trimesh.Trimesh, eye: np.ndarray, targets: np.ndarray) -> int:
    """How many of the rays from ``eye`` to ``targets`` meet ``obstacle`` first (or start in
    it)."""
    to = targets - eye
    length = np.linalg.norm(to, axis=1)
    dirs = to / length[:, None]
    hits, rays, _ = obstacle.ray.intersects_location(
        np.repeat(eye[None], len(targets), axis=0), dirs, multiple_hits=True
    )
    nearer = np.zeros(len(targets), dtype=bool)
    for hit, ray in zip(hits, rays, strict=True):
        if np.linalg.norm(hit - eye) < length[ray] - 1e-3:
            nearer[ray] = True
    return int(nearer.sum())


def top_view_pose(bounds: np.ndarray, fov_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """(eye, look-at) straight above a part of base-frame ``bounds`` (2, 3), looking down at
    the centre of its top from 0.65 x its wider side / tan(fov / 2) + 50 mm above it: the
    view spans 1.3 x that side at the top, the whole part in view with a margin."""
    bounds = np.asarray(bounds, dtype=float)
    centre = 0.5 * (bounds[0] + bounds[1])
    span = float(np.max(bounds[1, :2] - bounds[0, :2]))
    height = 0.65 * span / math.tan(0.5 * fov_rad) + 0.05
    look_at = np.array([centre[0], centre[1], bounds[1, 2]])
    return look_at + np.array([0.0, 0.0, height]), look_at
