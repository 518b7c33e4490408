"""The touches a click on a face makes (``teaching.face_touches``), over generated blocks (a
fresh seed each run, printed on failure): each touch on the face's plane with the face flat
``FLAT_MARGIN_M`` around it (to the ``ON_FACE_M`` a point counts as on the mesh), a top's three
touches spread across it (the third far off the line through the first two: three in a row
leave the tilt about that row free), a side's at the height clicked."""

from __future__ import annotations

import random

import numpy as np
import trimesh

from robomach_core.part import mesh_from_bytes
from robomach_core.teaching import face_touch_points
from robomach_core.teaching.face_touches import FLAT_MARGIN_M, ON_FACE_M


def _block(rng: random.Random) -> tuple[np.ndarray, object]:
    """(extents [m], the block as a workpiece): its bottom on z = 0, centred in x-y."""
    extents_mm = np.array([rng.uniform(60, 400), rng.uniform(40, 200), rng.uniform(15, 60)])
    box = trimesh.creation.box(extents=extents_mm)
    box.apply_translation([0.0, 0.0, extents_mm[2] / 2])
    data = trimesh.exchange.stl.export_stl(box)
    return extents_mm * 1e-3, mesh_from_bytes(data, ".stl", name="block")


def test_a_tops_three_touches_span_it_and_a_sides_stay_at_the_height_clicked():
    seed = random.randrange(2**32)
    rng = random.Random(seed)
    for case in range(6):
        (length, width, height), block = _block(rng)
        context = f"seed {seed}, block {case}: {length * 1e3:.0f} x {width * 1e3:.0f} mm"
        inner = np.array([length, width]) / 2 - FLAT_MARGIN_M
        pick = np.array([*(rng.uniform(-1, 1) * inner), height])
        top = face_touch_points(block, pick, 3)
        assert len(top) == 3, context
        assert np.allclose(top[:, 2], height, atol=1e-6), context
        assert np.all(np.abs(top[:, :2]) <= inner + ON_FACE_M), f"{context}: a touch near an edge"
        axis = (top[1] - top[0]) / np.linalg.norm(top[1] - top[0])
        rel = top[2] - top[0]
        off_line = np.linalg.norm(rel - (rel @ axis) * axis)
        usable = 2 * inner.min()
        assert off_line >= 0.4 * usable, f"{context}: the third {off_line * 1e3:.1f} mm off"
        z = (
            rng.uniform(FLAT_MARGIN_M, height - FLAT_MARGIN_M)
            if height > 2 * FLAT_MARGIN_M
            else height / 2
        )
        side_pick = np.array([rng.uniform(-1, 1) * inner[0], -width / 2, z])
        side = face_touch_points(block, side_pick, 3)
        assert 1 <= len(side) <= 3, context
        assert np.allclose(side[:, 1], -width / 2, atol=1e-6), context
        assert np.allclose(side[:, 2], z, atol=1e-9), context
