"""The part's variation: stocks drawn as castings differ from part to part, and the
configurations' figures over them (median, 95th percentile, share within the limit).

PROBLEM   One stock and one seed say what one casting does; the next casting has another
          allowance, burrs elsewhere and of other heights, and a harder or softer skin, and a
          configuration chosen on one sample may trip the limit on the next.
STRATEGY  Draw N stocks from stated ranges (``StockVariation``), seeded, each from the part's
          own stock: a built-in stock is drawn anew from a derived seed (new allowance phases,
          new burrs) with its allowance range scaled; a profile or mesh stock keeps its shape,
          scaled, with burrs drawn on it; every stock gets a material coefficient that scales
          the process gain K (the controllers keep the nominal design). Run every
          configuration on every stock (``parallel``), and summarise per configuration.
SOLUTION  ``draw_stocks`` and ``variation_rows``; the chooser reads the 95th percentiles.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .errors import StockError
from .stock import (
    BURR_HEIGHT_RANGE_M,
    BURR_LENGTH_RANGE_M,
    BURRS_PER_M,
    LEAD_IN_M,
    MAX_ALLOWANCE_M,
    Burr,
    Stock,
    builtin_stock,
)

MM = 1e-3
# Figures summarised over the stocks: (row key, run summary key).
VARIED_FIGURES: tuple[tuple[str, str], ...] = (
    ("cycle_time", "cycle_time_s"),
    ("force_peak", "force_peak_N"),
    ("wall_error_max", "wall_error_max_mm"),
)
UNITS = {"cycle_time": "s", "force_peak": "N", "wall_error_max": "mm"}


@dataclass(frozen=True)
class StockVariation:
    """The stated ranges a casting varies within (each drawn uniformly, per stock).

    Attributes:
        allowance_scale: Factor on the stock's allowance (the casting's wall thickness).
        material_factor: Factor on the process gain K (the casting's hardness).
        burrs_per_m: Burrs drawn on a profile or mesh stock, per metre of path (a built-in
            stock draws its own).
    """

    allowance_scale: tuple[float, float] = (0.85, 1.15)
    material_factor: tuple[float, float] = (0.9, 1.1)
    burrs_per_m: float = BURRS_PER_M

    def __post_init__(self) -> None:
        for name in ("allowance_scale", "material_factor"):
            lo, hi = getattr(self, name)
            if not (0.1 <= lo <= hi <= 10.0):
                raise StockError(f"{name} must be a range within 0.1-10, got ({lo}, {hi})")
        if not 0.0 <= self.burrs_per_m <= 100.0:
            raise StockError(f"burrs_per_m must be within 0-100, got {self.burrs_per_m}")

    def describe(self) -> str:
        """The ranges as one line for reports."""
        a, k = self.allowance_scale, self.material_factor
        return (
            f"allowance x{a[0]:g}-{a[1]:g}, burrs re-drawn (0.5-2 mm high), "
            f"material K x{k[0]:g}-{k[1]:g}"
        )


def draw_stocks(base: Stock, count: int, seed: int, variation: StockVariation) -> list[Stock]:
    """``count`` stocks drawn from ``base``'s variation, reproducible from ``seed``."""
    if not 1 <= count <= 10_000:
        raise StockError(f"the number of variations must be within 1-10000, got {count}")
    out = []
    for i in range(count):
        rng = np.random.default_rng([seed, i])
        scale = rng.uniform(*variation.allowance_scale)
        material = float(rng.uniform(*variation.material_factor))
        if base.source == "builtin":
            from .stock import ALLOWANCE_RANGE_M

            lo, hi = ALLOWANCE_RANGE_M
            stock = builtin_stock(
                base.path_points_m,
                int(rng.integers(0, 2**31)),
                wall_normals_m=base.wall_normals_m,
                tool_radius_m=base.tool_radius_m,
                allowance_range_m=(lo * scale, min(hi * scale, MAX_ALLOWANCE_M)),
            )
        else:
            stock = _with_burrs(base, scale, variation.burrs_per_m, rng)
        out.append(replace(stock, material_factor=material))
    return out


def _with_burrs(base: Stock, scale: float, burrs_per_m: float, rng) -> Stock:
    s = base.profile_s_m
    length = float(s[-1])
    allowance = base.profile_allowance_m * scale
    burrs: list[Burr] = []
    count = int(round(burrs_per_m * length))
    for _ in range(50 * max(count, 1)):
        if len(burrs) == count:
            break
        blen = rng.uniform(*BURR_LENGTH_RANGE_M)
        lo, hi = LEAD_IN_M + blen, max(length - blen, LEAD_IN_M + blen)
        centre = rng.uniform(lo, hi)
        if all(abs(centre - b.center_m) > blen + b.length_m for b in burrs):
            burrs.append(Burr(float(centre), float(blen), float(rng.uniform(*BURR_HEIGHT_RANGE_M))))
    for burr in burrs:
        allowance = allowance + burr.profile(s)
    allowance = np.minimum(allowance, MAX_ALLOWANCE_M)
    return replace(base, profile_allowance_m=allowance, burrs=tuple(burrs))


def variation_rows(
    summaries: Sequence[Sequence[dict[str, Any] | None]],
    pairs: Sequence[tuple[str, str]],
    *,
    force_limit_N: float,
    peak_margin: float,
) -> list[dict[str, Any]]:
    """Per configuration (``pairs[i]``), its runs' summaries over the stocks
    (``summaries[i][j]``, None for a refused run): p50 and p95 of cycle time, peak force and
    wall error over the completed runs, the share completed, and the share within the limit
    (completed with a peak at most ``peak_margin`` over it, the choice rule's tolerance)."""
    rows = []
    for (controller, compensation), runs in zip(pairs, summaries, strict=True):
        done = [r for r in runs if r is not None and r["completed"]]
        n = len(runs)
        row: dict[str, Any] = {
            "controller": controller,
            "compensation": compensation,
            "stocks": n,
            "completed_share": len(done) / n if n else 0.0,
            "within_limit_share": (
                sum(r["force_peak_N"] <= (1 + peak_margin) * force_limit_N for r in done) / n
                if n
                else 0.0
            ),
            "force_limit_N": force_limit_N,
        }
        for key, source in VARIED_FIGURES:
            values = np.array([r[source] for r in done], dtype=float)
            unit = UNITS[key]
            row[f"{key}_p50_{unit}"] = float(np.median(values)) if values.size else None
            row[f"{key}_p95_{unit}"] = float(np.percentile(values, 95)) if values.size else None
        rows.append(row)
    return rows
