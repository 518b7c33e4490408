"""What the run's motion will meet, said before it starts (issue 31, point 6).

PROBLEM   A run stops at the first supervision limit it meets: axis 6 wound to its end by a
          tool turned about its axis round a loop, a stretch beyond the arm's reach, the spindle
          against the part. Met by the run, it costs the run; named by guess afterwards (a
          wind-up called a reach problem) it sends the person the wrong way.
STRATEGY  The run's motion is known before it starts: it comes straight down to where it
          starts (``run.run_start``) from ``APPROACH_CLEARANCE_M`` above, in the first point's
          arm configuration with axis 6 unwound for the route (``run.start_joints``), then follows
          the wall the route's walk found on the mesh (``route.walks``: the cutter rolled along
          it; the straight legs without a mesh), turning the tool as the law does (the slerp
          R_a exp(f omega), f the progress along the leg, ``law.turn_towards``). The poses are
          solved every ``MOTION_CHECK_STEP_M`` in order, each from the last (the arm's branch,
          each joint's nearest equivalent: the run moves continuously), and judged by the
          cell's own supervisor (``Supervisor.limit_at``): the first limit crossed is the
          finding, with where (the leg, mm along the route) and the cause the supervisor names.
          Axis 6 adds how far the tool turns about its axis round the route, how far the axis
          can, and what to turn: the points, back to the first one's turn (the run already
          starts axis 6 a whole turn either way when that fits).
SOLUTION  ``motion_findings(route, supervisor) -> tuple[GuideWarning, ...]`` (none, or the first
          limit).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..cell import Supervisor
from ..errors import RobomachError
from . import thresholds as th
from .findings import GuideRule, GuideWarning
from .route import LearningRoute, Leg
from .run import axis6_round_route, run_start, start_joints

RULE_OF_CAUSE: dict[str, GuideRule] = {
    "joint limit": "joint_limit",
    "wrist singularity": "singularity",
    "shoulder singularity": "singularity",
    "elbow singularity": "reach",
    "edge of reach": "reach",
    "collision": "clearance",
}


def _samples(route: LearningRoute) -> list[tuple[int, np.ndarray]]:
    """(leg index, tool-centre point) along the route, ``MOTION_CHECK_STEP_M`` apart."""
    out: list[tuple[int, np.ndarray]] = []
    last = None
    for k, leg in enumerate(route.legs):
        walk = route.walks[k].points_m if k < len(route.walks) else np.empty((0, 3))
        if len(walk) < 2:
            n = max(2, int(leg.length / th.MOTION_CHECK_STEP_M) + 1)
            walk = leg.a + (leg.b - leg.a) * np.linspace(0.0, 1.0, n)[:, None]
        for i, p in enumerate(walk):
            if (
                last is None
                or i == len(walk) - 1
                or np.linalg.norm(p - last) >= (th.MOTION_CHECK_STEP_M)
            ):
                out.append((k, np.asarray(p, dtype=float)))
                last = p
    return out


def _pose(leg: Leg, p: np.ndarray) -> np.ndarray:
    """The tool pose the law turns to at ``p`` on ``leg`` (``law.turn_towards``)."""
    f = min(max(float((p - leg.a) @ leg.xp) / leg.length, 0.0), 1.0)
    T = np.eye(4)
    T[:3, :3] = leg.Ra @ pin.exp3(leg.omega * f)
    T[:3, 3] = p
    return T


def _approach(
    route: LearningRoute, supervisor: Supervisor
) -> tuple[np.ndarray, GuideWarning | None]:
    """The approach's last move, straight down to where the run starts, every
    ``MOTION_CHECK_STEP_M`` in the first point's orientation: (the joints at the start, the
    first limit it crosses as a finding, or None)."""
    robot, axis = supervisor.robot, route.axis
    start = run_start(route)[0]
    T = route.guides[0].T_base_tcp.copy()
    q = start_joints(robot, route.guides, route.closed)
    n = int(th.APPROACH_CLEARANCE_M / th.MOTION_CHECK_STEP_M) + 1
    for above in np.linspace(th.APPROACH_CLEARANCE_M, 0.0, n):
        T[:3, 3] = start - axis * above
        try:
            q_new = robot.ik(T, q)
        except RobomachError:
            return q, None  # the first point's reach is the route's finding (below)
        q = q + np.array([math.remainder(d, 2 * math.pi) for d in q_new - q])
        stop = supervisor.limit_at(q)
        if stop is not None:
            rule = RULE_OF_CAUSE.get(stop.cause, "reach")
            where = (
                f"coming down to G1, {above * 1e3:.0f} mm above where the run starts"
                if above >= th.MOTION_CHECK_STEP_M
                else "where it starts, at G1"
            )
            return q, GuideWarning(1, rule, (
                f"the approach would stop {where}: {stop.message}; {_FIX[rule]}"
            ))  # fmt: skip
    return q, None


_FIX = {
    "joint_limit": "place the part elsewhere (the work object), or teach the points with the "
    "tool turned so the arm stays in range",
    "singularity": "place the part elsewhere (the work object), or tilt or turn the tool so the "
    "arm passes clear of it",
    "reach": "place the part nearer the arm (the work object's x, y, z)",
    "clearance": "move the part (the work object) or change the tool's orientation so the arm "
    "and spindle stay clear",
}


def motion_findings(route: LearningRoute, supervisor: Supervisor) -> tuple[GuideWarning, ...]:
    """The first limit the run's motion (its approach's last move, then along ``route``)
    meets (module docstring), as a finding; () when the arm follows the whole route.
    ``supervisor``: the cell's (``supervision.cell_supervisor``), with its arm."""
    samples = _samples(route)
    if not samples:
        return ()
    robot = supervisor.robot
    q, found = _approach(route, supervisor)
    if found is not None:
        return (found,)
    travelled, previous = 0.0, samples[0][1]
    for k, p in samples:
        leg = route.legs[k]
        travelled += float(np.linalg.norm(p - previous))
        previous = p
        where = (
            f"on the leg G{leg.first + 1} -> G{leg.last + 1}, {travelled * 1e3:.0f} mm along the "
            "route"
        )
        try:
            q_new = robot.ik(_pose(leg, p), q)
        except RobomachError as exc:
            return (_finding(leg, "reach", (
                f"the run would stop {where}: the arm cannot reach the tool's pose there "
                f"({exc}); place the part nearer the arm (the work object's x, y, z) or turn the "
                "tool's axis"
            )),)  # fmt: skip
        # each joint's nearest equivalent to the last: the run turns continuously
        q = q + np.array([math.remainder(d, 2 * math.pi) for d in q_new - q])
        stop = supervisor.limit_at(q)
        if stop is None:
            continue
        if stop.cause == "joint limit" and stop.axis == 6:
            return (_wind_up(robot, route, leg, where, q),)
        rule = RULE_OF_CAUSE.get(stop.cause, "reach")
        return (_finding(leg, rule, f"the run would stop {where}: {stop.message}; {_FIX[rule]}"),)
    return ()


def _finding(leg: Leg, rule: GuideRule, message: str) -> GuideWarning:
    return GuideWarning(leg.first + 1, rule, message)


def _wind_up(robot, route: LearningRoute, leg: Leg, where: str, q: np.ndarray) -> GuideWarning:
    """Axis 6 wound to its end: how far the tool turns round the route, how far the axis can,
    and what to turn."""
    turns = axis6_round_route(robot, route.guides, route.closed)
    turn = max(turns) - min(turns)
    span = float(robot.upper_rad[5] - robot.lower_rad[5])
    limit = robot.upper_rad[5] if q[5] > 0 else robot.lower_rad[5]
    said = (
        f"the run would stop {where}: axis 6 reaches its limit of {math.degrees(limit):.0f} deg "
        f"there. The tool turns {math.degrees(turn):.0f} deg about its axis round the route, "
        f"and axis 6 has {math.degrees(span):.0f} deg in all (less from where G1 leaves it)"
    )
    # The run already starts with axis 6 a whole turn either way when that fits the route
    # (``run.start_joints``): what is left is the turn taught into the points.
    points = range(min(len(turns), len(route.guides)))
    most = max(points, key=lambda k: abs(turns[k] - turns[0]))
    turned = math.degrees(turns[most] - turns[0])
    return _finding(leg, "wrist_turn", (
        f"{said}: keep the tool's turn about its axis the same at every point (G{most + 1} is "
        f"turned {turned:+.0f} deg from G1; a spinning cutter does not mind)"
    ))  # fmt: skip
