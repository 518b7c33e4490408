"""Post-processing of a path-learning recording (chapter section 3.3).

Force-threshold filtering drops samples whose contact force is outside [Fmin, Fmax] (corner
spikes, lost contact), except where the chord bridging the gap would leave them by more than the
tolerance (``keep_corners``: the tool's arc round a sharp outside corner, out of contact, whose
chord would cut the corner). A closed loop's samples end at their nearest approach to the
first kept one (``closed_at_start``: the run goes on a little past its start). Deviation-height
reduction (the chapter's fig. 3) approximates the contour by straight segments: a chord runs
from a start sample to the current sample; the deviation height of every intermediate sample is
its perpendicular distance from the chord; the current sample moves along the contour until
some deviation height exceeds the tolerance, and then the *previous* sample ends the segment
and starts the next. Per-target speeds are slower where the
local curvature is high (section 3.4: about 10 mm/s on average, slower at sharp corners).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import _kernels
from ..errors import InvalidInputError
from ..limits import (
    CONTACT_STIFFNESS_N_MM,
    CURVATURE_REFERENCE_1_M,
    FORCE_THRESHOLD_N,
    PROGRAM_SPEED_MM_S,
    TOLERANCE_MM,
)
from ..transforms import arc_length_m

# The force filter's band around the learning force (the defaults, 5-15 N, at the chapter's
# 10 N), and the least a band must reach to keep a recording held at that force.
FORCE_BAND = (0.5, 1.5)
FORCE_BAND_MARGIN = (0.8, 1.2)


@dataclass(frozen=True)
class PostprocessSettings:
    """User settings of post-processing (SI units).

    Attributes:
        force_min_N: Samples with a contact force below this are dropped.
        force_max_N: Samples with a contact force above this are dropped.
        tolerance_m: Deviation-height tolerance of the reduction.
        speed_mean_m_s: Average machining feed over the targets.
        speed_min_m_s: Slowest feed, used at the sharpest corners.
        curvature_ref_1_m: Curvature at which the feed is halved.
        contact_stiffness_N_m: Interaction stiffness used to move each sample back to the
            unloaded surface (sample + F / k); 0 disables this compensation.
        arcs: Fit circular moves (MoveC / movec) where the contour is an arc within the arc
            tolerance (``robomach_core.postprocess.arc_targets``) instead of the straight program.
        arc_tolerance_m: Largest distance of a filtered sample from its line or arc; None uses
            ``tolerance_m``.
    """

    force_min_N: float = 5.0
    force_max_N: float = 15.0
    tolerance_m: float = TOLERANCE_MM.default_value() * 1e-3
    speed_mean_m_s: float = 0.010
    speed_min_m_s: float = 0.003
    curvature_ref_1_m: float = 1.0 / 0.010
    contact_stiffness_N_m: float = 100e3
    arcs: bool = False
    arc_tolerance_m: float | None = None

    def holds_force(self, force_N: float) -> bool:
        """True when the filter band keeps a recording held at ``force_N``: the band reaches
        ``FORCE_BAND_MARGIN`` of it on both sides (its noise and the corners' dips)."""
        lo, hi = FORCE_BAND_MARGIN
        return self.force_min_N <= lo * force_N and self.force_max_N >= hi * force_N

    def with_band_for(self, force_N: float) -> PostprocessSettings:
        """These settings with the filter band ``FORCE_BAND`` x ``force_N`` (5-15 N at 10 N)."""
        lo, hi = FORCE_BAND
        return replace(self, force_min_N=lo * force_N, force_max_N=hi * force_N)

    def for_learning_force(self, force_N: float) -> PostprocessSettings:
        """The band rule of every path (workbench, REST and CLI, through
        ``project.with_learned``): these settings when their band holds a recording at
        ``force_N`` (``holds_force``: a band the user chose wins), else the band moved to
        ``FORCE_BAND`` x ``force_N``. At 12 N the default 5-15 N band stays."""
        return self if self.holds_force(force_N) else self.with_band_for(force_N)

    def __post_init__(self) -> None:
        # limits.TOLERANCE_MM: below 0.01 mm the reduction keeps nearly every sample (a 311k
        # sample recording took 6.5-7 GB at 0.001 mm; issue 19, R3).
        TOLERANCE_MM.check(_mm(self.tolerance_m), "deviation-height tolerance [mm]")
        FORCE_THRESHOLD_N.check(self.force_min_N, "force_min_N")
        FORCE_THRESHOLD_N.check(self.force_max_N, "force_max_N")
        PROGRAM_SPEED_MM_S.check(_mm(self.speed_mean_m_s), "mean program speed [mm/s]")
        PROGRAM_SPEED_MM_S.check(_mm(self.speed_min_m_s), "slowest program speed [mm/s]")
        CURVATURE_REFERENCE_1_M.check(self.curvature_ref_1_m, "reference curvature [1/m]")
        CONTACT_STIFFNESS_N_MM.check(
            _per_mm(self.contact_stiffness_N_m), "contact stiffness [N/mm]"
        )
        if not (0 <= self.force_min_N < self.force_max_N):
            raise InvalidInputError(
                f"force thresholds need 0 <= Fmin < Fmax, got Fmin={self.force_min_N:g} N, "
                f"Fmax={self.force_max_N:g} N"
            )
        if not (0 < self.speed_min_m_s <= self.speed_mean_m_s):
            raise InvalidInputError("speeds need 0 < minimum speed <= mean speed")
        if self.contact_stiffness_N_m < 0:
            raise InvalidInputError("contact stiffness must be >= 0 N/mm")
        if self.arc_tolerance_m is not None:
            TOLERANCE_MM.check(_mm(self.arc_tolerance_m), "arc tolerance [mm]")


def _mm(value_m: object) -> object:
    """A length in metres as millimetres for a range check (non-numbers pass through)."""
    if isinstance(value_m, bool) or not isinstance(value_m, (int, float, np.floating)):
        return value_m
    return value_m * 1e3


def _per_mm(value_per_m: object) -> object:
    """A stiffness in N/m as N/mm for a range check (non-numbers pass through)."""
    if isinstance(value_per_m, bool) or not isinstance(value_per_m, (int, float, np.floating)):
        return value_per_m
    return value_per_m * 1e-3


def force_threshold_mask(force_N: np.ndarray, force_min_N: float, force_max_N: float) -> np.ndarray:
    """Boolean mask of the samples whose contact force lies in [force_min_N, force_max_N]."""
    f = np.asarray(force_N, dtype=float)
    return (f >= force_min_N) & (f <= force_max_N)


def keep_corners(points: np.ndarray, mask: np.ndarray, tolerance: float) -> np.ndarray:
    """``mask`` with the dropped samples of a gap kept again where the chord bridging it would
    leave them by more than ``tolerance``: round a sharp outside corner the tool rolls out of
    contact (the force filter drops it), and the chord between the samples either side would
    cut the corner (0.4 mm deep round a 90 deg corner with a 1 mm ball). Leading and trailing
    samples (before the first contact, after the last) stay dropped. Shape (n,) bool."""
    out = np.asarray(mask, dtype=bool).copy()
    kept = np.flatnonzero(out)
    for i, j in zip(kept[:-1], kept[1:], strict=True):
        if j - i < 2:
            continue
        a, b = points[i], points[j]
        d = b - a
        length = float(np.linalg.norm(d))
        rel = points[i + 1 : j] - a
        if length > 1e-12:
            u = d / length
            rel = rel - np.outer(np.clip(rel @ u, 0.0, length), u)
        if float(np.max(np.linalg.norm(rel, axis=1))) > tolerance:
            out[i + 1 : j] = True
    return out


def deviation_heights(points: np.ndarray, start: int, end: int) -> np.ndarray:
    """Perpendicular distances of points[start+1:end] from the chord points[start]->points[end]."""
    a = points[start]
    chord = points[end] - a
    length = np.linalg.norm(chord)
    rel = points[start + 1 : end] - a
    if length < 1e-15:
        return np.linalg.norm(rel, axis=1)
    u = chord / length
    along = rel @ u
    return np.linalg.norm(rel - along[:, None] * u, axis=1)


def reduce_deviation_height(points: np.ndarray, tolerance: float) -> np.ndarray:
    """Indices of the samples kept by the deviation-height method (chapter fig. 3).

    A chord runs from the segment's start to the current sample; the current sample moves along
    until some intermediate sample's deviation height (``deviation_heights``) exceeds
    ``tolerance``; the previous sample then ends the segment and starts the next. The compiled
    kernel ``_kernels.deviation_height_kept`` makes the same decisions as the literal scan
    ``reduce_deviation_height_reference`` at near-linear cost.

    Args:
        points: Shape (n, d) samples in order along the contour (any consistent unit).
        tolerance: Largest allowed deviation height, same unit as ``points``.

    Returns:
        Increasing indices into ``points``; always includes the first and the last sample.
        Every dropped sample lies within ``tolerance`` of the chord of its segment, and each
        segment is the longest from its start that does (one more sample would exceed it).
    """
    pts = _as_points(points, tolerance)
    if len(pts) <= 2:
        return np.arange(len(pts), dtype=np.int64)
    if pts.shape[1] > 3:
        return reduce_deviation_height_reference(pts, tolerance)
    if pts.shape[1] < 3:  # zeros in the missing axes change no distance
        pts = np.pad(pts, ((0, 0), (0, 3 - pts.shape[1])))
    return _kernels.deviation_height_kept(np.ascontiguousarray(pts), float(tolerance))


def reduce_deviation_height_reference(points: np.ndarray, tolerance: float) -> np.ndarray:
    """The literal scan of fig. 3, for any dimension: ``reduce_deviation_height``'s oracle.

    Every end after a start is tried in turn with ``deviation_heights``, so a segment of L
    samples costs O(L^2); use ``reduce_deviation_height`` on real recordings.
    """
    pts = _as_points(points, tolerance)
    n = len(pts)
    kept = [0] if n else []
    start = 0
    while start < n - 1:
        end = next(
            (e for e in range(start + 2, n) if deviation_heights(pts, start, e).max() > tolerance),
            None,
        )
        if end is None:
            break
        start = end - 1  # the chord start->end fails; end-1 is the last good chord end
        kept.append(start)
    if n and kept[-1] != n - 1:
        kept.append(n - 1)
    return np.asarray(kept, dtype=np.int64)


def _as_points(points: np.ndarray, tolerance: float) -> np.ndarray:
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2:
        raise InvalidInputError(f"points must have shape (n, d), got {pts.shape}")
    if not (tolerance > 0 and np.isfinite(tolerance)):
        raise InvalidInputError(f"tolerance must be positive and finite, got {tolerance}")
    if not np.isfinite(pts).all():
        raise InvalidInputError("points must be finite")
    return pts


def curvature_along(
    points: np.ndarray, *, window_m: float = 0.002, at: np.ndarray | None = None
) -> np.ndarray:
    """Unsigned curvature [1/m] from the circle through neighbours ~window apart.

    Args:
        points: (n, 3) samples in order along the path [m].
        window_m: Arc length to the neighbours on each side.
        at: Indices to evaluate at (default: every point); the arc length still runs over all.

    Returns:
        (len(at),) or (n,) curvatures: 2 |AB x AC| / (|AB| |BC| |CA|) for the neighbours A, C.
    """
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    where = np.arange(n) if at is None else np.asarray(at, dtype=np.int64)
    if n < 3:
        return np.zeros(len(where))
    steps = np.diff(pts, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.sqrt(np.einsum("ij,ij->i", steps, steps)))])
    s_at = s[where]
    prev_idx = np.clip(np.searchsorted(s, s_at - window_m), 0, n - 1)
    next_idx = np.clip(np.searchsorted(s, s_at + window_m), 0, n - 1)
    a, b, c = pts[prev_idx], pts[where], pts[next_idx]
    ab = np.linalg.norm(b - a, axis=1)
    bc = np.linalg.norm(c - b, axis=1)
    ca = np.linalg.norm(a - c, axis=1)
    cross = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    denom = ab * bc * ca
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(denom > 1e-18, 2.0 * cross / denom, 0.0)
    return k


def speeds_by_curvature(
    curvature_1_m: np.ndarray,
    *,
    speed_mean_m_s: float,
    speed_min_m_s: float,
    curvature_ref_1_m: float,
) -> np.ndarray:
    """Per-target feed, slower at sharp corners, scaled so the mean equals ``speed_mean_m_s``.

    v_i = v_top / (1 + kappa_i / kappa_ref), clipped to [speed_min, v_top]; v_top is found by
    bisection so that mean(v) = speed_mean (as in section 3.4: ~10 mm/s average).
    """
    k = np.asarray(curvature_1_m, dtype=float)
    if len(k) == 0:
        return k
    shape = 1.0 / (1.0 + k / curvature_ref_1_m)
    lo, hi = speed_mean_m_s, speed_mean_m_s * 20
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if np.mean(np.clip(mid * shape, speed_min_m_s, mid)) < speed_mean_m_s:
            lo = mid
        else:
            hi = mid
    return np.clip(hi * shape, speed_min_m_s, hi)


def surface_positions(
    position_m: np.ndarray,
    force_tool_N: np.ndarray,
    quaternion_wxyz: np.ndarray,
    contact_stiffness_N_m: float,
) -> np.ndarray:
    """Samples moved back to where the unloaded surface is: p + F_planar / k.

    During learning the cutter presses into the wall by F / k (the interaction stiffness the
    papers measured), so the recorded TCP sits that far inside the surface. The measured contact
    force, without its component along the tool axis, points from the wall to the tool; adding
    F / k moves each sample out of the wall. k = 0 leaves the samples as recorded.
    """
    from ..transforms import matrices_from_quaternions

    p = np.asarray(position_m, dtype=float)
    if contact_stiffness_N_m <= 0:
        return p.copy()
    f_planar = np.asarray(force_tool_N, dtype=float)[:, :3].copy()
    f_planar[:, 2] = 0.0
    Rs = matrices_from_quaternions(quaternion_wxyz)
    return p + np.einsum("nij,nj->ni", Rs, f_planar) / contact_stiffness_N_m


@dataclass(frozen=True)
class Targets:
    """The reduced program: one row per target (SI units, base frame).

    Attributes:
        position_m: (m, 3) target positions.
        quaternion_wxyz: (m, 4) target orientations (from the guide points).
        joints_rad: (m, 6) joints recorded at the target's sample.
        speed_m_s: (m,) feed for the move to each target.
        curvature_1_m: (m,) local curvature of the learned path at each target.
        sample_index: (m,) index of the target's sample in the recording.
    """

    position_m: np.ndarray
    quaternion_wxyz: np.ndarray
    joints_rad: np.ndarray
    speed_m_s: np.ndarray
    curvature_1_m: np.ndarray
    sample_index: np.ndarray

    def __len__(self) -> int:
        return len(self.position_m)


@dataclass(frozen=True)
class PostprocessResult:
    """Filtered samples and the reduced targets.

    Attributes:
        keep_mask: (n,) samples that passed the force-threshold filter.
        surface_m: (n, 3) sample positions moved to the unloaded surface (all samples).
        targets: The reduced program.
    """

    keep_mask: np.ndarray
    surface_m: np.ndarray
    targets: Targets

    @property
    def samples_filtered(self) -> int:
        return int(self.keep_mask.sum())


def loop_ridge_m(
    position_m: np.ndarray, tool_radius_m: float, axis: np.ndarray | None = None
) -> float:
    """The ridge a closed program leaves where its end stops short of its start [m]: 0 when
    the end reaches or passes the start (along the first move), else the scallop between two
    cutter positions a gap g apart, r - sqrt(r^2 - (g/2)^2), and the whole radius when the
    cutters do not overlap. (A loop that closed before the force filter's first sample left
    3 mm of a wall uncut, and no check said so.) With the tool ``axis``, the gap and the first
    move are measured across it: the wall runs along the axis, and a loop that ends where it
    began on the wall but 1.6 mm lower (points taught at different heights at its start) was
    NOT FIT for a 0.37 mm ridge it does not leave."""
    p = np.asarray(position_m, dtype=float)
    if len(p) < 3:
        return 0.0
    if axis is not None:
        a = np.asarray(axis, dtype=float) / float(np.linalg.norm(axis))
        p = p - np.outer(p @ a, a)
    first = p[1] - p[0]
    n = float(np.linalg.norm(first))
    gap = p[-1] - p[0]
    if n == 0.0 or float(gap @ first) / n >= 0.0:
        return 0.0
    half = 0.5 * float(np.linalg.norm(gap))
    r = tool_radius_m
    return r if half >= r else r - float(np.sqrt(r * r - half * half))


def closed_at_start(points: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``mask`` without a closed loop's samples past its nearest approach to its first kept
    sample, looked for over the loop's second half by length: the run goes on past its start
    before it knows it has passed it (``learning.walk.LegEnd``), and the program ends where it
    began instead of cutting that stretch of wall twice. (Elsewhere on a loop a tool passes no
    nearer its start than across a wall, two radii.)"""
    kept = np.nonzero(mask)[0]
    if len(kept) < 3:
        return mask
    p = points[kept]
    along = arc_length_m(p)
    second = np.flatnonzero(along > 0.5 * along[-1])
    if not len(second):
        return mask
    d = np.linalg.norm(p[second] - p[0], axis=1)
    last = int(second[np.argmin(d)])
    out = mask.copy()
    out[kept[last + 1 :]] = False
    return out


def postprocess(
    recording,
    guide_quaternions_wxyz: np.ndarray,
    settings: PostprocessSettings,
    *,
    closed: bool = True,
) -> PostprocessResult:
    """Filter, compensate, reduce and give speeds and orientations (chapter section 3.3).

    Args:
        recording: A ``path_learning.Recording``.
        guide_quaternions_wxyz: (g, 4) orientations of the guide points, in order (the run
            interpolated its orientation from them; each target keeps the run's at its sample).
        settings: Thresholds, tolerance and speeds.
        closed: Whether the program's last segment returns to the first guide point.
    """
    rec = recording
    mask = force_threshold_mask(rec.force_normal_N, settings.force_min_N, settings.force_max_N)
    if mask.sum() < 2:
        raise InvalidInputError(
            f"only {int(mask.sum())} samples have a contact force in "
            f"[{settings.force_min_N:g}, {settings.force_max_N:g}] N; widen the thresholds"
        )
    surface = surface_positions(
        rec.position_m, rec.wrench_tool, rec.quaternion_wxyz, settings.contact_stiffness_N_m
    )
    mask = keep_corners(surface, mask, settings.tolerance_m)
    if closed:
        mask = closed_at_start(surface, mask)
    kept = np.nonzero(mask)[0]
    pts = surface[kept]
    local = reduce_deviation_height(pts, settings.tolerance_m)
    idx = kept[local]
    curvature = curvature_along(pts, at=local)
    speeds = speeds_by_curvature(
        curvature,
        speed_mean_m_s=settings.speed_mean_m_s,
        speed_min_m_s=settings.speed_min_m_s,
        curvature_ref_1_m=settings.curvature_ref_1_m,
    )
    # Orientation: the one the run held at the target's sample, which is the guide points'
    # interpolated along the route (the chapter: their orientation "will be kept in the final
    # program"), turned no faster than the arm could; the joints recorded there reach it.
    quats = np.asarray(rec.quaternion_wxyz, dtype=float)[idx].copy()
    targets = Targets(
        position_m=surface[idx],
        quaternion_wxyz=quats,
        joints_rad=rec.joints_rad[idx],
        speed_m_s=speeds,
        curvature_1_m=curvature,
        sample_index=idx,
    )
    return PostprocessResult(mask, surface, targets)
