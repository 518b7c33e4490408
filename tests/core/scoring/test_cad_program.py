"""The CAD-only program scored beside the learned one against the real wall."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import TOOL_DOWN
from robomach_core.part import PartDeviation, Workpiece, real_workpiece
from robomach_core.part.real_part import fixture_error
from robomach_core.part.workpiece import water_pump
from robomach_core.scoring import compare_with_cad
from robomach_core.transforms import make_transform, quaternion_from_matrix
from tests.generated_parts import drawn_plate

R = 0.001
TOLERANCE = 0.0002
Z = 0.017


def _tool_path(workpiece: Workpiece, z: float, *, into_material_m: float = 0.0) -> np.ndarray:
    """A 'learned' program exactly on a part's tool path (its wall offset by the radius), or
    pushed into the material; base frame, every 0.5 mm."""
    pts = workpiece.wall.offset(R - into_material_m).sample(5e-4)
    T = workpiece.T_base_wobj
    return np.column_stack([pts, np.full(len(pts), z)]) @ T[:3, :3].T + T[:3, 3]


def _compare(workpiece: Workpiece, positions: np.ndarray, closed: bool = True):
    quats = np.tile(quaternion_from_matrix(TOOL_DOWN), (len(positions), 1))
    return compare_with_cad(workpiece, positions, quats, R, TOLERANCE, closed=closed)


def test_on_a_part_that_is_its_cad_both_programs_are_within_the_tolerance():
    pump = water_pump()
    c = _compare(pump, _tool_path(pump, Z))
    assert not c.part_deviates and c.closed
    assert c.learned.max_m < 2e-5
    assert c.cad_only.max_m == pytest.approx(TOLERANCE, abs=2e-5)  # the chords' sagitta
    assert 60 < len(c.cad_positions_m) < 200
    assert c.z_m == pytest.approx(Z)


def test_on_the_real_part_the_cad_program_carries_the_fixture_error():
    pump = water_pump()
    real = real_workpiece(pump, PartDeviation.realistic(0))
    c = _compare(real, _tool_path(real, Z))  # a program that found the real wall
    assert c.part_deviates and "fixture error" in c.deviation_note
    assert c.learned.max_m < 2e-5
    fixture = fixture_error(PartDeviation.realistic(0))
    shift = float(np.hypot(*fixture.shift_m[:2]))
    assert c.cad_only.max_m > shift  # at least the fixture's shift somewhere ...
    assert c.cad_only.max_m < shift + 0.135 * abs(fixture.rotation_rad) + 0.5e-3 + TOLERANCE
    assert c.cad_only.overcut_m > 0.3e-3 and c.cad_only.air_m > 0.3e-3  # ... both ways
    # The worst place is reported where it is: on the part, at that error.
    k = int(np.argmax(np.abs(c.cad_only.deviation_m)))
    T = pump.T_base_wobj
    worst = (c.cad_only.points_m[k] - T[:3, 3]) @ T[:3, :3]
    assert c.cad_only.worst_wobj_m == pytest.approx(worst)
    assert 0.0 <= c.cad_only.worst_fraction <= 1.0


def test_a_program_inside_the_material_reads_as_an_overcut():
    pump = water_pump()
    c = _compare(pump, _tool_path(pump, Z, into_material_m=0.3e-3))
    assert c.learned.overcut_m == pytest.approx(0.3e-3, abs=2e-5)
    assert c.learned.air_m < 1e-5
    assert np.median(c.learned.deviation_m) == pytest.approx(-0.3e-3, abs=1e-5)
    summary = c.summary()
    assert summary["learned"]["overcut_mm"] == pytest.approx(0.3, abs=0.02)
    assert set(summary["cad_only"]) >= {"max_deviation_mm", "worst_at_wobj_mm"}


def test_a_path_away_from_every_wall_has_no_comparison():
    pump = water_pump()
    T = pump.T_base_wobj
    far = np.array([[0.0, 0.0, Z], [0.01, 0.0, Z], [0.02, 0.01, Z]]) @ T[:3, :3].T + T[:3, 3]
    far[:, 2] += 0.05  # above the part
    assert _compare(pump, far) is None


@given(
    seed=st.integers(0, 2**32 - 1),
    tilt_deg=st.floats(10.0, 20.0),
    wall=st.sampled_from(["outer", "island", "outline"]),
)
@settings(max_examples=10, deadline=None)
def test_on_a_plate_tilted_in_its_mesh_both_programs_follow_the_wall_along_the_floor(
    seed, tilt_deg, wall
):
    """A path on the tool path of a groove's wall or of an outside edge, a few mm above a
    floor tilted 10-20 deg in the mesh, is within the tolerance, and so is the CAD-only
    program (cut along the floor, not by a horizontal plane that crosses the wall)."""
    plate = drawn_plate(seed, "edge" if wall == "outline" else "groove", tilt_deg)
    outline = plate.walls[wall]
    free = -R if wall == "outer" else R  # the tool's side: inside the outer wall's ring
    ring = shapely.Polygon(outline).buffer(free, quad_segs=32).exterior
    xy = np.array([ring.interpolate(s).coords[0] for s in np.arange(0, ring.length, 5e-4)])
    height = 0.008 if wall == "outline" else 0.017  # 8 mm up the edge, 3 mm above the floor
    plate_frame = np.column_stack([xy, np.full(len(xy), height)])
    T = make_transform(np.eye(3), np.array([0.8, 0.16, 0.0]))
    wp = Workpiece("tilted", plate.mesh, T)
    positions = (plate_frame @ plate.T_mesh_plate[:3, :3].T + plate.T_mesh_plate[:3, 3]) + T[:3, 3]
    c = _compare(wp, positions)
    assert c is not None
    assert c.learned.max_m < 5e-5, c.learned.max_m  # the path's and the mesh's own facets
    assert c.cad_only.max_m <= TOLERANCE + 2e-5, c.cad_only.max_m
