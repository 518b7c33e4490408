"""Guide points taught beside a part that may not be where its mesh is.

PROBLEM   Teaching uses the part's CAD, the cell meets the real part (``real_part``): a point
          placed 2 mm off the CAD's wall may come down on the real wall, or on its rim. And
          points taught by hand say which way they go along the wall only by their order.
STRATEGY  Enter each pushed point in the middle of the free space beside its wall (a groove's
          middle; ``OPEN_EDGE_ENTRY_M`` off an open edge), as a careful operator does, and let
          the push find the real wall from there. Which way points go: project them on the
          nearest wall loop of the CAD's section at their height above the floor
          (``walls.walls_near``) and compare the distances travelled forwards and backwards
          along it.
SOLUTION  ``robust_intents(intents, workpiece, tool_radius_m)`` and ``wall_side_of(positions,
          workpiece)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..workpiece import Workpiece
from .planner import WallPlacer
from .thresholds import OPEN_EDGE_ENTRY_M
from .walls import walls_near


def wall_side_of(positions_base_m: np.ndarray, workpiece: Workpiece) -> str | None:
    """The wall side ("left"/"right") of guide points taught beside one wall of the part's
    mesh: "right" when they follow the wall's own direction (material on the right), None
    when they are not beside one wall at one height above the floor or go neither way."""
    cad = workpiece.cad()
    pts = np.asarray(positions_base_m, dtype=float)
    if len(pts) < 2:
        return None
    T = cad.T_base_wobj
    _, pf, loops = walls_near(cad.mesh, (pts - T[:3, 3]) @ T[:3, :3])
    if np.ptp(pf[:, 2]) > 0.005:
        return None
    best = None
    for loop in loops:
        d = np.abs(loop.signed_distance(pf[:, :2]))
        if d.max() < 0.008 and (best is None or d.mean() < best[1]):
            best = (loop, float(d.mean()))
    if best is None:
        return None
    loop = best[0]
    s = loop.project(pf[:, :2])
    steps = np.diff(s)
    if loop.closed:
        steps = (steps + 0.5 * loop.length_m) % loop.length_m - 0.5 * loop.length_m
    forward, backward = float(steps[steps > 0].sum()), float(-steps[steps < 0].sum())
    if max(forward, backward) < 3.0 * min(forward, backward) + 1e-4:
        return None
    return "right" if forward > backward else "left"


def robust_intents(intents: Sequence, workpiece: Workpiece, tool_radius_m: float) -> list:
    """Intents for a part that may not be where its mesh is: each point with a wall push is
    entered in the middle of the free space beside its wall (a groove's middle;
    ``OPEN_EDGE_ENTRY_M`` off an open edge), so that the cutter comes down clear of the real
    walls, and the push finds the wall from there (a careful operator does the same when the
    part may be off its drawing). Points without a push (outside corners) stay where they
    are."""
    cad = workpiece.cad()
    T = cad.T_base_wobj
    out = []
    for intent in intents:
        if intent.wall_normal is None:
            out.append(intent)
            continue
        p = (np.asarray(intent.position_m) - T[:3, 3]) @ T[:3, :3]
        T_floor, (pf,), loops = walls_near(cad.mesh, p)
        if not loops:
            out.append(intent)
            continue
        loop = min(loops, key=lambda lp: abs(lp.signed_distance(pf[None, :2])[0]))
        xy, note = WallPlacer(loop, loops, tool_radius_m, OPEN_EDGE_ENTRY_M)(
            float(loop.project(pf[None, :2])[0])
        )
        if "too narrow" in note:
            out.append(intent)
            continue
        entry = T[:3, :3] @ T_floor[:3, :3] @ np.array([xy[0], xy[1], pf[2]]) + T[:3, 3]
        out.append(replace(intent, position_m=entry))
    return out
