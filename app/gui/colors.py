"""The colours of the workbench's 3D scene, and the green-to-red scale of a deviation.

Colours are (r, g, b) in 0-255. The panels show some of them as legends (the learned and the
CAD-only program, ``COMPARISON_COLORS``; the pendant's ``static/teach.js`` repeats those two),
and the machining panel colours a machined wall's error with ``deviation_colors``.
"""

from __future__ import annotations

import numpy as np

WORKPIECE_COLOR = (150, 160, 175)
TOOL_COLOR = (70, 70, 80)
CUTTER_COLOR = (230, 180, 40)
CONTACT_COLOR = (220, 40, 40)
PUSH_COLOR = (40, 120, 230)
RAW_COLOR = (150, 150, 150)
FILTERED_COLOR = (40, 110, 220)
TARGET_COLOR = (240, 120, 20)
STALE_COLOR = (110, 110, 120)  # a path computed from inputs that changed since
GUIDE_COLOR = (20, 160, 90)
TAUGHT_WALL_COLOR = (255, 200, 0)  # the wall the next run will follow
STOP_COLOR = (220, 20, 20)
SELECTED_GUIDE_COLOR = (230, 40, 160)
REACH_COLORS = {"ok": (30, 170, 70), "near": (240, 160, 20), "unreachable": (220, 40, 40)}
PROPOSAL_LINE_COLOR = (120, 120, 200)
WALL_COLOR = (40, 140, 220)
# The learned and the CAD-only program, drawn side by side: two colours, the panels' legend.
COMPARISON_COLORS = {"learned": (0, 160, 110), "cad_only": (170, 60, 220)}
PICKED_WALL_COLOR = (255, 70, 20)  # the wall a click picked, before anything moves
OTHER_WALL_COLOR = (150, 150, 160)  # the other walls at that height (a groove's other side)
TABLE_COLOR = (196, 182, 160)
TOUCH_COLOR = (90, 90, 200)  # a calibration's touch before the touches fix a frame
FIT_COLOR = (40, 200, 120)  # the CAD where the calibration's fit places it


def deviation_colors(deviation_m: np.ndarray, scale_m: float) -> np.ndarray:
    """(n, 3) uint8 colours: green at 0, yellow at scale/2, red at and above ``scale_m``."""
    t = np.clip(np.asarray(deviation_m, dtype=float) / max(scale_m, 1e-9), 0.0, 1.0)
    stops = np.array([[30, 170, 70], [240, 200, 30], [220, 40, 40]], dtype=float)
    lo = np.where(t < 0.5, stops[0][:, None], stops[1][:, None]).T
    hi = np.where(t < 0.5, stops[1][:, None], stops[2][:, None]).T
    f = np.where(t < 0.5, t * 2, (t - 0.5) * 2)[:, None]
    return (lo + (hi - lo) * f).astype(np.uint8)
