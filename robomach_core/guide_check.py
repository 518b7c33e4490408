"""The operator's rules for guide points, checked before path learning (docs/guide_points.md).

PROBLEM   Path learning follows the wall from guide point to guide point, pushing along Yp at
          the reference force and stopping at the protection limit (60 N by default). A guide
          point recorded in heavy contact, or with a push into the wall at an outside corner
          (where the path bends around the material, so the tool slides off one face and the
          next leg starts pressed into the other), trips that protection a few seconds into a
          run; a point far from the wall costs a slow search; two points on top of each other
          give a leg with no direction.
STRATEGY  Look at the guide points alone, as the operator left them: the contact force
          recorded at each (the force the wall pushed back with), the turn of the path at each
          (incoming and outgoing legs projected across the tool axis), and, when the part's
          mesh is known, the gap between the cutter and the surface.
SOLUTION  ``guide_point_warnings(guides, settings, *, workpiece, tool_radius_m)`` returns one
          ``GuideWarning`` per problem (1-based point number, rule, message). Warnings, not
          errors: the operator may know better; the API returns them with the job it starts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .leadthrough import GuidePoint
from .path_learning import PathLearningSettings
from .workpiece import Workpiece

HEAVY_CONTACT_FRACTION = 0.5  # of the protection limit: already half-way to a stop
OUTSIDE_CORNER_TURN_DEG = 45.0  # a sharper turn towards the material is an outside corner
WALL_PUSH_MIN_N = 1.0  # below this the point was recorded free (no wall push)
MAX_WALL_GAP_M = 0.005  # farther than this from the surface, the run searches slowly
MIN_SPACING_M = 0.001  # closer guide points give a leg with no direction

GuideRule = Literal[
    "heavy_contact", "outside_corner_push", "far_from_wall", "in_material", "too_close"
]


@dataclass(frozen=True)
class GuideWarning:
    """One guide point that breaks an operator rule.

    Attributes:
        point: 1-based guide point number (as the GUIs list them).
        rule: Which rule (``GuideRule``).
        message: What is wrong and what to do, for the operator.
    """

    point: int
    rule: GuideRule
    message: str


def _turn(prev: np.ndarray, here: np.ndarray, nxt: np.ndarray, axis: np.ndarray):
    """Unit incoming and outgoing legs across the tool axis, and the turn angle [rad]."""
    legs = []
    for a, b in ((prev, here), (here, nxt)):
        d = b - a
        d = d - axis * (d @ axis)
        n = float(np.linalg.norm(d))
        if n < 1e-9:
            return None
        legs.append(d / n)
    angle = math.acos(float(np.clip(legs[0] @ legs[1], -1.0, 1.0)))
    return legs[0], legs[1], angle


def guide_point_warnings(
    guides: Sequence[GuidePoint],
    settings: PathLearningSettings,
    *,
    workpiece: Workpiece | None = None,
    tool_radius_m: float | None = None,
) -> tuple[GuideWarning, ...]:
    """The guide points that would trip the protection or slow the run (module docstring).

    Args:
        guides: The guide points in order.
        settings: The path-learning settings (force limit, closed or open contour).
        workpiece: The part; with ``tool_radius_m``, the gap to its mesh is checked.
        tool_radius_m: Ball cutter radius.
    """
    out: list[GuideWarning] = []
    n = len(guides)
    limit = settings.force_limit_N
    gaps = None
    if workpiece is not None and tool_radius_m is not None and n:
        import trimesh

        pts = np.array([g.position_m for g in guides])
        # the cutter's gap: distance of its centre from the surface minus its radius
        with np.errstate(divide="ignore", invalid="ignore"):
            _, dist, _ = trimesh.proximity.closest_point(workpiece.mesh_in_base(), pts)
        gaps = np.asarray(dist) - tool_radius_m
    for k, g in enumerate(guides):
        number = k + 1
        force = np.asarray(g.force_N, dtype=float)
        magnitude = float(np.linalg.norm(force))
        if magnitude > HEAVY_CONTACT_FRACTION * limit:
            out.append(
                GuideWarning(
                    number,
                    "heavy_contact",
                    f"guide point {number} was recorded pressing {magnitude:.0f} N into the "
                    f"part (protection stops at {limit:.0f} N): back off to a light touch "
                    "or no contact, and record it again",
                )
            )
        if k > 0 and float(np.linalg.norm(g.position_m - guides[k - 1].position_m)) < MIN_SPACING_M:
            out.append(
                GuideWarning(
                    number,
                    "too_close",
                    f"guide point {number} is less than {MIN_SPACING_M * 1e3:g} mm from point "
                    f"{number - 1}: delete one of them",
                )
            )
        has_neighbours = settings.closed or 0 < k < n - 1
        if n >= 3 and has_neighbours and magnitude >= WALL_PUSH_MIN_N:
            axis = g.T_base_tcp[:3, 2]
            turn = _turn(
                guides[k - 1].position_m, g.position_m, guides[(k + 1) % n].position_m, axis
            )
            if turn is not None:
                leg_in, leg_out, angle = turn
                # The wall pushes the tool away from it: the material lies along -force.
                towards_wall = -(force - axis * (force @ axis))
                bend = leg_out - leg_in
                if (
                    math.degrees(angle) > OUTSIDE_CORNER_TURN_DEG
                    and float(bend @ towards_wall) > 0.0
                ):
                    out.append(
                        GuideWarning(
                            number,
                            "outside_corner_push",
                            f"guide point {number} is at an outside corner (the path turns "
                            f"{math.degrees(angle):.0f} deg around the material) and was "
                            f"recorded with a wall push of {magnitude:.0f} N: there the tool "
                            "slides off the face and the protection trips; record it off the "
                            "corner's middle without a push",
                        )
                    )
        if gaps is not None:
            gap = float(gaps[k])
            if gap > MAX_WALL_GAP_M:
                out.append(
                    GuideWarning(
                        number,
                        "far_from_wall",
                        f"guide point {number} is {gap * 1e3:.1f} mm from the part's surface: "
                        f"put it within 1-3 mm of the wall (the run searches slowly beyond "
                        f"{MAX_WALL_GAP_M * 1e3:g} mm)",
                    )
                )
            elif gap < -0.5 * (tool_radius_m or 0.0):
                out.append(
                    GuideWarning(
                        number,
                        "in_material",
                        f"guide point {number} has the cutter {-gap * 1e3:.1f} mm inside the "
                        "part: move it out to touch the wall",
                    )
                )
    return tuple(out)
