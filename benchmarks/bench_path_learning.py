"""Real-time factor of path learning on the water pump, and what one 4 ms period costs.

Run: python benchmarks/bench_path_learning.py [--repeats N] [--quick]

Prints the simulated seconds per wall second of ``learn_path`` (median over repeats), the cost
of one control period, in microseconds and in units of references measured in the same run
(a fixed pinocchio workload: ``computeJointJacobians``, frame placements, the TCP's Jacobian
and pose, whose cost our code does not change; and one ``Cell.step``), so that figures from a
loaded machine compare; then the period broken down:
supervision (with the IK step inside it), the cell (kinematics, contact, sensor), the force
loop (the law and the recording's row) and the recording built at the end, from a run with
timers around each part. Then, off the example: sloppy guide points on the block's outer wall
(tests/sloppy_guides.py), where the spindle overhangs the part's edge and supervision measures
its clearance every period. ``--quick`` leads the robot to the first two guide points only and
learns that open stretch once, and one sloppy set once (a smoke test, not a measurement).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np
import pinocchio as pin

from robomach_core import _kernels
from robomach_core.cell import CONTROL_PERIOD_S, Cell, LeadThrough, cell_supervisor
from robomach_core.learning import run as path_learning
from robomach_core.learning.law import record_row
from robomach_core.learning.route import plan_route
from robomach_core.learning.run import learn_path
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.teaching import guide_plan, scripted_leadthrough


def per_call_us(fn: Callable[[], object], n: int) -> float:
    samples = []
    for _ in range(5):
        t = time.perf_counter()
        for _ in range(n):
            fn()
        samples.append((time.perf_counter() - t) / n * 1e6)
    return statistics.median(samples)


@numba.njit(cache=True)
def _ik_steps(q, T, J, T_target, lower, upper, n):  # noqa: ANN001, ANN202
    out = q
    for _ in range(n):
        out = _kernels.ik_newton_step(q, T, J, T_target, lower, upper, 1e-4)
    return out


@numba.njit(cache=True)
def _row_writes(reading, T, q, wrench, w, record, n):  # noqa: ANN001, ANN202
    for i in range(n):
        record_row(record[i % record.shape[0]], 0.1, q, T, reading, wrench, 10.0, 1.0, w, 2.0)
    return record


def in_kernel_us(fn: Callable[[int], object], n: int) -> float:
    """Cost of one iteration of a compiled loop (no Python call per iteration)."""
    fn(1)
    samples = []
    for _ in range(5):
        t = time.perf_counter()
        fn(n)
        samples.append((time.perf_counter() - t) / n * 1e6)
    return statistics.median(samples)


class PartTimer:
    """Timers around the parts of the period (patched on the objects the loop uses), counting
    each part's own time (a nested part's is its own), from ``start()`` on."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self.active = False
        self._stack: list[str] = []
        self._undo: list[Callable[[], None]] = []

    def wrap(self, owner: object, name: str, part: str) -> None:
        inner = getattr(owner, name)
        seconds, calls, stack = self.seconds, self.calls, self._stack
        clock = time.perf_counter

        def timed(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
            if not self.active:
                return inner(*args, **kwargs)
            stack.append(part)
            t = clock()
            try:
                return inner(*args, **kwargs)
            finally:
                elapsed = clock() - t
                stack.pop()
                seconds[part] += elapsed
                calls[part] += 1
                if stack:
                    seconds[stack[-1]] -= elapsed

        had = name in vars(owner)
        setattr(owner, name, timed)
        self._undo.append(lambda: setattr(owner, name, inner) if had else delattr(owner, name))

    def restore(self) -> None:
        for undo in reversed(self._undo):
            undo()

    @staticmethod
    def overhead_s() -> float:
        """What one timed call adds (the wrapper's own cost)."""
        probe = PartTimer()
        probe.active = True
        holder = type("Holder", (), {"f": staticmethod(lambda: None)})
        probe.wrap(holder, "f", "probe")
        return max(0.0, per_call_us(holder.f, 20000) - per_call_us(lambda: None, 20000)) * 1e-6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="two guide points, one run")
    args = parser.parse_args()
    repeats, calls = (1, 50) if args.quick else (args.repeats, 3000)

    cell = Cell()
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    intents = None
    learning = PathLearningSettings(closed=not args.quick)
    # The scripted operator's lead-through, ``repeats`` times from the same start and seed
    # (the first run also loads the compiled kernels): the median.
    start, lead_walls = state, []
    for _ in range(repeats):
        rng = np.random.default_rng(0)
        if args.quick:
            intents = guide_plan(cell.workpiece, cell.tool.radius_m, rng)[:2]
        t = time.perf_counter()
        state, guides = scripted_leadthrough(lt, start, cell.workpiece, rng, intents=intents)
        lead_walls.append(time.perf_counter() - t)
    lead_wall = float(np.median(lead_walls))
    print(
        f"lead-through: {state.cell.time_s:.1f} s simulated in {lead_wall:.2f} s, median of "
        f"{repeats} (x{state.cell.time_s / lead_wall:.1f}; runs "
        + ", ".join(f"{w:.2f} s" for w in lead_walls)
        + ")"
    )

    # References, measured between the runs: a fixed pinocchio workload (joint Jacobians and
    # frame placements, then the TCP's Jacobian and pose) and one cell step.
    model, data, tcp = cell.robot.model, cell.robot.model.createData(), cell.robot.tcp_frame_id
    q_ref = state.cell.q_motor.copy()

    def fk_jacobian() -> None:
        pin.computeJointJacobians(model, data, q_ref)
        pin.updateFramePlacements(model, data)
        pin.getFrameJacobian(model, data, tcp, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        _ = data.oMf[tcp].homogeneous

    factors, per_step, fk_us, cell_us, plans = [], [], [], [], []
    for _ in range(repeats):
        fk_us.append(per_call_us(fk_jacobian, calls))
        c = Cell()
        t = time.perf_counter()
        route = plan_route(
            guides, learning, workpiece=c.workpiece.cad(), tool_radius_m=c.tool.radius_m
        )
        plans.append(time.perf_counter() - t)
        t = time.perf_counter()
        rec, end = learn_path(c, state.cell, route, learning, lt.estimator)
        wall = time.perf_counter() - t
        factors.append(rec.time_s[-1] / wall)
        per_step.append(wall / len(rec) * 1e6)
        cell_us.append(per_call_us(lambda c=c, end=end: c.step(end, end.q_motor), calls // 3))
    period, fk, one_cell = (statistics.median(v) for v in (per_step, fk_us, cell_us))
    print(
        f"path learning: {len(rec)} samples, {rec.time_s[-1]:.1f} s simulated; "
        f"real-time factor median x{statistics.median(factors):.1f} "
        f"(runs: {', '.join(f'x{f:.1f}' for f in factors)}); "
        f"{period:.1f} us per {CONTROL_PERIOD_S * 1e3:.0f} ms period"
    )
    print(
        f"  one period = {period / fk:.1f} x the pinocchio reference ({fk:.2f} us) "
        f"= {period / one_cell:.2f} x one whole cell step ({one_cell:.1f} us), measured in this run"
    )
    print(
        f"  the route planned before it (the side, the heights, the walk on the mesh): "
        f"{statistics.median(plans):.2f} s, not in the factor"
    )
    print("  aim: x150 real time (27 us per period), x200 (20 us)")

    # The period broken down: one more run with timers around its parts (after the approach).
    c = Cell()
    supervisor = cell_supervisor(c)
    timer = PartTimer()
    timer.wrap(supervisor, "supervise_increment", "supervision (limits, IK step)")
    timer.wrap(c, "step", "cell: arm-side deflection, the rest")
    timer.wrap(c.robot, "fk_and_jacobian", "cell: kinematics (pinocchio FK + Jacobian)")
    timer.wrap(c.contact_model, "evaluate", "cell: contact (coal, nearest face, force)")
    timer.wrap(c.sensor, "measure", "cell: F/T sensor reading")
    timer.wrap(path_learning, "controller_period", "force loop (law, turn, recording row)")
    timer.wrap(path_learning, "quaternions_from_matrices", "recording (built at the end)")
    approach = path_learning._approach
    started: list[float] = []

    def approach_then_time(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        out = approach(*args, **kwargs)
        timer.active = True
        started.append(time.perf_counter())
        return out

    path_learning._approach = approach_then_time
    try:
        route = plan_route(
            guides, learning, workpiece=c.workpiece.cad(), tool_radius_m=c.tool.radius_m
        )
        rec, end = learn_path(c, state.cell, route, learning, lt.estimator, supervisor=supervisor)
        wall = time.perf_counter() - started[0]
    finally:
        timer.restore()
        path_learning._approach = approach
    overhead = timer.overhead_s()
    n = len(rec)
    total = (wall - overhead * sum(timer.calls.values())) / n * 1e6
    rows = [(p, (timer.seconds[p] - overhead * timer.calls[p]) / n * 1e6) for p in timer.seconds]
    rows.append(("the loop's own Python (stops, legs)", total - sum(v for _, v in rows)))
    print(
        f"one period, by part ({n} periods with timers; {overhead * 1e6:.2f} us per timed call "
        "taken off):"
    )
    for name, value in rows:
        print(f"  {name:44s} {value:6.2f} us  {value / total * 100:5.1f} %")
    print(f"  {'total':44s} {total:6.2f} us")
    # Inside the compiled kernels: the IK step and the recording's row, without a Python call.
    T_end, J_end = c.robot.fk_and_jacobian(end.q_motor)
    T_target = T_end.copy()
    T_target[:3, 3] += 1e-5
    lo, hi = c.robot.lower_rad, c.robot.upper_rad
    ik = in_kernel_us(lambda k: _ik_steps(end.q_motor, T_end, J_end, T_target, lo, hi, k), 20000)
    record = np.zeros((64, path_learning.REC_WIDTH))
    wrench, w = np.ones(6), np.array([0.0, 1.0, 0.0])
    row = in_kernel_us(
        lambda k: _row_writes(end.ft_reading, T_end, end.q_motor, wrench, w, record, k), 20000
    )
    print(f"  inside supervision: the IK step (ik_newton_step)    {ik:6.2f} us")
    print(f"  inside the force loop: the recording's row           {row:6.2f} us")
    print(f"  whole cell step {one_cell:.1f} us; the pinocchio reference {fk:.2f} us")
    bench_outer_wall(1 if args.quick else 3, 1 if args.quick else repeats)


def bench_outer_wall(sets: int, repeats: int) -> None:
    """Path learning at 10 mm/s from seeded sloppy points on the block's outer wall (the side
    given): the spindle over the part's edge keeps the part within its slow zone. Each run is
    paired with a reference run, interleaved: the supervisor's model without the obstacles'
    corners, so every near clearance goes back to Python and coal (as before the kernel's GJK,
    ``supervision._kernels.convex_clearance``)."""
    from robomach_core.cell import CellConfig
    from robomach_core.cell.supervision._kernels import obstacle_corner_counts
    from robomach_core.project import CellSettings, Project, learn

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout's tests/
    from tests.sloppy_guides import sloppy_guides

    factors: dict[str, list[float]] = {"gjk": [], "coal": []}
    for seed in range(1, 1 + sets):
        cell = Cell(CellConfig(workpiece="block", seed=seed))
        sset = sloppy_guides(cell, np.random.default_rng(1000 + seed), side_mode="given")
        project = Project(cell=CellSettings(seed=seed), guide_points=tuple(sset.guides))
        lt = LeadThrough(cell)
        start = lt.start(cell.initial_state()).cell
        settings = PathLearningSettings(speed_m_s=0.010, wall_side=sset.wall_side)
        supervisor = cell_supervisor(cell)
        corner_counts = obstacle_corner_counts(supervisor._model)  # a view into the model
        with_corners = corner_counts.copy()
        learn(project, cell, start, settings, lt.estimator)  # the kernels loaded
        for _ in range(repeats):
            for mode in ("gjk", "coal"):
                corner_counts[:] = with_corners if mode == "gjk" else 0.0
                supervisor._memory[:] = np.nan  # no step remembered from the other mode
                t = time.perf_counter()
                learned, _ = learn(project, cell, start, settings, lt.estimator)
                factors[mode].append(learned.recording.time_s[-1] / (time.perf_counter() - t))
        corner_counts[:] = with_corners
    gjk, coal = (statistics.median(factors[m]) for m in ("gjk", "coal"))
    print(
        f"off the example, the block's outer wall from {sets} sloppy set{'s' * (sets > 1)}: "
        f"real-time factor median x{gjk:.1f} "
        f"(runs: {', '.join(f'x{f:.1f}' for f in factors['gjk'])})"
    )
    print(
        f"  reference, interleaved: every near clearance by coal, median x{coal:.1f}; "
        f"the kernel's GJK is x{gjk / coal:.2f} as fast"
    )


if __name__ == "__main__":
    main()
