# ruff: noqa: E501 - one line per threshold: the table docs/learning_model.md is checked against
"""Every threshold of path learning, once: value, unit, reason, and how it scales.

docs/learning_model.md holds the same table for people (a test keeps the two equal). Each line
reads ``NAME = value  # unit | why | scales with``. A rule that needs a number takes it from
here; nothing in the learning package writes a bare threshold in a function body.
"""

from __future__ import annotations

import math

# fmt: off
# --- the wall: is this point at that wall, and which side ----------------------------------------
AT_WALL_GAP_M = 0.005  # m | a point whose cutter is farther than this from a wall was not taught on it (people leave points 0-3 mm off) | fixed: the operator's rule "within 1-3 mm"
NEARER_MARGIN_M = 0.00025  # m | one wall is nearer than another only by more than this (the mesh's facets) | fixed
WALL_FORCE_CLEAR_N = 2.0  # N | a force across the leg this large is a push against the wall, not the sensor's noise (0.3 N rms) | sensor noise
MIN_FORCE_VOTES = 2  # points | clear pushes needed to tell the side (all points when fewer) | fixed
MESH_MAJORITY = 0.75  # share | of the points that are nearer one wall, to tell the side from the mesh | fixed
WALL_FACE_MAX_COS = math.cos(math.radians(45.0))  # 1 | a face whose normal is within 45 deg of across the tool axis is a wall, else a floor or a top | fixed

# --- the height: what the route holds along the tool axis ----------------------------------------
FLOOR_SEARCH_M = 0.03  # m | a floor farther than this below the cutter is not the one the route runs over | fixed
PLANE_SPREAD_M = 0.01  # m | without a floor, the points' plane has no slope along a direction they spread less than this over (rms) | fixed
FLOOR_ABOVE_M = 0.002  # m | the floor is looked for from this far above the cutter's centre (a cutter pressed into it still finds it) | tool radius (added to it)
WALK_MATCH_M = 0.001  # m | the run takes the floor the walk measured nearest to the tool within this, and measures it itself farther off | fixed
STEP_LOOKAHEAD_M = 0.003  # m | the floor is also measured this far (+ the cutter's radius) ahead, so a step up is climbed before the cutter meets it | learning speed: enough up to 20 mm/s
REFERENCE_SPACING_M = 0.001  # m | the floor under the tool is measured anew after this much travel; a plane extrapolates between | fixed: spatial, not timed
FLOOR_CONE_TAN = math.tan(math.radians(37.0))  # 1 | a force along the axis is the floor's only beyond a wall contact's cone: walls up to 20 deg off the axis and friction up to 0.3 (17 deg) | friction and wall tilt
FLOOR_FORCE_N = 1.5  # N | ... and beyond this (five times the sensor's noise) | sensor noise
LIFT_DECAY_M = 0.005  # m | a lift off a floor the route did not know fades over this much travel, then the floor is felt again | fixed: spatial
HEIGHT_TIME_S = 0.05  # s | the height returns to the route's within about this (a position loop; the route's rate is fed forward) | fixed
HEIGHT_SPEED_M_S = 0.05  # m/s | the fastest the height loop moves the tool along its axis (a 2 mm step climbed within 3 mm of travel at 20 mm/s) | fixed
CLIMB_SHARE = 0.5  # x HEIGHT_SPEED_M_S | the advance is slowed where the route's height changes so fast along a leg (a point taught far above a neighbour close by) that following it would take more than this share of the height loop's speed | fixed

# --- following the wall ---------------------------------------------------------------------------
CONTACT_FLAG_N = 1.0  # N | a measured contact force above this counts as contact | sensor noise
WALL_DIRECTION_TIME_S = 0.02  # s | low-pass of the measured wall direction (the sensor's noise is per sample) | fixed
BEHIND_COS = math.cos(math.radians(135.0))  # 1 | a contact force more than 135 deg off the wall direction is the wall behind the tool | fixed
SLOW_FROM = 1.25  # x F_ref | full learning speed up to this force ... | force reference
SLOWEST_AT = 2.0  # x F_ref | ... falling to SLOWEST at this force (a wall turning towards the tool) | force reference
SLOWEST = 0.1  # x speed | the slowest advance, near the force limit | learning speed
FIRST_SEARCH_ACROSS_M = 0.006  # m | the first search goes straight across this far before it also advances | gap: people leave points 0-3 mm off, twice that
SEARCH_TURN_M = 0.006  # m | out of contact this long after a wall, the search turns across the leg again | gap
TURN_RATE_RAD_S = 0.5  # rad/s | the tool's orientation follows the route's at most this fast | fixed

# --- legs: where they end ----------------------------------------------------------------------
LEG_END_MARGIN_M = 0.002  # m | a leg ends this far before its guide point's plane (at most a quarter of the leg) | fixed
PLANE_END_WITHIN_M = 0.01  # m | ... where the tool is within this (+ the cutter's radius) of the point across the axis: a wall that detours round the part crosses the plane far from the point, and that is not the leg's end (a T-boss leg whose chord cuts through the stem ended on the bar's top, 44 mm from its point) | gap: twice AT_WALL_GAP_M; tool radius (added to it)
NEAR_END_M = 0.006  # m | ... or at the nearest approach to its guide point, when that comes within this across the axis | gap: twice the farthest a point is left
END_PASSED_M = 0.001  # m | ... and recedes by this (past the nearest approach; a tool backing off an inside corner for a moment does not end it) | fixed
CLOSE_LOOP_M = 0.001  # m | a closed route ends at its nearest approach to where the contact first held the set force, within this beyond the cutter's radius (a contact on a corner is on the cutter's arc round it) | tool radius (added to it)
CLOSE_PASSED_M = 0.0005  # m | ... once the tool has receded this far past that nearest approach (the wall's direction wiggles at slow feeds: a loop that ended at the first step away stopped 1.7 mm short of its start and left a ridge) | fixed
CLOSE_LOOP_OVERRUN_M = 0.01  # m | ... or this far past the last point's plane | fixed

# --- protections: stop and say why ---------------------------------------------------------------
LOST_WALL_M = 0.03  # m | the tool searched this far without finding the wall | fixed
ROUTE_WANDER_FRACTION = 1.0  # x leg | the wall may lead the tool this far off the leg's line (or what the mesh says it runs, + WANDER_MARGIN_M) | leg length
WANDER_MARGIN_M = 0.01  # m | the wall may lead the tool this much farther off a leg than the mesh's wall runs | fixed
LEG_DETOUR_FACTOR = 4.0  # x leg | a leg's wall longer than this (+ LEG_DETOUR_EXTRA_M) is not the wall between its points | leg length
LEG_DETOUR_EXTRA_M = 0.05  # m | ... | fixed
PENETRATION_STOP_FRACTION = 0.5  # x tool radius | a cutter deeper than this in the part is a collision, not a contact | tool radius
APPROACH_CLEARANCE_M = 0.03  # m | the approach travels this far above the first point | fixed

# --- the route's check before any motion ---------------------------------------------------------
WALK_STEP_M = 0.0005  # m | the route is walked along the mesh's wall in steps of this, before the run | fixed
OVER_TOP_SIN = math.sin(math.radians(45.0))  # 1 | the wall met more than 45 deg below the cutter's equator: the cutter rides over the wall's top edge | fixed
OVER_TOP_M = 0.002  # m | a route whose walk rides over the wall's top this far is refused | fixed
OPEN_RETURN_M = 0.02  # m | a leg that comes back along the other wall of the same free space this far, with no point there, means an open wall taught as a loop | fixed
FIRST_WALK_SHARE = 0.5  # x walk | the first point starts from the wall it stands by, not the one its chord's side gives, when the first leg's walk from it is shorter than this share | fixed
HEAVY_CONTACT_FRACTION = 0.5  # x force limit | a guide point recorded pressing this hard is half-way to a stop | force limit
TOUCH_WITHOUT_PUSH_N = 0.8  # N | a force between this and WALL_FORCE_CLEAR_N touches without telling the side | sensor noise
MIN_SPACING_M = 0.001  # m | closer guide points give a leg with no direction | fixed
ONE_STATION_M = 0.006  # m | a neighbour nearer than this, the way to it more across the point's wall than along it, stands at its station (one pressed on the wall, one a gap off it): no direction of travel | gap: twice the farthest a point is left
MOTION_CHECK_STEP_M = 0.002  # m | the check before a run solves the arm's pose along the route this far apart (the run moves continuously between) | fixed

# --- after learning: is the program on the taught wall -------------------------------------------
TAUGHT_WALL_TOLERANCE_M = 0.001  # m | the program passes this near every taught wall point (the CAD may differ from the part by this) | fixed
OPEN_END_SHORT_M = 0.006  # m | an open route's program may start (end) this far short of its first (last) point's wall point: the force builds over the first mm of a run | gap: as NEAR_END_M
TAUGHT_WALL_HEIGHT_BAND_M = 0.005  # m | ... measured across the axis among program points within this height of the point or its neighbours | fixed
FOOT_ON_FACE_COS = math.cos(math.radians(5.0))  # 1 | a guide point's nearest wall point is its taught wall only when it is the foot on a wall face (the way to it within 5 deg of the face's normal), a wall standing at the point's height; an edge (a riser's top, a corner) is not: the wall is then found by a ray that way | fixed
FAN_HALF_ANGLE_RAD = math.radians(60.0)  # rad | "that way" for a guide point's taught wall: its nearest wall within this of the side's direction, else the nearest met by rays within this of it | fixed: a corner's chord turns the side up to 45 deg off the wall's normal
FAN_RAYS = 13  # 1 | ... that many rays, 10 deg apart | fixed

# --- the guide-point planner: picks, floors, heights, corners, points (teaching/pointing.py) ---
MAX_PICK_DISTANCE_M = 0.002  # m | a picked point farther than this from the mesh is not on the part | fixed: a click lands on the surface, a typed point within a few tenths
LEVEL_FLOOR_RAD = 1e-4  # rad | a floor within this of the work object's x-y plane is level, and its section the work object's (0.02 mm over 200 mm) | fixed
AMBIGUOUS_CLICK_RADII = 1.0  # x tool radius | a point whose distances to the two walls across the free space differ by less than this is between them: refused | tool radius
CUTTER_FLOOR_CLEARANCE_M = 0.001  # m | the cutter's lowest point stays this far above the floor (a casting's floor may be 0.5 mm off its mesh) | fixed: the part's deviation
CONTACT_BELOW_TOP_RADII = 0.5  # x tool radius | the TCP (the ball's contact height on a wall) stays this far below the wall's top ... | tool radius
CONTACT_BELOW_TOP_M = 5e-4  # m | ... and at least this far below it (a wall's rim is its weakest and burred edge, no place to press on) | fixed
SPINDLE_CLEARANCE_M = 0.005  # m | the spindle body stays this far above the part within its radius (the supervisor stops a few mm from it) | fixed
STITCH_M = 2e-5  # m | section chains ending this close to each other are one wall across a crack in the mesh | the mesh's precision
CORNER_RADIUS_M = 0.015  # m | the wall turning on a tighter radius than this is a corner (the pump's 6 mm corners and 3 mm fillets) | fixed: the parts' fillets
CORNER_TURN_MIN_DEG = 15.0  # deg | a corner turning less than this needs no point of its own (a leg across it keeps the wall) | fixed
OUTSIDE_CORNER_DEG = 45.0  # deg | a corner turning round the material this much gets a point at its middle (the chord between its runs would cut the part) | fixed
SLOT_END_DEG = 150.0  # deg | a corner group turning back round the free side this much, within SLOT_END_MAX_M, is a slot's end: the wall to follow ends there | fixed
SLOT_END_MAX_M = 0.025  # m | ... the longest such a group may be (a slot's end cap is its width across, a tight U-turn of the wall) | slot width
MIN_RUN_M = 0.011  # m | corners closer than this along the wall are one group; a shorter run between groups gets no point | fixed: the pump's 14 mm bosses
LONG_RUN_M = 0.040  # m | a straight run this long gets two points, LONG_RUN_END_SHARE from its ends, bracketing its corners | fixed
EQUAL_STRETCH_M = 0.001  # m | two straight stretches this close in length are equally long (a block's two sides): the one nearer the pick starts a closed loop's count | fixed
LONG_RUN_END_SHARE = 0.2  # x run | where a long run's two points stand, from each end (one point in the middle of a shorter run) | fixed
WALL_END_MARGIN_M = 5e-4  # m | an open wall's end points stand this much more than the tool radius and gap from its ends | fixed
LEG_CLEARANCE_M = 3e-4  # m | a leg's chord keeps the cutter this far off the wall (at most half the gap its own points keep), else a point is added at the worst place ... | fixed; gap (half of it at most)
MAX_LEG_GAP_M = 0.012  # m | ... and the wall no farther than this from the chord (the route would leave it to a long search) | fixed
MAX_ADDED_POINTS = 200  # points | the planner stops adding points after this many and says so (a wall it cannot bracket) | fixed
ROUND_LOOP_POINTS = 4  # points | a closed wall without any corner (a round boss or pocket) gets this many points, evenly spread | fixed
JOINT_JUMP_DEG = 60.0  # deg | an axis turning this much between neighbouring points is a change of configuration: "near" | fixed
CUTTER_FIT_M = 2e-4  # m | free space narrower than the cutter's diameter plus this is too narrow to enter: unreachable | fixed
OPEN_EDGE_ENTRY_M = 0.003  # m | on a part that may be off its mesh, the operator comes down this far off an open edge (a groove: its middle) | fixed: the fixture error
UNEVEN_FLOOR_NOTE_M = 1e-4  # m | proposed points whose heights differ by more than this stand on a stepped or sloped floor: a note says so | fixed
EXAMPLE_BELOW_TOP_M = 0.003  # m | the example operator points at the built-in part's known wall this far below its top | fixed
# fmt: on


def table_markdown() -> str:
    """This module's thresholds as the markdown table docs/learning_model.md holds: one row per
    ``NAME = value  # unit | why | scales with`` line, the value as Python evaluated it."""
    import re
    from pathlib import Path

    rows = ["| name | value | unit | why | scales with |", "|---|---|---|---|---|"]
    pattern = re.compile(r"^([A-Z][A-Z0-9_]*) = .*?  # (.*)$")
    for line in Path(__file__).read_text().splitlines():
        m = pattern.match(line)
        if m:
            name, (unit, why, scales) = m.group(1), (p.strip() for p in m.group(2).split("|"))
            rows.append(f"| `{name}` | {globals()[name]:.6g} | {unit} | {why} | {scales} |")
    return "\n".join(rows) + "\n"


if __name__ == "__main__":
    print(table_markdown(), end="")
