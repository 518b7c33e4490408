"""Offline deflection compensation planned from the cut the program will meet (chapter sec. 5.4).

PROBLEM   Offline compensation moves each target against the deflection the process force will
          cause there, x_c = x - C F (chapter eq. 32, ``stiffness.compensate_targets_and_joints``).
          Planning it for the reference force Fr (what a CMRR controller aims at) falls short
          wherever the cut never reaches Fr: the feed is limited by the programmed speed on a
          thin allowance, the controller is still catching a burr, or the tool is entering the
          stock; there the planned correction overcuts, and the error cut by compensation
          stays at 57-74 % instead of >= 75 %.
STRATEGY  Rehearse the cut, and plan each station's correction from the force the rehearsals
          met there. The first plan is the force of the cut a working compensation meets: the
          tool held on the nominal wall, the full allowance cut by the same controller (one cut
          with the deflection left out). Each rehearsal cuts the program corrected by the plan;
          the force it met at a station is the least force over the stretch that station's
          correction governs (the loop holds a station's offset from s_i to s_i + ds, and the
          wall there is the tool's lowest reach: a correction for the least force never
          overcuts, and a sub-station transient above it leaves a strip the ball shaves). The
          next plan is the midrange, (least + most) / 2, of the forces every rehearsal so far
          met at each station.
          Why not the finished wall's error (ILC on the wall, as before): a staged controller
          (fuzzy, two-stage) drops its force by half within a sample at a stage switch, and a
          switch lands where the noise and sub-micrometre depth changes put it, a sample to a
          millimetre from one rehearsal to the next. Where it landed before the planned step,
          the wall has a groove C dF deep that the ball widens to ~0.6 mm; the wall's error there
          moved the plan of every station under the groove, not only the one that met the low
          force, and the plan chased the switches (two-stage 59-95 % over 24 stocks, four of
          six rehearsals left a groove). The force met is local to its station.
          Why the midrange of every rehearsal: each rehearsal cuts a noise draw of its own (NOISE),
          so together they sample where the cell's draw may put a switch; where they all agree
          the midrange is their force, where a switch came and went it is halfway, so the
          wall is off by at most half a stage step whichever way the cell's draw falls. The
          mean of the last two rehearsals (before) hedged only the two switch patterns it had
          seen, and the best rehearsal's plan (kept before) was the one whose own draw happened
          to agree with it. Same 300 fresh stocks (100 each on the UR10, IRB 4400 and KR 270
          demos, the papers' switching rules; issue 29): two-stage median 60-62 % -> 67-72 %,
          stocks under 75 % 282 -> 212; fuzzy median 77-81 % -> 80-82 %, under 75 % 91 -> 36
          of 297; per stock the unstaged controllers move by -0.24 to +0.38 points on the mean.
          Repeat until the plan moves no target by more than ``SETTLE_M`` or a rehearsal
          leaves the wall within ``WALL_TOLERANCE_FRACTION`` of the largest planned correction
          (that rehearsal's plan is the program: its cut was good, and the range of one more
          draw would only move it; at most ``MAX_REHEARSALS``). Rehearsals cut the nominal
          program's plan with the planned offsets; the corrected program is built from the
          last plan and cut. The identified stiffness turns the force into the correction;
          the rehearsals only predict the force (they never learn the arm's true compliance).
SOLUTION  ``offline_compensated_run`` returns the corrected program's cut: its program is the
          one the export carries, and its trace and finished wall are what that program does,
          so the table shows what the exported program will cut.

NOISE     Each rehearsal cuts on a sensor-noise draw of its own, never the settings' seed:
          rehearsal k (0 the nominal wall's cut, 1, 2, ... the plans') runs
          ``run.rehearsal_seed`` = SeedSequence([seed, k]), deterministic for a seed. The
          corrected program's cut, the table's row, runs the settings' seed: the cell's draw,
          which no rehearsal saw, and nothing is chosen on it. Why: rehearsals on the
          program's own draw meet its noise sample by sample,
          so the plan settled on the stage switches that very sequence puts, and the staged
          controllers' rows showed a cut no cell meets (UR10 pump demo, seed 0: fuzzy and
          two-stage 0.005 mm, 95-96 % cut; on draws of their own 0.015 mm, 87 %, and
          0.043 mm, 60 %).
STAGES    Under a staged controller (fuzzy, two-stage) with ``MachiningSettings.stages``
          "planned", the stages are planned too, before the correction (``schedule``, issue
          29): ``schedule.SCHEDULE_DRAWS`` cuts of the nominal wall (rehearsal numbers 0, 1,
          ...: draws of their own) fix the lowest stage any of them ran at each station, the
          program carries that schedule as its speeds (a target where the stage changes), and
          every later rehearsal and the corrected program's cut run those speeds with no
          online switching (``run.FeedSource`` "program"). The cut is then deterministic, as
          the constant feed's: the plan above meets the force it was made for. Where every
          draw stops (the controller's protection rule on the nominal wall), there is no
          schedule and the stages switch online. With "online" (the default) the stages
          switch in the cell's cut, by its force.
LIMIT     With the stages switched online, a staged controller's stage switch lands where the
          noise puts it, a sample to a millimetre from one draw to the next, and where some
          rehearsals switched and others did not the midrange leaves half a stage step
          (two-stage on a UR10 stock: ~110 N to ~40 N), ~30 % of the uncompensated error: over
          100 fresh stocks on each of the UR10, IRB 4400 and KR 270 demos fuzzy median
          80-82 %, 57.6 % at worst, two-stage median 67-72 %, 42.9 % at worst (README pump:
          83 % and 61 %). With the stages planned, over 20 fresh stocks on each
          (``benchmarks/bench_offline_stocks.py --stages planned``, seeds from 2026120500):
          fuzzy median 92.6-96.8 %, 91.8 % at worst; two-stage median 91.9-97.7 %, 91.3 % at
          worst; none under 75 % (switching online on the same stocks: fuzzy 69.8 % at worst,
          6 of 60 under 75 %; two-stage 44.5 % at worst, 40 of 60); the cycle 0.2-0.3 %
          longer in the median (at most 2.6 %). What planning costs: the schedule is planned
          for the stock it was cut on. A casting with burrs elsewhere meets them at the
          planned speeds with no feed control (the pump's program over 16 drawn stocks: peak
          p95 272 N against the online fuzzy's 145 N; the cell's overload trip at twice the
          limit; a sweep over castings, ``--variations``, shows it and its rule passes them
          over), so "online" stays the default and the person asks for planned stages. A
          guard that drops to the lowest stage while the force is over the limit was measured
          and not built: the feed and the force lag, and the peaks stayed at 216-233 N
          (``schedule`` LIMIT).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ..cell import Robot
from ..postprocess import Targets
from ..transforms import (
    arc_length_m,
    make_transform,
    matrices_from_quaternions,
    quaternions_from_matrices,
)

if TYPE_CHECKING:
    from .run import MachiningRun, Rehearsal

# Rehearsals stop when the planned shift moves by no more than this between two of them [m].
SETTLE_M = 1.0e-6
# Eight: six left a staged controller's plan unsettled on some stocks (two-stage 82 % at worst
# over ten UR10 stocks, 88 % with eight).
MAX_REHEARSALS = 8
# Rehearsals also stop when one leaves the wall within this fraction of the largest deflection
# the first plan corrects (95 % of it removed, the chapter asks 75 %): further rehearsals only
# redraw the stage switches.
WALL_TOLERANCE_FRACTION = 0.05
# The corrected program's targets: where the planned shift departs from a straight line
# between two targets by more than this, and at most this far apart [m].
PLACEMENT_TOLERANCE_M = 1.0e-6
MAX_SPACING_M = 5.0e-3


def densify_targets(targets: Targets, spacing_m: float) -> Targets:
    """Targets every ~``spacing_m`` along the MoveL path, positions and joints linear between
    the program's targets, orientation and speed of the move's end target."""
    s = arc_length_m(targets.position_m)
    return targets_at(targets, np.union1d(np.arange(0.0, s[-1], spacing_m), s))


def targets_at(targets: Targets, grid_m: np.ndarray) -> Targets:
    """Targets at arc lengths ``grid_m`` (increasing, within the path) of the MoveL path."""
    s = arc_length_m(targets.position_m)
    grid = np.asarray(grid_m, dtype=float)
    seg = np.clip(np.searchsorted(s, grid, side="left"), 1, len(s) - 1)
    pos = np.stack([np.interp(grid, s, targets.position_m[:, i]) for i in range(3)], axis=1)
    joints = np.stack([np.interp(grid, s, targets.joints_rad[:, i]) for i in range(6)], axis=1)
    return Targets(
        position_m=pos,
        quaternion_wxyz=np.asarray(targets.quaternion_wxyz)[seg],
        joints_rad=joints,
        speed_m_s=np.asarray(targets.speed_m_s)[seg],
        curvature_1_m=np.asarray(targets.curvature_1_m)[seg],
        sample_index=np.asarray(targets.sample_index)[seg],
    )


def correction_stations(
    s_m: np.ndarray, shift_m: np.ndarray, fixed_m: np.ndarray, *, tolerance_m: float,
    max_spacing_m: float,
) -> np.ndarray:  # fmt: skip
    """Where the corrected program needs targets: the ``fixed_m`` arc lengths (the nominal
    targets, exactly: the corrected program keeps their corners and their moves' speeds), at
    most ``max_spacing_m`` apart, and wherever the planned shift between two
    targets departs from a straight line by more than ``tolerance_m`` (the deviation-height
    reduction of chapter fig. 3, applied to the correction: a burr's force transient gets
    targets every few tenths of a millimetre, a steady cut one every few millimetres)."""
    from ._kernel import split_by_deviation

    keep = np.zeros(len(s_m), dtype=bool)
    keep[np.searchsorted(s_m, np.clip(fixed_m, s_m[0], s_m[-1]))] = True
    keep[[0, -1]] = True
    grid = np.arange(0.0, s_m[-1], max_spacing_m)
    keep[np.searchsorted(s_m, grid)] = True
    split_by_deviation(
        np.ascontiguousarray(s_m, dtype=float), np.ascontiguousarray(shift_m, dtype=float),
        keep, float(tolerance_m),
    )  # fmt: skip
    fixed = np.asarray(fixed_m, dtype=float)
    fixed = fixed[(fixed >= s_m[0]) & (fixed <= s_m[-1])]
    grid = np.union1d(s_m[keep], fixed)
    # A station within a nanometre of a nominal target stands for it.
    return grid[np.concatenate([[True], np.diff(grid) > 1e-9])]


def split_by_deviation_reference(
    s_m: np.ndarray, shift_m: np.ndarray, keep: np.ndarray, tolerance_m: float
) -> None:
    """``_kernel.split_by_deviation`` in numpy (its reference, tests compare them): between
    each two kept stations, keep the one the shift departs most from the straight line by,
    when that is more than ``tolerance_m``, and split there, until no interval needs one."""
    stack = list(zip(np.flatnonzero(keep)[:-1], np.flatnonzero(keep)[1:], strict=True))
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        t = (s_m[i + 1 : j] - s_m[i]) / (s_m[j] - s_m[i])
        line = shift_m[i] + t * (shift_m[j] - shift_m[i])
        dev = np.abs(shift_m[i + 1 : j] - line)
        k = int(np.argmax(dev))
        if dev[k] > tolerance_m:
            mid = i + 1 + k
            keep[mid] = True
            stack += [(i, mid), (mid, j)]


def program_poses(targets: Targets) -> np.ndarray:
    """(m, 4, 4) poses of the targets."""
    Rs = matrices_from_quaternions(np.asarray(targets.quaternion_wxyz, dtype=float))
    return np.array([make_transform(R, p) for R, p in zip(Rs, targets.position_m, strict=True)])


def corrected_program(
    robot: Robot,
    dense: Targets,
    directions_m: np.ndarray,
    force_N: np.ndarray,
    model,
) -> Targets:
    """The dense program with each target moved against the deflection the force ``force_N``
    (along ``directions_m``, u = (n - rho t) / |n - rho t|) causes under the identified
    stiffness ``model``: chapter eq. (32), linear, as ``stiffness.compensate_targets_and_joints``
    does it, with the joints moved by -theta (first order: the robot's IK of the corrected pose
    differs by O(theta^2), nano-radians here), so it needs no IK per target."""
    from scipy.spatial.transform import Rotation

    u = np.asarray(directions_m, dtype=float)
    force = np.asarray(force_N, dtype=float)
    c = np.asarray(model.compliance_rad_Nm, dtype=float)
    q0 = np.asarray(dense.joints_rad, dtype=float)
    Js = np.empty((len(dense), 6, 6))
    for i in range(len(dense)):
        Js[i] = robot.fk_and_jacobian(q0[i])[1]
    # theta = Kq^-1 J^T [F u; 0], the twist J theta (the arm's deflection), applied negated:
    # p - dp, R' = exp(-dw) R (``stiffness.model.apply_twist``).
    theta = c * np.einsum("kji,kj->ki", Js[:, :3, :], force[:, None] * u)
    twist = np.einsum("kij,kj->ki", Js, theta)
    R = matrices_from_quaternions(np.asarray(dense.quaternion_wxyz, dtype=float))
    R_c = Rotation.from_rotvec(-twist[:, 3:]).as_matrix() @ R
    return replace(
        dense,
        position_m=np.asarray(dense.position_m, dtype=float) - twist[:, :3],
        quaternion_wxyz=quaternions_from_matrices(R_c),
        joints_rad=q0 - theta,
    )


def _program_cut(cut, robot: Robot, nominal: Targets, plan, s_f, directions_m, force, model):
    """(the cut of the program corrected for ``force`` at the stations ``s_f``, its nominal)."""
    grid, _ = plan(force)
    dense = targets_at(nominal, grid)
    u = np.stack([np.interp(grid, s_f, directions_m[:, i]) for i in range(3)], axis=1)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    program = corrected_program(robot, dense, u, np.interp(grid, s_f, force), model)
    return cut(program, dense), dense


def force_met_N(run, s_m: np.ndarray) -> np.ndarray:
    """The least process force a run met over each station's stretch [s_i, s_i + ds) [N]
    (``s_m`` the stations, every ds from 0: the loop holds station i's offset over that
    stretch); a station no sample fell in takes its neighbours' (interpolated), and stations
    beyond where a stopped run ended meet none (zero)."""
    from ._kernel import lowest_reach

    s = np.asarray(s_m, dtype=float)
    tr = run.trace
    if len(tr.path_m) < 2 or len(s) < 2:
        return np.zeros(len(s))
    ds = float(s[1] - s[0])
    station = np.clip(np.floor(tr.path_m / ds).astype(np.int64), 0, len(s) - 1)
    least = lowest_reach(station, np.ascontiguousarray(tr.force_N, dtype=float), len(s))
    met = np.isfinite(least)
    out = np.interp(s, s[met], least[met])
    out[s > float(tr.path_m[-1])] = 0.0
    return out


def offline_compensated_run(
    rehearse: Callable[[np.ndarray, int], Rehearsal],
    cut: Callable[[Targets, Targets], MachiningRun],
    robot: Robot,
    nominal: Targets,
    stations_m: np.ndarray,
    run_stations_m: np.ndarray,
    normal_compliance_m_N: np.ndarray,
    normals_m: np.ndarray,
    directions_m: np.ndarray,
    first_force_N: np.ndarray,
    *,
    model,
    progress: Callable[[float], None] | None = None,
):
    """Rehearse until the corrected targets settle (module docstring), then cut the corrected
    program of the last plan.

    Args:
        rehearse: Cuts the nominal program moved off the stock's path by the given offsets at
            ``run_stations_m`` (the planned correction's normal part, -n^T C_hat u F, between
            the corrected targets) as rehearsal number 1, 2, ... (the second argument: each
            on a noise draw of its own, ``run.rehearsal_seed``), returns the ``Rehearsal``.
        cut: Cuts a corrected program paired with its nominal targets (``cut_program``) on
            the settings' noise draw, the one no rehearsal met.
        nominal: The nominal program; ``stations_m`` (k,) a fine grid of arc lengths along it,
            ``normal_compliance_m_N`` (k,) n^T C_hat u there (``compliance``), ``normals_m``
            and ``directions_m`` (k, 3) the wall normals n and the force's directions u there.
        first_force_N: (k,) the force of the first plan at the stations.

    Returns:
        (the corrected program's run, the corrected program, its nominal targets, number of
        rehearsals, the last change of the planned shift [m]).
    """
    s_n = arc_length_m(nominal.position_m)
    s_f = np.asarray(stations_m, dtype=float)
    s_run = np.asarray(run_stations_m, dtype=float)

    def plan(force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The corrected targets' arc lengths and the shift there."""
        shift = normal_compliance_m_N * force
        grid = correction_stations(
            s_f, shift, s_n, tolerance_m=PLACEMENT_TOLERANCE_M, max_spacing_m=MAX_SPACING_M
        )
        return grid, np.interp(grid, s_f, shift)

    force = np.asarray(first_force_N, dtype=float)
    last_completed = force
    change = np.inf
    least = most = None
    good_m = WALL_TOLERANCE_FRACTION * float(np.max(normal_compliance_m_N * force, initial=0.0))
    for k in range(MAX_REHEARSALS):
        grid, shift = plan(force)
        run = rehearse(-np.interp(s_run, grid, shift), k + 1)
        if progress is not None:
            progress(min((k + 1) / (MAX_REHEARSALS + 1), 1.0))
        if not run.summary["completed"]:
            # A stopped cut (a controller's protection rule, the force supervision) cannot
            # plan the rest of the path, and the plan that stopped it would stop it again: the
            # next plan is the force the last completed cut met, and the range starts again.
            if least is None:
                break  # no rehearsal completed yet: the first plan's own cut stops
            force, least, most = last_completed, None, None
            continue
        if run.summary["wall_error_max_mm"] * 1e-3 <= good_m:
            break  # this plan's cut is good: it is the program
        met = force_met_N(run, s_f)
        last_completed = met
        least = met if least is None else np.minimum(least, met)
        most = met if most is None else np.maximum(most, met)
        following = 0.5 * (least + most)
        change = float(np.max(np.abs(normal_compliance_m_N * (following - force))))
        force = following
        if change <= SETTLE_M:
            break
    # The corrected program is the last plan (the range's midrange, or the plan whose
    # rehearsal left a good wall), cut on the settings' noise draw, which no rehearsal met:
    # its cut is the table's row and nothing is chosen on it (a choice made on that draw
    # would know where its noise puts the stage switches).
    final = _program_cut(cut, robot, nominal, plan, s_f, directions_m, force, model)
    run, dense = final
    if progress is not None:
        progress(1.0)
    return run, run.program, dense, k + 1, change
