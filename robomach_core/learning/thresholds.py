"""Every threshold of path learning, once: value, unit, reason, and how it scales.

docs/learning_model.md holds the same table for people (a test keeps the two equal). Each line
reads ``NAME = value  # unit | why | scales with``. A rule that needs a number takes it from
here; nothing in the learning package writes a bare threshold in a function body.
"""

from __future__ import annotations

# --- the wall: is this point at that wall, and which side ----------------------------------------
AT_WALL_GAP_M = 0.005  # m | a point whose cutter is farther than this from a wall was not taught on it (people leave points 0-3 mm off) | fixed: the operator's rule "within 1-3 mm"
NEARER_MARGIN_M = 0.00025  # m | one wall is nearer than another only by more than this (the mesh's facets) | fixed
WALL_FORCE_CLEAR_N = 2.0  # N | a force across the leg this large is a push against the wall, not the sensor's noise (0.3 N rms) | sensor noise
MIN_FORCE_VOTES = 2  # points | clear pushes needed to tell the side (all points when fewer) | fixed
MESH_MAJORITY = 0.75  # share | of the points that are nearer one wall, to tell the side from the mesh | fixed
