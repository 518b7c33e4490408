"""Arc fitting: circles through three points, greedy line/arc pieces, programs of moves."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.errors import InvalidInputError
from robomach_core.part import builtin_workpiece, water_pump_wall
from robomach_core.postprocess import (
    Move,
    Targets,
    arc_targets,
    linear_moves,
    reduce_deviation_height,
    sample_moves,
)
from robomach_core.postprocess.arcs import circle_through, fit_arcs


def line_arc_line(spacing: float = 2e-5, radius: float = 0.005) -> np.ndarray:
    """20 mm along x, a quarter circle of ``radius`` to the left, 20 mm along y (metres)."""
    a = np.arange(0.0, 0.020, spacing)
    first = np.column_stack([a, np.zeros_like(a), np.zeros_like(a)])
    t = np.arange(0.0, math.pi / 2, spacing / radius)
    arc = np.column_stack(
        [0.020 + radius * np.sin(t), radius - radius * np.cos(t), np.zeros_like(t)]
    )
    b = np.arange(0.0, 0.020 + spacing / 2, spacing)
    last = np.column_stack([np.full_like(b, 0.020 + radius), radius + b, np.zeros_like(b)])
    return np.vstack([first, arc, last])


def piece_deviation(points: np.ndarray, piece) -> np.ndarray:
    seg = points[piece.start : piece.end + 1]
    if piece.via is None:
        a, b = seg[0], seg[-1]
        u = (b - a) / np.linalg.norm(b - a)
        rel = seg - a
        return np.linalg.norm(rel - np.outer(rel @ u, u), axis=1)
    centre, radius, normal = circle_through(seg[0], points[piece.via], seg[-1])
    rel = seg - centre
    h = rel @ normal
    radial = np.linalg.norm(rel - np.outer(h, normal), axis=1)
    return np.sqrt((radial - radius) ** 2 + h**2)


def test_circle_through_three_points_known_answer():
    centre, radius, normal = circle_through(
        np.array([1.0, 0.0, 2.0]), np.array([0.0, 1.0, 2.0]), np.array([-1.0, 0.0, 2.0])
    )
    np.testing.assert_allclose(centre, (0, 0, 2), atol=1e-12)
    assert radius == pytest.approx(1.0)
    np.testing.assert_allclose(normal, (0, 0, 1), atol=1e-12)
    assert circle_through(np.zeros(3), np.ones(3), 2 * np.ones(3)) is None


def test_line_arc_line_is_three_pieces_with_the_arc_found():
    pts = line_arc_line()
    pieces = fit_arcs(pts, 1e-5)
    # Greedy: the first piece may bend slightly into the fillet (a large arc within 10 um).
    assert len(pieces) == 3 and pieces[1].via is not None and pieces[2].via is None
    arc = pieces[1]
    arc_samples = len(pts) - 2 * len(np.arange(0.0, 0.020, 2e-5))
    assert arc.end - arc.start > 0.9 * arc_samples
    centre, radius, _ = circle_through(pts[arc.start], pts[arc.via], pts[arc.end])
    assert radius == pytest.approx(0.005, rel=1e-2)
    np.testing.assert_allclose(centre, (0.020, 0.005, 0.0), atol=1e-4)


@given(
    st.floats(0.002, 0.02),
    st.floats(2e-5, 3e-4),
    st.integers(0, 2**31 - 1),
)
@settings(max_examples=25, deadline=None)
def test_every_sample_lies_within_the_tolerance_of_its_piece(radius, tolerance, seed):
    """Pieces chain from the first sample to the last, and no sample is farther than the
    tolerance from its line or arc, noise included."""
    rng = np.random.default_rng(seed)
    pts = line_arc_line(radius=radius)
    pts = pts + rng.normal(0.0, tolerance / 6, pts.shape) * np.array([1.0, 1.0, 0.2])
    pieces = fit_arcs(pts, tolerance)
    assert pieces[0].start == 0 and pieces[-1].end == len(pts) - 1
    assert all(a.end == b.start for a, b in zip(pieces[:-1], pieces[1:], strict=True))
    for piece in pieces:
        assert piece_deviation(pts, piece).max() <= tolerance * (1 + 1e-9)
        assert piece.deviation_m <= tolerance


def test_on_the_pump_wall_arcs_need_fewer_moves_and_follow_it_closer():
    """The exact water-pump tool path (offset wall): at 0.1 mm, arcs need fewer moves than the
    deviation-height chords and their RMS distance to the path is lower."""
    contour = water_pump_wall().offset(0.001)
    xy = contour.sample(5e-5)
    pts = np.column_stack([xy, np.zeros(len(xy))])
    tolerance = 1e-4
    straight = reduce_deviation_height(pts, tolerance)
    pieces = fit_arcs(pts, tolerance)
    moves = [Move("linear", 0)]
    kept = [0]
    for piece in pieces:
        if piece.via is not None:
            kept.append(piece.via)
        kept.append(piece.end)
        moves.append(
            Move("circular", len(kept) - 1, len(kept) - 2)
            if piece.via is not None
            else Move("linear", len(kept) - 1)
        )
    arc_path = sample_moves(pts[kept], moves, spacing_m=5e-5)
    line_path = sample_moves(pts[straight], linear_moves(len(straight)), spacing_m=5e-5)
    arc_dev = contour.distance(arc_path[:, :2])
    line_dev = contour.distance(line_path[:, :2])
    assert len(moves) < len(straight)
    assert arc_dev.max() < 1.05 * tolerance
    assert np.sqrt(np.mean(arc_dev**2)) < 0.85 * np.sqrt(np.mean(line_dev**2))


def test_arc_targets_builds_a_program_on_the_samples():
    pts = line_arc_line(spacing=5e-5)
    n = len(pts)
    keep = np.ones(n, dtype=bool)
    keep[5] = False  # a sample the force filter dropped is never a target
    straight_idx = np.nonzero(keep)[0][reduce_deviation_height(pts[keep], 1e-4)]
    m = len(straight_idx)
    quat = np.tile([0.0, 1.0, 0.0, 0.0], (m, 1))
    straight = Targets(
        position_m=pts[straight_idx],
        quaternion_wxyz=quat,
        joints_rad=np.zeros((m, 6)) + np.arange(m)[:, None],
        speed_m_s=np.linspace(0.005, 0.015, m),
        curvature_1_m=np.zeros(m),
        sample_index=straight_idx,
    )
    targets, moves = arc_targets(straight, pts, keep, 1e-4)
    assert moves[0] == Move("linear", 0)
    assert len(moves) == 4 and any(m.kind == "circular" for m in moves)
    assert len(targets) == 1 + sum(2 if m.via is not None else 1 for m in moves[1:])
    assert moves[-1].to == len(targets) - 1
    np.testing.assert_allclose(targets.position_m, pts[targets.sample_index])
    assert 5 not in targets.sample_index
    assert np.all(np.diff(targets.sample_index) > 0)
    np.testing.assert_allclose(np.abs(targets.quaternion_wxyz[:, 1]), 1.0)
    assert np.all((targets.speed_m_s >= 0.005) & (targets.speed_m_s <= 0.015))


def test_sample_moves_follows_the_circle():
    pts = np.array([[1.0, 0, 0], [0, 1.0, 0], [-1.0, 0, 0]])
    drawn = sample_moves(pts, (Move("linear", 0), Move("circular", 2, 1)), spacing_m=0.01)
    np.testing.assert_allclose(np.linalg.norm(drawn, axis=1), 1.0, atol=1e-12)
    assert drawn[:, 1].min() >= -1e-12  # through the via point's half, not the other
    np.testing.assert_allclose(drawn[-1], pts[-1], atol=1e-12)


def test_bad_input_is_a_clear_error():
    with pytest.raises(InvalidInputError, match="tolerance"):
        fit_arcs(np.zeros((4, 3)), 0.0)
    with pytest.raises(InvalidInputError, match="shape"):
        fit_arcs(np.zeros((4, 2)), 1e-4)


def test_score_moves_of_the_straight_program_is_score_path():
    from robomach_core.scoring import score_moves, score_path

    pump = builtin_workpiece("water_pump")
    xy = pump.wall.offset(0.001).sample(0.004)[:40]
    T = pump.T_base_wobj
    pts = (T[:3, :3] @ np.column_stack([xy, np.full(len(xy), 0.017)]).T).T + T[:3, 3]
    pts[::3] += np.array([0.0001, 0.0, 0.0])
    expected = score_path(pump, 0.001, pts)
    got = score_moves(pump, 0.001, pts, linear_moves(len(pts)))
    assert got.max_m == pytest.approx(expected.max_m, rel=1e-6)
    assert got.rms_m == pytest.approx(expected.rms_m, rel=1e-3)
    assert got.targets_max_m == pytest.approx(expected.targets_max_m, rel=1e-9)
