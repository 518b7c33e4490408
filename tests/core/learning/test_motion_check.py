"""The check before a run names what the run will hit (issue 31, point 6): the run's motion
along the route solved before it starts (``learning.motion_check``) against the run itself,
over generated loops (a fresh seed each run; ``ROBOMACH_SEED`` replays one): an arm, the pump
turned on the table, and the tool turned about its axis 0, 1 or 2 times round the loop (a
tool that faces each wall turns once). Causes are named by what supervision met."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from robomach_core.cell import TOOL_DOWN, Cell, CellConfig, GuidePoint, LeadThrough, cell_supervisor
from robomach_core.errors import SupervisionError
from robomach_core.learning.checks import guide_point_warnings
from robomach_core.learning.route import plan_route
from robomach_core.learning.run import learn_path
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.part import builtin_workpiece
from robomach_core.transforms import make_transform, rotation_about
from tests.envelope import replay, run_seed

SEED = run_seed()
# The pump's groove, outer wall, 2.5 mm off it (work object, mm): a loop of 12 points.
LOOP_WOBJ_MM = [
    (-85, -62.5), (0, -62.5), (85, -62.5), (98, -50), (98, 0), (98, 50),
    (85, 62.5), (0, 62.5), (-85, 62.5), (-98, 50), (-98, 0), (-98, -50),
]  # fmt: skip
STOP_WITHIN_M = 0.03  # where the check says the run stops, and where it does


def _rng(*key: object) -> np.random.Generator:
    return np.random.default_rng([SEED, zlib.crc32(repr(key).encode())])


def _loop(k: int):
    """A cell and its guide points: the tool turned ``turns`` times about its axis round the
    loop, each point's joints solved from the last (as a person jogging it there)."""
    rng = _rng("loop", k)
    arm = str(rng.choice(["ur10", "kr270", "irb4400"]))
    turns = int(rng.integers(0, 3))
    cad = builtin_workpiece("water_pump", robot=arm)
    turn = rotation_about("z", math.radians(float(rng.uniform(-20, 20))))
    cad = cad.placed(cad.T_base_wobj @ make_transform(turn, np.zeros(3)))
    cell = Cell(CellConfig(robot=arm, workpiece=cad, seed=int(rng.integers(2**31))))
    T_wobj = cad.T_base_wobj
    guides, q = [], cell.robot.home_rad
    for x, y in LOOP_WOBJ_MM:
        p = T_wobj[:3, :3] @ np.array([x, y, 17.0]) * 1e-3 + T_wobj[:3, 3]
        about = -turns * math.atan2(y, x)
        T = np.eye(4)
        T[:3, :3] = T_wobj[:3, :3] @ TOOL_DOWN @ rotation_about("z", about)
        T[:3, 3] = p
        q_new = cell.robot.ik(T, q)
        q_new[5] = q[5] + math.remainder(q_new[5] - q[5], 2 * math.pi)
        q = np.clip(q_new, cell.robot.lower_rad, cell.robot.upper_rad)
        guides.append(GuidePoint(T, q.copy(), 0.0))
    what = f"{replay(SEED)}: loop {k} on the {arm}, the tool turned {turns} times round it"
    return cell, guides, what


@pytest.mark.slow
@pytest.mark.parametrize("k", range(2))
def test_the_check_says_where_the_run_stops_and_why(k):
    cell, guides, what = _loop(k)
    settings = PathLearningSettings(wall_side="right")
    findings = guide_point_warnings(
        guides, settings, workpiece=cell.workpiece, tool_radius_m=cell.tool.radius_m,
        supervisor=cell_supervisor(cell),
    )  # fmt: skip
    motion = [f for f in findings if f.rule in ("wrist_turn", "joint_limit", "singularity",
                                                 "reach", "clearance")]  # fmt: skip
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    route = plan_route(guides, settings, workpiece=cell.workpiece, tool_radius_m=0.001)
    rec, _ = learn_path(cell, state.cell, route, settings, lt.estimator)
    said = "; ".join(f.message for f in motion) or "nothing"
    if rec.completed:
        assert not motion, f"{what}: the run completed, the check said {said}"
        return
    assert rec.stop is not None and rec.stop.cause == "supervision", f"{what}: {rec.stop_reason}"
    assert len(motion) == 1, f"{what}: the run stopped ({rec.stop_reason}), the check said {said}"
    (finding,) = motion
    if "axis 6" in rec.stop_reason and "joint limit" in rec.stop_reason:
        assert finding.rule == "wrist_turn", f"{what}: {said}"
        assert "keep the tool's turn about its axis the same" in finding.message, said
    else:
        assert finding.rule != "wrist_turn", f"{what}: {rec.stop_reason}; {said}"
    travelled = float(np.linalg.norm(np.diff(rec.position_m, axis=0), axis=1).sum())
    predicted = float(finding.message.split(" mm along the route")[0].rsplit(" ", 1)[1]) * 1e-3
    assert abs(predicted - travelled) <= STOP_WITHIN_M, (
        f"{what}: stopped after {travelled * 1e3:.0f} mm; the check said {said}"
    )


def test_a_pose_past_a_limit_is_named_as_supervision_names_it():
    cell = Cell(CellConfig(seed=0))
    supervisor = cell_supervisor(cell)
    q = cell.robot.home_rad.copy()
    assert supervisor.limit_at(q) is None
    q[5] = cell.robot.lower_rad[5] + math.radians(1.0)  # inside the 2 deg stop
    stop = supervisor.limit_at(q)
    assert stop is not None and stop.cause == "joint limit" and stop.axis == 6


@pytest.mark.parametrize(
    ("cause", "axis", "says", "never"),
    [
        ("joint limit", 6, "axis 6 is wound", "reach"),
        ("edge of reach", None, "beyond the ur10 arm's reach", "axis 6"),
        ("elbow singularity", 3, "beyond the ur10 arm's reach", "axis 6"),
        ("collision", None, "move the part", "reach"),
        ("joint limit", 2, "axis 2 is at the end of its range", "reach"),
        ("wrist singularity", 5, "passes a wrist singularity", "reach"),
    ],
)
def test_a_refusal_says_what_to_do_about_its_own_cause(cause, axis, says, never):
    exc = SupervisionError("stopped", cause=cause, axis=axis).with_cause_note(
        "ur10", place="--wobj"
    )
    assert says in str(exc) and never not in str(exc).split("; ", 1)[1]
    assert exc.cause == cause and exc.axis == axis


@pytest.mark.parametrize("k", range(3))
def test_the_check_names_the_spindle_against_the_part_on_the_approach_as_the_run_meets_it(k):
    """The approach's last move, straight down to where the run starts, is part of the run's
    motion: a first point taught with the tool leaning over its wall brings the spindle
    against the part there, and the run raised a supervision error the check had not said
    (a tilted plate, envelope set 9609494606522070085). The check names it exactly when the
    approach meets it (G1 leant 0-45 deg over the part, fresh each run; from about 30 deg the
    spindle meets it)."""
    from robomach_core.errors import CancelledError

    cell, guides, what = _loop(k)
    tilt_deg = float(_rng("approach", k).uniform(*[(0, 15), (32, 45), (0, 45)][k]))
    R_wobj = cell.workpiece.cad().T_base_wobj[:3, :3]
    lean = R_wobj @ rotation_about("x", -math.radians(tilt_deg)) @ R_wobj.T
    T = guides[0].T_base_tcp.copy()
    T[:3, :3] = lean @ T[:3, :3]
    guides[0] = GuidePoint(T, cell.robot.ik(T, guides[0].joints_rad), 0.0)
    what += f", G1 leant {tilt_deg:.1f} deg over the part"
    settings = PathLearningSettings(wall_side="right")
    findings = guide_point_warnings(
        guides, settings, workpiece=cell.workpiece, tool_radius_m=cell.tool.radius_m,
        supervisor=cell_supervisor(cell),
    )  # fmt: skip
    said = [f.message for f in findings if f.message.startswith("the approach would stop")]
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    route = plan_route(guides, settings, workpiece=cell.workpiece, tool_radius_m=0.001)
    try:  # the run's approach, then cancelled at its first period
        learn_path(cell, state.cell, route, settings, lt.estimator, cancelled=lambda: True)
        met = ""
    except SupervisionError as exc:
        met = str(exc)
    except CancelledError:
        met = ""
    assert bool(said) == bool(met), f"{what}: the approach met {met or 'nothing'}; said {said}"
    if met:
        assert "collision" in met and "collision" in said[0], f"{what}: {met}; {said}"
