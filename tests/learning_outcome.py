"""What became of one taught set, as issue 28's acceptance sorts it, measured independently.

A set runs through the project's own stages (``project.learn`` then ``project.process``, as
the CLI and the workbench run them). Its program (the post-processed targets, straight moves
between them) is then measured against the part's true walls in the part's own frame
(``envelope_parts.TrueWall``): not the product's scores or checks.

Classes:
    learned         completed, every program point within 0.3 mm of the taught wall, the whole
                    taught stretch covered, at each guide point within 5 mm of its taught
                    height or a neighbour's, and no problem (fine)
    refused         ``RouteRefusedError`` (a ``WallSideError`` is one) from ``learn``, before
                    any motion, with a reason (fine)
    stopped         learning ended early (the program is partial and says so)
    off wall, flagged  completed but off the taught wall (or a point's height), and NOT
                    FIT says so
    error           another error from a stage
    wrong passed    FAILURE: off the taught wall (or not covering it) with no problem: a wrong
                    program that passes (another wall, the floor, a slot's closing leg)
    good condemned  FAILURE: on the taught wall within 0.3 mm, whole, completed, yet NOT FIT

The taught wall is the wall on the side the person gave; with "auto", the wall the points
were made on (people_points keeps such points nearer it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from robomach_core.cell import Cell, CellConfig, GuidePoint, LeadThrough
from robomach_core.errors import RobomachError, RouteRefusedError
from robomach_core.learning.run import PathLearningSettings
from robomach_core.postprocess import PostprocessSettings
from robomach_core.project import Project, learn, process
from tests.envelope_parts import EnvelopePart, TrueWall
from tests.people_points import PeopleSet

WITHIN_MM = 0.3  # the acceptance: within 0.3 mm of the taught wall
HEIGHT_BAND_MM = 5.0  # ... at each guide point, within this of its taught height or a
# neighbour's (between points taught at different heights the route passes through theirs):
# the height the learning model documents for its taught-wall check
COVER_MM = 0.6  # a wall vertex is covered when a program point is within r + this (across)
END_MARGIN_MM = 2.0  # an open stretch's ends (a point's foot, the run's start) are not scored
SAMPLE_MM = 0.05  # program points along each move
FINE = ("learned", "refused")
FAILURES = ("wrong passed", "good condemned")


@dataclass(frozen=True)
class Measure:
    """The program against the true walls (mm).

    Attributes:
        dev_mm: Largest |distance - r| of a program point from the taught wall.
        coverage: Fraction of the taught stretch's wall within r + COVER_MM of the program.
        height_mm: Largest height error against the points' heights interpolated along the
            wall (part frame), over the program points on the taught stretch.
        at_points_mm: Largest height error at the guide points themselves: the program's
            height where its foot on the wall is nearest each point's, against the nearest of
            the point's taught height and its neighbours' (a point taught 12 mm above a
            neighbour 0.5 mm away is passed at one of the two).
        nearest: The wall the program runs along (smallest median |distance - r|) and its
            largest deviation.
        worst_at_mm: Part-frame position of the worst point (x, y, z).
    """

    dev_mm: float
    coverage: float
    height_mm: float
    nearest: tuple[str, float]
    worst_at_mm: tuple[float, float, float]
    at_points_mm: float = 0.0


@dataclass(frozen=True)
class Outcome:
    """What became of one set (module docstring)."""

    kind: str
    reason: str = ""
    measure: Measure | None = None
    completed: bool = False
    problems: tuple[str, ...] = ()
    wall_side: str = ""
    samples: int = 0
    settings: str = ""
    description: str = field(default="", compare=False)

    @property
    def fine(self) -> bool:
        return self.kind in FINE

    @property
    def failure(self) -> bool:
        return self.kind in FAILURES

    def line(self) -> str:
        """One line: the class and the figures behind it."""
        out = [self.kind, self.settings]
        if self.measure is not None:
            m = self.measure
            out.append(
                f"{m.dev_mm:.3f} mm from the taught wall (worst at "
                f"{', '.join(f'{v:.1f}' for v in m.worst_at_mm)}), {m.coverage:.1%} covered, "
                f"height within {m.height_mm:.2f} mm ({m.at_points_mm:.2f} mm at the points), "
                f"runs along {m.nearest[0]!r} "
                f"({m.nearest[1]:.3f} mm)"
            )
        if self.wall_side:
            out.append(f"side {self.wall_side}")
        if self.samples:
            out.append(f"{self.samples} samples")
        if self.reason:
            out.append(self.reason)
        if self.problems:
            out.append("NOT FIT: " + " | ".join(self.problems))
        return "; ".join(s for s in out if s)


# --- measuring ----------------------------------------------------------------------------------


def program_points(targets_m: np.ndarray, moves: object = None) -> np.ndarray:
    """(k, 3) points every SAMPLE_MM along straight moves through the targets [m]."""
    if moves is not None:
        raise NotImplementedError("arc moves: measure with straight moves (arcs off)")
    pts = np.asarray(targets_m, dtype=float)
    out = [pts[:1]]
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        n = max(1, int(math.ceil(np.linalg.norm(b - a) * 1e3 / SAMPLE_MM)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.vstack(out)


def measure_program(
    part: EnvelopePart,
    workpiece: object,
    tool_radius_m: float,
    pset: PeopleSet,
    targets_m: np.ndarray,
) -> Measure:
    """The program through ``targets_m`` against the true walls (module docstring)."""
    r_mm = tool_radius_m * 1e3
    p = part.to_part_mm(workpiece, program_points(targets_m))
    wall = part.walls[pset.wall]
    sd, _ = wall.signed_distance(p)
    dev = np.abs(sd - r_mm)
    worst = int(np.argmax(dev))
    stretch = wall.stretch(pset.stretch_mm, END_MARGIN_MM if pset.stretch_mm else 0.0)
    if len(stretch):
        d_cover, _ = cKDTree(p[:, :2]).query(wall.xy_mm[stretch])
        coverage = float(np.mean(d_cover <= r_mm + COVER_MM))
    else:
        coverage = 1.0
    height = _height_error(wall, pset, p, stretch)
    at_points = _height_at_points(wall, pset, p)
    medians = {
        name: float(np.median(np.abs(w.signed_distance(p)[0] - r_mm)))
        for name, w in part.walls.items()
    }
    nearest = min(medians, key=medians.get)
    nearest_dev = float(np.max(np.abs(part.walls[nearest].signed_distance(p)[0] - r_mm)))
    return Measure(
        float(dev[worst]),
        coverage,
        height,
        (nearest, nearest_dev),
        tuple(float(v) for v in p[worst]),
        at_points,
    )


def _height_error(wall: TrueWall, pset: PeopleSet, p: np.ndarray, stretch: np.ndarray) -> float:
    """Largest |z - taught height| over the program points whose foot is on the stretch; the
    taught height interpolated along the wall between the points' feet."""
    if len(pset.s_mm) < 2:
        return float("nan")
    idx = wall.nearest(p[:, :2])
    s_prog = wall.cumulative_mm[idx]
    on = np.isin(idx, stretch)
    if not on.any():
        return float("nan")
    order = np.argsort(pset.s_mm)
    s_k, h_k = pset.s_mm[order], pset.heights_mm[order]
    if wall.closed:
        L = wall.length_mm
        s_k = np.concatenate([s_k - L, s_k, s_k + L])
        h_k = np.tile(h_k, 3)
    h = np.interp(s_prog[on], s_k, h_k)
    return float(np.max(np.abs(p[on, 2] - h)))


def _height_at_points(wall: TrueWall, pset: PeopleSet, p: np.ndarray) -> float:
    """Largest |program height - taught height| at the guide points: at each point's foot on
    the wall, the program points whose foot is nearest along the wall, against the point's
    height and its neighbours' (0: no points)."""
    if not len(pset.s_mm):
        return 0.0
    s_prog = wall.cumulative_mm[wall.nearest(p[:, :2])]
    worst = 0.0
    n = len(pset.s_mm)
    for k, s_k in enumerate(pset.s_mm):
        gap = np.abs(s_prog - s_k)
        if wall.closed:
            gap = np.minimum(gap, wall.length_mm - gap)
        near = gap <= gap.min() + SAMPLE_MM
        around = [j % n for j in (k - 1, k, k + 1) if pset.closed or 0 <= j < n]
        taught = pset.heights_mm[around]
        worst = max(worst, float(np.min(np.abs(p[near, 2][:, None] - taught[None, :]))))
    return worst


def classify(measure: Measure, completed: bool, problems: tuple[str, ...]) -> str:
    """The class of a learned program (module docstring)."""
    if not completed:
        return "stopped" if problems else "wrong passed"
    within = (
        measure.dev_mm <= WITHIN_MM
        and measure.coverage >= 1.0
        and measure.at_points_mm <= HEIGHT_BAND_MM
    )
    if within:
        return "good condemned" if problems else "learned"
    return "off wall, flagged" if problems else "wrong passed"


def planned_or_refused(
    guides: list[GuidePoint], cell: Cell, settings: PathLearningSettings, where: str
) -> object | None:
    """The route for ``guides`` on ``cell``'s part (``route.plan_route``), or None when it is
    refused before any motion, which must say why (``where`` names the set in the message)."""
    from robomach_core.learning.route import plan_route

    try:
        return plan_route(
            guides, settings, workpiece=cell.workpiece, tool_radius_m=cell.tool.radius_m
        )
    except RouteRefusedError as exc:
        assert str(exc).strip(), f"{where}: refused without a reason"
        return None


# --- running a set through the project's stages ---------------------------------------------------


def learn_set(
    part: EnvelopePart,
    cell: Cell,
    pset: PeopleSet,
    *,
    force_N: float = 10.0,
    speed_mm_s: float = 10.0,
    state: object | None = None,
    estimator: object | None = None,
) -> tuple[Outcome, object]:
    """Learn ``pset`` on ``cell`` (from ``state``/``estimator`` after a lead-through, else from
    rest), post-process, measure and classify. Returns the outcome and the processed path
    (None when refused or failed)."""
    settings_note = f"{force_N:g} N, {speed_mm_s:g} mm/s"
    base = Outcome("", settings=settings_note, description=pset.description)
    if len(pset.guides) < 2:
        return replace(base, kind="error", reason="fewer than 2 points reachable"), None
    project = Project(
        cell=part.cell_settings(cell.config.seed, cell.config.robot),
        mesh=part.mesh_file(),
        guide_points=tuple(pset.guides),
    )
    if state is None:
        lt = LeadThrough(cell)
        state, estimator = lt.start(cell.initial_state()).cell, lt.estimator
    settings = PathLearningSettings(
        force_N=force_N,
        speed_m_s=speed_mm_s * 1e-3,
        closed=pset.closed,
        wall_side=pset.wall_side,
    )
    try:
        learned, _ = learn(project, cell, state, settings, estimator)
    except RouteRefusedError as exc:
        kind = "refused" if str(exc).strip() else "error"
        return replace(base, kind=kind, reason=f"refused: {exc}"), None
    except RobomachError as exc:
        return replace(base, kind="error", reason=f"{type(exc).__name__}: {exc}"), None
    rec = learned.recording
    post = PostprocessSettings().for_learning_force(force_N)
    try:
        processed = process(learned, post, cell.workpiece, cell.tool.radius_m, guides=pset.guides)
    except RobomachError as exc:
        outcome = judge(part, cell.workpiece, cell.tool.radius_m, pset, rec, None, base, error=exc)
        return outcome, None
    return judge(part, cell.workpiece, cell.tool.radius_m, pset, rec, processed, base), processed


def judge(
    part: EnvelopePart,
    workpiece: object,
    tool_radius_m: float,
    pset: PeopleSet,
    recording: object,
    processed: object | None,
    base: Outcome | None = None,
    *,
    error: Exception | None = None,
) -> Outcome:
    """The outcome of a learned ``recording`` and its ``processed`` path (None when
    post-processing raised ``error``): measured and classified (module docstring)."""
    rec = recording
    base = replace(
        base or Outcome("", description=pset.description),
        completed=rec.completed,
        wall_side=rec.wall_side,
        samples=len(rec),
    )
    if processed is None:
        kind = "stopped" if not rec.completed else "error"
        return replace(base, kind=kind, reason=f"{rec.stop_reason}; {error}")
    problems = tuple(processed.problems())
    targets = processed.result.targets.position_m
    if len(targets) < 2:
        return replace(base, kind="stopped", reason=rec.stop_reason, problems=problems)
    m = measure_program(part, workpiece, tool_radius_m, pset, targets)
    reason = "" if rec.completed else rec.stop_reason
    kind = classify(m, rec.completed, problems)
    return replace(base, kind=kind, reason=reason, measure=m, problems=problems)


def example_leadthrough(
    part: EnvelopePart, seed: int, *, intents: list | None = None
) -> tuple[PeopleSet, object, object]:
    """The scripted operator (``teaching.operator.scripted_leadthrough``) leads the robot to
    the example's guide points on a built-in part, or to ``intents``; returns the set (taught
    wall "outer"/"outline"/"right side": the built-in's wall), the cell state at the end and
    the tared estimator."""
    from robomach_core.teaching import scripted_leadthrough

    cell = part.cell(seed)
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    state, guides = scripted_leadthrough(
        lt, state, cell.workpiece.cad(), np.random.default_rng(seed), intents=intents
    )
    pset = as_set(
        part, cell.workpiece, cell.tool.radius_m, guides, "the example operator", side="auto"
    )
    return pset, state.cell, lt.estimator


def as_set(
    part: EnvelopePart,
    workpiece: object,
    tool_radius_m: float,
    guides: list[GuidePoint],
    who: str,
    *,
    wall: str | None = None,
    closed: bool = True,
    side: str = "auto",
) -> PeopleSet:
    """A set of guide points recorded by someone else, on ``wall`` (default the part's first),
    measured where they are."""
    name = wall or next(iter(part.walls))
    w = part.walls[name]
    p = part.to_part_mm(workpiece, np.array([g.position_m for g in guides]))
    s = w.project(p[:, :2])
    r_mm = tool_radius_m * 1e3
    floors = np.array([w.at(float(si))[2] for si in s])
    heights = np.maximum(p[:, 2], floors + r_mm + 0.5)
    stretch = None if (closed and w.closed) else (float(s[0]), float(s[-1]))
    gaps = w.signed_distance(p)[0] - r_mm
    lines = [
        f"{part.name} ({part.description}), wall {name!r}, {len(guides)} points by {who}",
        *(
            f"G{k + 1}: s={s[k]:.0f} gap={gaps[k]:.2f} z={p[k, 2] - floors[k]:.1f} above floor "
            f"(top {w.top_mm - floors[k]:.1f}) |F|={np.linalg.norm(g.force_N):.1f} N"
            for k, g in enumerate(guides)
        ),
    ]
    return PeopleSet(
        list(guides), part.name, name, closed, side, "right", s, heights, "\n".join(lines),
        stretch,
    )  # fmt: skip


def within_the_wall(pset: PeopleSet, part: EnvelopePart, workpiece: object, r_mm: float) -> list:
    """The points of ``pset`` that are not beside their wall: below the floor + the cutter,
    above its top, or farther than 3 mm from it (1-based numbers)."""
    w = part.walls[pset.wall]
    p = part.to_part_mm(workpiece, np.array([g.position_m for g in pset.guides]))
    sd, i = w.signed_distance(p)
    off = (p[:, 2] < w.floor_mm[i] + r_mm - 0.1) | (p[:, 2] > w.top_mm) | (sd - r_mm > 3.0)
    return [int(k) + 1 for k in np.flatnonzero(off)]


def proposal_set(
    part: EnvelopePart, seed: int, wall: str, *, s_mm: float | None = None
) -> tuple[PeopleSet, object, object, object]:
    """Point at ``wall`` (``teaching.pointing.propose_guide_points``), let the scripted
    operator lead the robot to the proposed points touching the wall (as ``robomach demo
    --propose-guide-points`` does); returns the set, the end state, the estimator and the
    proposal. The taught side is the proposal's."""
    from robomach_core.cell import cell_supervisor
    from robomach_core.teaching import guide_intents, scripted_leadthrough
    from robomach_core.teaching.pointing import (
        propose_guide_points,
        refuse_unreachable,
        tool_reach,
    )

    cell = part.cell(seed)
    cad = cell.workpiece.cad()
    proposal = propose_guide_points(
        cad,
        cell.robot,
        part.pick_wobj_mm(wall, s_mm) * 1e-3,
        tool_radius_m=cell.tool.radius_m,
        q_seed=cell.robot.home_rad,
        supervisor=cell_supervisor(cell),
        tool_reach_m=tool_reach(cell.tool),
    )
    refuse_unreachable(proposal)
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    state, guides = scripted_leadthrough(
        lt, state, cad, np.random.default_rng(seed), intents=guide_intents(proposal)
    )
    pset = as_set(
        part, cell.workpiece, cell.tool.radius_m, guides, "a proposal", wall=wall,
        closed=proposal.closed, side=proposal.wall_side,
    )  # fmt: skip
    return pset, state.cell, lt.estimator, proposal


def fresh_cell(part: EnvelopePart, seed: int) -> Cell:
    """The same cell again (its sensor noise from the start), to learn one set after another."""
    return Cell(CellConfig(robot="ur10", workpiece=part.workpiece(seed), seed=seed))
