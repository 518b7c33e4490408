"""Throughput of deviation-height reduction on 100k samples, next to RDP (``simplification``).

Run: python benchmarks/bench_reduction.py [--repeats N] [--quick]
The input is the water-pump tool path sampled every 0.02 mm (5 mm/s at 4 ms) with 10 um noise,
in 3-D, cut to 100 000 samples. RDP (Ramer-Douglas-Peucker, Rust) is the reference measured in
the same run on the same samples (its x, y: it takes 2-D only); it is a different algorithm
(global, recursive) that keeps fewer points for the same tolerance, so both the speed and the
number of points kept are printed, and the ratio of the times (ours / RDP; the aim is <= 1.0).

Then the cost on dense recordings: one lap of the path sampled as learned at 5 and at 0.5 mm/s
(the lowest learning speed; 0.02 and 0.002 mm apart, 38k and 376k samples), whose time per sample
should stay about the same (near-linear cost), and ``postprocess()`` as a whole (force filter,
surface positions, reduction, curvature, speeds, orientations) on a synthetic 311k-sample
recording (the size of the water pump learned at 0.5 mm/s).
``--quick`` runs tiny sizes in seconds (a check that the script still works, not a measurement).
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np

from robomach_core.cell import CONTROL_PERIOD_S
from robomach_core.learning.run import Recording
from robomach_core.part import water_pump_wall
from robomach_core.postprocess import PostprocessSettings, postprocess, reduce_deviation_height

N_SAMPLES = 100_000
TOLERANCE_M = 0.0002
NOISE_M = 1e-5
DENSE_SPEEDS_MM_S = (5.0, 0.5)
DENSE_SAMPLES = 311_000  # a water-pump recording learned at 0.5 mm/s
FORCE_N = 10.0
N_GUIDES = 14


def timed(fn: Callable[[], object], repeats: int) -> tuple[float, object]:
    """Median wall time [s] over ``repeats`` calls, and the last result."""
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def contour_samples(spacing_m: float, n: int | None, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) water-pump tool path every ``spacing_m``, laps repeated up to n, 10 um noise."""
    path = water_pump_wall().offset(0.001).sample(spacing_m)
    if n is not None:
        path = np.vstack([path] * int(np.ceil(n / len(path))))[:n]
    return np.column_stack([path, np.zeros(len(path))]) + rng.normal(0, NOISE_M, (len(path), 3))


def synthetic_recording(n: int, rng: np.random.Generator) -> tuple[Recording, np.ndarray]:
    """A recording of one lap of the water pump in ``n`` samples, and its guide orientations.

    The tool points down; it presses 10 N (+-1 N noise, with 1 % spikes outside the force
    window) towards the wall along the path normal; the lap is split into 14 guide segments.
    """
    path = water_pump_wall().offset(0.001)
    xy = path.sample(path.length / n)[:n]
    n = len(xy)
    pts = np.column_stack([xy, np.zeros(n)]) + rng.normal(0, NOISE_M, (n, 3))
    tangent = np.gradient(np.column_stack([xy, np.zeros(n)]), axis=0)
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0], np.zeros(n)])
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-12)[:, None]
    force = FORCE_N + rng.normal(0, 1.0, n)
    force[rng.random(n) < 0.01] = 40.0
    down = np.array([0.0, 1.0, 0.0, 0.0])  # wxyz: 180 deg about x, tool z along -z
    wrench_tool = np.zeros((n, 6))
    wrench_tool[:, 0] = normal[:, 0] * force  # rotation by 180 deg about x: x stays, y flips
    wrench_tool[:, 1] = -normal[:, 1] * force
    recording = Recording(
        time_s=np.arange(n) * CONTROL_PERIOD_S,
        joints_rad=np.zeros((n, 6)),
        position_m=pts,
        quaternion_wxyz=np.tile(down, (n, 1)),
        wrench_sensor=np.zeros((n, 6)),
        wrench_tool=wrench_tool,
        force_normal_N=force,
        force_reference_N=np.full(n, FORCE_N),
        in_contact=np.ones(n, dtype=bool),
        yp=normal,
        segment=(np.arange(n) * N_GUIDES) // n,
        stop_reason="completed",
        completed=True,
    )
    return recording, np.tile(down, (N_GUIDES, 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per figure (median)")
    parser.add_argument("--quick", action="store_true", help="tiny sizes, one run: a smoke test")
    args = parser.parse_args()
    repeats = 1 if args.quick else args.repeats
    n_samples = 5_000 if args.quick else N_SAMPLES
    dense_samples = 20_000 if args.quick else DENSE_SAMPLES
    rng = np.random.default_rng(0)
    reduce_deviation_height(np.eye(3), 0.1)  # compile (or load) the kernel

    pts = contour_samples(2e-5, n_samples, rng)
    t_ours, kept = timed(lambda: reduce_deviation_height(pts, TOLERANCE_M), repeats)
    print(
        f"deviation height (chapter fig. 3, 3-D): {n_samples} samples -> {len(kept)} targets, "
        f"median {t_ours * 1e3:.1f} ms, {n_samples / t_ours / 1e6:.2f} M samples/s"
    )
    try:
        from simplification.cutil import simplify_coords_idx
    except ImportError:
        print("simplification is not installed: pip install -e '.[test]' for the RDP reference")
        t_rdp = None
    else:
        xy = np.ascontiguousarray(pts[:, :2])
        t_rdp, kept_rdp = timed(lambda: simplify_coords_idx(xy, TOLERANCE_M), repeats)
        print(
            f"RDP reference (simplification, Rust, 2-D): -> {len(kept_rdp)} points, "
            f"median {t_rdp * 1e3:.1f} ms, {n_samples / t_rdp / 1e6:.2f} M samples/s"
        )
        print(
            f"ratio ours / RDP: {t_ours / t_rdp:.2f} of the time (aim <= 1.0), "
            f"x{len(kept) / len(kept_rdp):.2f} the points"
        )

    for speed_mm_s in DENSE_SPEEDS_MM_S:
        spacing_m = speed_mm_s * 1e-3 * CONTROL_PERIOD_S
        n = None
        if args.quick:
            n = 2_000 if speed_mm_s > 1.0 else 20_000
        dense = contour_samples(spacing_m, n, rng)
        t, kept = timed(lambda d=dense: reduce_deviation_height(d, TOLERANCE_M), repeats)
        print(
            f"dense recording, learned at {speed_mm_s:g} mm/s: {len(dense)} samples -> "
            f"{len(kept)} targets in {t * 1e3:.1f} ms, {t / len(dense) * 1e9:.0f} ns per sample"
        )

    recording, guide_quats = synthetic_recording(dense_samples, rng)
    settings = PostprocessSettings(tolerance_m=TOLERANCE_M)
    t_post, result = timed(lambda: postprocess(recording, guide_quats, settings), repeats)
    print(
        f"postprocess() on a synthetic {len(recording)}-sample recording: "
        f"{result.samples_filtered} filtered -> {len(result.targets)} targets in "
        f"{t_post * 1e3:.0f} ms (aim < 2000 ms)"
    )


if __name__ == "__main__":
    main()
