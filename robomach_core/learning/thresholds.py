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

# --- the guide-point planner: walls, heights, corners, points (planner.py, walls.py) -------------
MAX_PICK_DISTANCE_M = 0.002  # m | a picked point farther than this from the mesh is not on the part | fixed: a click lands on the surface, a typed point within a few tenths
WALL_NORMAL_Z_MAX = 0.5  # cos | a picked face within 60 deg of the floor's normal is a floor or a top, not a wall | fixed
FLOOR_TILT_MAX_DEG = 45.0  # deg | a face below the tool tilted less than this from the work object's x-y plane is a floor (the parts' 10-20 deg tilts and more) | fixed
LEVEL_FLOOR_RAD = 1e-4  # rad | a floor within this of the work object's x-y plane is level: its section is the work object's (0.02 mm over 200 mm) | fixed
AMBIGUOUS_CLICK_RADII = 1.0  # tool radii | a point whose distances to two walls differ by less than this is between them: refused | tool radius
CUTTER_FLOOR_CLEARANCE_M = 0.001  # m | the cutter's lowest point stays this far above the floor (a casting's floor may be 0.5 mm off its mesh) | fixed: the part's deviation
CONTACT_BELOW_TOP_RADII = 0.5  # tool radii | the TCP (the ball's contact height on a wall) stays this far below the wall's top ... | tool radius
CONTACT_BELOW_TOP_M = 5e-4  # m | ... and at least this far (a wall's rim is its weakest, burred edge) | fixed
SPINDLE_CLEARANCE_M = 0.005  # m | the spindle body stays this far above the part within its radius | fixed
STITCH_M = 2e-5  # m | section chains ending this close are one wall across a crack in the mesh | the mesh's precision
CORNER_RADIUS_M = 0.015  # m | the wall turning on a tighter radius than this is a corner (the pump's 6 mm corners and 3 mm fillets) | fixed: the parts' fillets
CORNER_TURN_MIN_DEG = 15.0  # deg | a corner turning less than this needs no point (a leg across it keeps the wall) | fixed
OUTSIDE_CORNER_DEG = 45.0  # deg | a corner turning round the material this much gets a point at its middle (the chord between its runs would cut the part) | fixed
SLOT_END_DEG = 150.0  # deg | a corner group turning back round the free side this much ... | fixed
SLOT_END_MAX_M = 0.025  # m | ... within this length is a slot's end: the wall to follow ends there | slot width
MIN_RUN_M = 0.011  # m | corners closer than this are one group; a shorter run gets no point | fixed: the pump's 14 mm bosses
LONG_RUN_M = 0.040  # m | a run this long gets two points, at LONG_RUN_POINTS_AT, bracketing its corners | fixed
LONG_RUN_POINTS_AT = (0.2, 0.8)  # share of the run | where a long run's two points stand | fixed
WALL_END_MARGIN_M = 5e-4  # m | an open wall's end points stand radius + gap + this from its ends | fixed
LEG_CLEARANCE_M = 3e-4  # m | a leg's chord keeps the cutter this far off the wall, else a point is added ... | fixed
MAX_LEG_GAP_M = 0.012  # m | ... and the wall no farther than this from the chord | fixed
MIN_POINT_SPACING_M = 0.0015  # m | along the wall, two points closer than this are one | fixed
MAX_ADDED_POINTS = 200  # points | the planner stops adding points after this many (a wall it cannot bracket) | fixed
JOINT_JUMP_DEG = 60.0  # deg | an axis turning this much between neighbouring points is a change of configuration: "near" | fixed
OPEN_EDGE_ENTRY_M = 0.003  # m | on a part that may be off its mesh, the operator comes down this far off an open edge (a groove: its middle) | fixed: the fixture error
EXAMPLE_BELOW_TOP_M = 0.003  # m | the example operator points at the wall this far below its top | fixed
CUTTER_FIT_M = 2e-4  # m | free space narrower than the cutter's diameter plus this is too narrow to enter | fixed
ROUND_LOOP_POINTS = 4  # points | a closed wall without corners (a round boss) gets this many, evenly | fixed
