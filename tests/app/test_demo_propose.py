"""``robomach demo --propose-guide-points`` on uploaded parts, and ``--realistic``: the
learned program against the picked (real) wall, and the CAD-only program beside it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import shapely

from tests.cli import robomach_here as robomach  # in this process: imports paid once
from tests.generated_parts import PARTS

pytestmark = pytest.mark.slow

WOBJ_MM = np.array([800.0, 160.0, 0.0])  # where an uploaded part lands in front of a UR10
RADIUS_MM = 1.0


def _targets_wobj_mm(out: Path) -> np.ndarray:
    rows = np.loadtxt(out / "targets.csv", delimiter=",", skiprows=1)
    return rows[:, 2:5] - WOBJ_MM


def _deviation_mm(targets: np.ndarray, wall: shapely.Geometry) -> np.ndarray:
    """|distance from the wall - radius| along the straight moves through the targets."""
    pts = []
    for a, b in zip(targets[:-1], targets[1:], strict=True):
        n = max(2, int(np.linalg.norm(b - a) / 0.05))
        pts.append(a[:2] + np.linspace(0, 1, n)[:, None] * (b[:2] - a[:2]))
    xy = np.vstack(pts)
    return np.abs(shapely.distance(shapely.points(xy), wall) - RADIUS_MM)


@pytest.mark.parametrize(
    "part_name, wall",
    [
        ("grooved_plate", "island"),  # a groove: the picked wall, not the other one
        ("grooved_plate", "outer"),
        ("l_block", "outline"),  # an outside edge with sharp corners
        ("slotted_plate", "right side"),  # an open slot
    ],
)
def test_an_uploaded_part_learns_the_picked_wall_without_a_csv(tmp_path, part_name, wall):
    part = PARTS[part_name]()
    stl = tmp_path / f"{part.name}.stl"
    stl.write_bytes(part.stl_bytes())
    x, y, z = part.picks[wall]
    out = tmp_path / "out"
    proc = robomach(
        "demo", "--out", str(out), "--workpiece", str(stl),
        f"--propose-guide-points={x},{y},{z}", "--no-plot",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "proposed" in proc.stdout and "wall side right" in proc.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"], summary["stop_reason"]
    assert summary["closed"] == (wall not in part.open_walls)
    targets = _targets_wobj_mm(out)
    picked = _deviation_mm(targets, part.walls[wall])
    assert picked.max() <= 0.3, f"{picked.max():.3f} mm from the picked wall"
    for other, outline in part.walls.items():
        if other != wall:  # the groove's other wall is 6 mm away: never followed
            assert _deviation_mm(targets, outline).min() > 3.0
    learned = summary["cad_comparison"]["learned"]
    assert learned["max_deviation_mm"] == pytest.approx(picked.max(), abs=0.03)


def test_the_realistic_preset_learns_the_real_wall_and_shows_the_cad_program_error(tmp_path):
    out = tmp_path / "out"
    proc = robomach("demo", "--out", str(out), "--realistic", "--no-plot")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "real part" in proc.stdout and "CAD-only program" in proc.stdout
    summary = json.loads((out / "summary.json").read_text())
    comparison = summary["cad_comparison"]
    assert comparison["part_deviates_from_cad"]
    learned, cad = comparison["learned"], comparison["cad_only"]
    assert learned["max_deviation_mm"] <= 0.3
    assert summary["max_deviation_mm"] <= 0.3  # the score against the real contour agrees
    # The CAD-only program is off by about the fixture error (0.3-0.6 mm and 0.15-0.3 deg at
    # up to 120 mm from its pivot) plus the casting's +-0.5 mm.
    assert 0.5 < cad["max_deviation_mm"] < 3.0
    assert cad["max_deviation_mm"] > 3 * learned["max_deviation_mm"]
    assert cad["rms_deviation_mm"] > learned["rms_deviation_mm"]
    settings = json.loads((out / "settings.json").read_text())
    assert settings["cell"]["part_deviation"]["seed"] == 0
