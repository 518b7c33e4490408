"""Throughput of deviation-height reduction on 100k samples, next to RDP (``simplification``).

Run: python benchmarks/bench_reduction.py
The input is the water-pump tool path sampled every 0.02 mm (5 mm/s at 4 ms) with 10 um noise,
cut to 100 000 samples. RDP (Ramer-Douglas-Peucker, Rust) is the reference measured in the same
run; it is a different algorithm (global, recursive) that keeps fewer points for the same
tolerance, so both the speed and the number of points kept are printed.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from robomach_core.postprocess import reduce_deviation_height
from robomach_core.workpiece import water_pump_wall

N_SAMPLES = 100_000
TOLERANCE_M = 0.0002


def timed(fn, repeats: int = 5) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def main() -> None:
    path = water_pump_wall().offset(0.001).sample(2e-5)
    laps = int(np.ceil(N_SAMPLES / len(path)))
    pts2 = np.vstack([path] * laps)[:N_SAMPLES]
    rng = np.random.default_rng(0)
    pts = np.column_stack([pts2, np.zeros(len(pts2))]) + rng.normal(0, 1e-5, (N_SAMPLES, 3))

    t_ours, kept = timed(lambda: reduce_deviation_height(pts, TOLERANCE_M))
    print(
        f"deviation height (chapter fig. 3): {N_SAMPLES} samples -> {len(kept)} targets, "
        f"median {t_ours * 1e3:.0f} ms, {N_SAMPLES / t_ours / 1e6:.2f} M samples/s"
    )
    try:
        from simplification.cutil import simplify_coords_idx
    except ImportError:
        print("simplification is not installed: pip install -e '.[test]' for the RDP reference")
        return
    xy = np.ascontiguousarray(pts[:, :2])
    t_rdp, kept_rdp = timed(lambda: simplify_coords_idx(xy, TOLERANCE_M))
    print(
        f"RDP reference (simplification, Rust): -> {len(kept_rdp)} points, "
        f"median {t_rdp * 1e3:.1f} ms, {N_SAMPLES / t_rdp / 1e6:.2f} M samples/s"
    )
    print(
        f"ratio: deviation height takes x{t_ours / t_rdp:.1f} the RDP time and keeps "
        f"x{len(kept) / len(kept_rdp):.2f} the points"
    )


if __name__ == "__main__":
    main()
