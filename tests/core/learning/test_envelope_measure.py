"""The envelope tests' own measure (tests/envelope_parts, tests/learning_outcome): the true
walls lie on the meshes the cell meets, whichever way a part is tilted, and a program is
scored against the wall it was taught on, not any wall."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from tests.envelope import part_named, replay, run_seed, tilted_part
from tests.learning_outcome import classify, measure_program
from tests.people_points import PeopleSet

SEED = run_seed()


@pytest.mark.parametrize("name", ["water_pump", "tboss", "stepped_groove", "s_slot", "cam_groove"])
def test_a_parts_true_walls_lie_on_its_mesh_with_the_material_on_their_right(name):
    _walls_on_the_mesh(part_named(name))


def test_a_tilted_parts_true_walls_lie_on_its_mesh_either_way_it_is_tilted():
    rng = np.random.default_rng(SEED)
    for kind in ("groove", "boss"):
        for how in ("mesh", "wobj"):
            _walls_on_the_mesh(tilted_part(kind, rng, how))


def _walls_on_the_mesh(part) -> None:
    wp = part.workpiece(0)
    T = wp.T_base_wobj
    pq = trimesh.proximity.ProximityQuery(wp.mesh)
    for name, wall in part.walls.items():
        ends = 0 if wall.closed else 97  # an open wall's ends are the plate's edges
        idx = np.arange(ends, len(wall.xy_mm) - ends, 97)
        z = 0.5 * (wall.floor_mm[idx] + wall.top_mm)
        for off, inside in ((0.0, None), (0.4, False), (-0.4, True)):
            p = np.column_stack([wall.xy_mm[idx] + off * wall.free_normals[idx], z])
            base = part.to_base_m(wp, p)
            d = pq.signed_distance((base - T[:3, 3]) @ T[:3, :3])  # > 0 inside the material
            why = f"{replay(SEED)}: {part.description}, wall {name!r}"
            if inside is None:
                assert np.abs(d).max() < 5e-5, why
                np.testing.assert_allclose(part.to_part_mm(wp, base), p, atol=1e-9)
            else:
                assert np.all((d > 0) == inside), why


def _program_along(part, wall_name: str, offset_mm: float, upto: float = 1.0) -> np.ndarray:
    """Targets (base frame) with the ball's centre ``offset_mm`` off ``wall_name`` on its
    free side, over the first ``upto`` of it, 3 mm above its floor."""
    wp = part.workpiece(0)
    w = part.walls[wall_name]
    idx = np.arange(0, int(len(w.xy_mm) * upto), 4)  # 0.2 mm chords
    p = np.column_stack([w.xy_mm[idx] + offset_mm * w.free_normals[idx], w.floor_mm[idx] + 3])
    return part.to_base_m(wp, p)


def _set(wall: str) -> PeopleSet:
    return PeopleSet([], "water_pump", wall, True, "right", "right", np.zeros(0), np.zeros(0), "")


def test_a_program_is_scored_against_the_taught_wall_not_the_nearest():
    pump = part_named("water_pump")
    wp = pump.workpiece(0)
    on_outer = measure_program(pump, wp, 0.001, _set("outer"), _program_along(pump, "outer", 1.0))
    assert on_outer.dev_mm < 0.01 and on_outer.coverage == 1.0
    assert on_outer.nearest[0] == "outer"
    on_island = measure_program(pump, wp, 0.001, _set("outer"), _program_along(pump, "island", 1.0))
    assert on_island.dev_mm > 2.95  # a 5 mm groove, a 1 mm cutter: 3 mm, more at the bosses
    assert on_island.coverage < 0.05 and on_island.nearest[0] == "island"
    inside = measure_program(pump, wp, 0.001, _set("outer"), _program_along(pump, "outer", 0.7))
    assert inside.dev_mm == pytest.approx(0.3, abs=0.01)
    half = measure_program(pump, wp, 0.001, _set("outer"), _program_along(pump, "outer", 1, 0.5))
    assert half.coverage == pytest.approx(0.5, abs=0.02)


@pytest.mark.parametrize(
    ("dev_mm", "coverage", "completed", "problems", "kind"),
    [
        (0.2, 1.0, True, (), "learned"),
        (0.2, 1.0, True, ("the wrong wall",), "good condemned"),
        (3.0, 0.0, True, (), "wrong passed"),
        (3.0, 0.0, True, ("the wrong wall",), "off wall, flagged"),
        (0.2, 0.9, True, (), "wrong passed"),
        (0.2, 0.3, False, ("partial",), "stopped"),
    ],
)
def test_the_classes_of_the_acceptance(dev_mm, coverage, completed, problems, kind):
    from tests.learning_outcome import Measure

    m = Measure(dev_mm, coverage, 0.0, ("outer", dev_mm), (0.0, 0.0, 0.0))
    assert classify(m, completed, problems) == kind
