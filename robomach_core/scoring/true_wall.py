"""Scoring a learned path against the true workpiece geometry (the product's honesty).

The exported path is the chain of straight segments through the targets. For a built-in
workpiece the true tool path is the wall contour offset by the tool radius towards the tool
(the cutter touches the wall along its radius). Both are compared in the work-object x-y plane,
where the built-in walls are vertical.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..part import Workpiece
from ..postprocess import Move, sample_moves
from ..transforms import arc_length_m

SCORE_SPACING_M = 2e-5  # points every 0.02 mm along each segment


@dataclass(frozen=True)
class PathScore:
    """Deviation of a path from the true tool path (metres).

    Attributes:
        max_m: Largest deviation over the targets and the segments between them.
        rms_m: RMS deviation over the path, sampled uniformly along its length.
        targets_max_m: Largest deviation at the targets alone.
        targets_rms_m: RMS deviation at the targets alone.
        along_s_m: (k,) arc length of the scored points along the path.
        deviation_m: (k,) deviation at each scored point; signed where the truth has a side
            (the mesh score: > 0 air, < 0 the cutter inside the material), else >= 0.
        overcut_m: Deepest the cutter goes into the material (>= 0; 0 for unsigned scores).
        air_m: Farthest the cutter stays off the surface (>= 0; ``max_m`` when unsigned).
    """

    max_m: float
    rms_m: float
    targets_max_m: float
    targets_rms_m: float
    along_s_m: np.ndarray
    deviation_m: np.ndarray
    overcut_m: float = 0.0
    air_m: float = 0.0


def _to_wobj_xy(workpiece: Workpiece, points_base: np.ndarray) -> np.ndarray:
    T = workpiece.T_base_wobj
    return ((np.asarray(points_base, dtype=float) - T[:3, 3]) @ T[:3, :3])[:, :2]


def true_tool_path_distance(
    workpiece: Workpiece, tool_radius_m: float, points_base: np.ndarray
) -> np.ndarray:
    """Distance (m) of base-frame points from the wall offset by the tool radius."""
    if workpiece.wall is None:
        raise InvalidInputError(f"workpiece {workpiece.name!r} has no known true geometry to score")
    # The wall is travelled with its material on the right: the tool is on the left.
    return workpiece.wall.offset(tool_radius_m).distance(_to_wobj_xy(workpiece, points_base))


def score_path(
    workpiece: Workpiece, tool_radius_m: float, targets_m: np.ndarray, *, closed: bool = False
) -> PathScore:
    """Score the polyline through ``targets_m`` (m, 3) against the true tool path."""
    pts = np.asarray(targets_m, dtype=float)
    if len(pts) < 2:
        raise InvalidInputError("scoring needs at least 2 targets")
    chain = np.vstack([pts, pts[:1]]) if closed else pts
    samples, along = [], []
    s0 = 0.0
    for a, b in zip(chain[:-1], chain[1:], strict=True):
        length = float(np.linalg.norm(b - a))
        n = max(2, int(np.ceil(length / SCORE_SPACING_M)) + 1)
        f = np.linspace(0.0, 1.0, n)[:-1]
        samples.append(a + (b - a) * f[:, None])
        along.append(s0 + f * length)
        s0 += length
    samples.append(chain[-1:])
    along.append(np.array([s0]))
    points = np.vstack(samples)
    dev = true_tool_path_distance(workpiece, tool_radius_m, points)
    at_targets = true_tool_path_distance(workpiece, tool_radius_m, pts)
    return PathScore(
        max_m=float(dev.max()),
        rms_m=float(np.sqrt(np.mean(dev**2))),
        targets_max_m=float(at_targets.max()),
        targets_rms_m=float(np.sqrt(np.mean(at_targets**2))),
        along_s_m=np.concatenate(along),
        deviation_m=dev,
        air_m=float(dev.max()),
    )


def score_moves(
    workpiece: Workpiece, tool_radius_m: float, positions_m: np.ndarray, moves: Sequence[Move]
) -> PathScore:
    """Deviation of the moved path (lines and arcs) from the true tool path, like
    ``scoring.score_path`` for the straight program (built-in parts with a known wall)."""
    return score_sampled_moves(
        lambda points: true_tool_path_distance(workpiece, tool_radius_m, points),
        positions_m,
        moves,
        spacing_m=SCORE_SPACING_M,
    )


def score_sampled_moves(
    deviation: Callable[[np.ndarray], np.ndarray],
    positions_m: np.ndarray,
    moves: Sequence[Move],
    *,
    spacing_m: float,
) -> PathScore:
    """Score a move sequence by ``deviation`` (points (k, 3) [m] -> (k,) [m], signed or not)
    of its path sampled every ``spacing_m`` and of the targets it uses (the truth is the
    caller's: the known wall, or the mesh). Max and RMS are of the deviation's size; a signed
    deviation's most negative value is the overcut, its most positive the air."""
    pts = np.asarray(positions_m, dtype=float)
    path = sample_moves(pts, moves, spacing_m=spacing_m)
    dev = deviation(path)
    used = sorted({m.to for m in moves} | {m.via for m in moves if m.via is not None})
    at_targets = deviation(pts[used])
    along = arc_length_m(path)
    return PathScore(
        max_m=float(np.abs(dev).max()),
        rms_m=float(np.sqrt(np.mean(dev**2))),
        targets_max_m=float(np.abs(at_targets).max()),
        targets_rms_m=float(np.sqrt(np.mean(at_targets**2))),
        along_s_m=along,
        deviation_m=dev,
        overcut_m=float(max(0.0, -dev.min())),
        air_m=float(max(0.0, dev.max())),
    )
