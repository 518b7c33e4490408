"""Planar contours made of straight lines and circular arcs, with exact offsets and distances.

The built-in workpieces are generated from such contours, so every learned path can be scored
against the true geometry: the offset of a line is a line, the offset of an arc is an arc, and
the distance to either has a closed form.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import InvalidInputError

DISTANCE_RUN = 256  # points measured together by Contour.distance


@dataclass(frozen=True)
class Line:
    """Segment from ``start`` to ``end`` (2-D, metres)."""

    start: tuple[float, float]
    end: tuple[float, float]

    @property
    def length(self) -> float:
        return float(np.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1]))

    def point_at(self, s: np.ndarray) -> np.ndarray:
        a, b = np.asarray(self.start), np.asarray(self.end)
        return a + (b - a) * (np.asarray(s)[:, None] / self.length)

    def offset(self, distance: float) -> Line:
        a, b = np.asarray(self.start), np.asarray(self.end)
        t = (b - a) / self.length
        n = np.array([-t[1], t[0]]) * distance
        return Line(tuple(a + n), tuple(b + n))

    def distance(self, p: np.ndarray) -> np.ndarray:
        a, b = np.asarray(self.start), np.asarray(self.end)
        ab = b - a
        u = np.clip(((p - a) @ ab) / (ab @ ab), 0.0, 1.0)
        return np.linalg.norm(p - (a + u[:, None] * ab), axis=1)


@dataclass(frozen=True)
class Arc:
    """Circular arc: centre, radius, start angle and signed sweep (CCW positive), radians."""

    center: tuple[float, float]
    radius: float
    start_angle: float
    sweep: float

    @property
    def length(self) -> float:
        return abs(self.sweep) * self.radius

    def point_at(self, s: np.ndarray) -> np.ndarray:
        ang = self.start_angle + np.sign(self.sweep) * np.asarray(s) / self.radius
        return np.asarray(self.center) + self.radius * np.stack([np.cos(ang), np.sin(ang)], 1)

    def offset(self, distance: float) -> Arc:
        # Left of travel: towards the centre for a CCW arc, away for a CW one.
        r = self.radius - distance if self.sweep > 0 else self.radius + distance
        if r <= 0:
            raise InvalidInputError(
                f"offset {distance * 1e3:g} mm exceeds an arc radius of {self.radius * 1e3:g} mm"
            )
        return Arc(self.center, r, self.start_angle, self.sweep)

    def distance(self, p: np.ndarray) -> np.ndarray:
        c = np.asarray(self.center)
        rel = p - c
        ang = np.arctan2(rel[:, 1], rel[:, 0])
        lo = self.start_angle if self.sweep > 0 else self.start_angle + self.sweep
        within = np.mod(ang - lo, 2 * np.pi) <= abs(self.sweep)
        d_arc = np.abs(np.linalg.norm(rel, axis=1) - self.radius)
        ends = self.point_at(np.array([0.0, self.length]))
        d_end = np.minimum(np.linalg.norm(p - ends[0], axis=1), np.linalg.norm(p - ends[1], axis=1))
        return np.where(within, d_arc, d_end)


Primitive = Line | Arc


@dataclass(frozen=True)
class Contour:
    """A G1-continuous chain of lines and arcs (closed when its end meets its start)."""

    pieces: tuple[Primitive, ...]
    closed: bool = True

    @property
    def length(self) -> float:
        return float(sum(p.length for p in self.pieces))

    def sample(self, spacing: float) -> np.ndarray:
        """Points every ~``spacing`` metres along the contour, shape (n, 2)."""
        out = []
        for piece in self.pieces:
            m = max(2, int(np.ceil(piece.length / spacing)) + 1)
            out.append(piece.point_at(np.linspace(0.0, piece.length, m))[:-1])
        if not self.closed:
            last = self.pieces[-1]
            out.append(last.point_at(np.array([last.length])))
        return np.vstack(out)

    def offset(self, distance: float) -> Contour:
        """The contour moved ``distance`` metres to the left of the direction of travel."""
        return Contour(tuple(p.offset(distance) for p in self.pieces), self.closed)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Exact distance of (n, 2) points from the contour.

        Consecutive points go in runs of ``DISTANCE_RUN``; a piece is measured only on the
        runs where it can hold the nearest point of one of their points: where its bounding
        box is no farther from the run's box than the run's farthest corner is from some
        piece's start (an upper bound of every distance in the run). Along a path a run sees
        two or three pieces, not all of them: the score of a learned path costs ~10 times
        less, in one call per piece on all its runs at once (large arrays, so numpy works
        without the interpreter lock). Points in no such order (scattered, or far from the
        contour) measure every piece on every point.
        """
        p = np.atleast_2d(np.asarray(points, dtype=float))
        d = np.full(len(p), np.inf)
        if len(p) == 0:
            return d
        boxes_lo, boxes_hi, starts = self._piece_boxes
        firsts = np.arange(0, len(p), DISTANCE_RUN)
        lo = np.minimum.reduceat(p, firsts)[:, None, :]  # (runs, 1, 2)
        hi = np.maximum.reduceat(p, firsts)[:, None, :]
        gap = np.maximum(0.0, np.maximum(boxes_lo - hi, lo - boxes_hi))  # (runs, pieces, 2)
        nearest_possible = np.hypot(gap[..., 0], gap[..., 1])
        corner = np.maximum(np.abs(starts - lo), np.abs(starts - hi))
        bound = np.hypot(corner[..., 0], corner[..., 1]).min(axis=1)
        candidate = nearest_possible <= bound[:, None]  # (runs, pieces)
        if candidate.sum() > 0.25 * candidate.size:  # pruning would not pay for itself
            for piece in self.pieces:
                np.minimum(d, piece.distance(p), out=d)
            return d
        offsets = np.arange(DISTANCE_RUN)
        for i in np.flatnonzero(candidate.any(axis=0)):
            runs = np.flatnonzero(candidate[:, i])
            idx = (runs[:, None] * DISTANCE_RUN + offsets).ravel()
            idx = idx[idx < len(p)]
            d[idx] = np.minimum(d[idx], self.pieces[i].distance(p[idx]))
        return d

    @cached_property
    def _piece_boxes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(k, 2) lower and upper corners of each piece's bounding box (an arc's whole circle)
        and (k, 2) start point of each piece."""
        lo, hi, starts = [], [], []
        for piece in self.pieces:
            if isinstance(piece, Arc):
                c, r = np.asarray(piece.center), piece.radius
                lo.append(c - r)
                hi.append(c + r)
                starts.append(piece.point_at(np.zeros(1))[0])
            else:
                a, b = np.asarray(piece.start), np.asarray(piece.end)
                lo.append(np.minimum(a, b))
                hi.append(np.maximum(a, b))
                starts.append(a)
        return np.array(lo), np.array(hi), np.array(starts)


def filleted_polygon(corners: np.ndarray, radii: np.ndarray) -> Contour:
    """Closed contour through the polygon ``corners`` (n, 2) with a fillet of ``radii[i]`` at each.

    Each corner is replaced by the tangent arc of its radius, so the contour is G1 (no kinks):
    gentle where the radius is large, sharp where it is small.
    """
    P = np.asarray(corners, dtype=float)
    R = np.asarray(radii, dtype=float)
    n = len(P)
    if n < 3 or R.shape != (n,):
        raise InvalidInputError("a filleted polygon needs >= 3 corners and one radius each")
    tangent_in, tangent_out, arcs = [], [], []
    for i in range(n):
        prev_pt, pt, next_pt = P[i - 1], P[i], P[(i + 1) % n]
        d_in = (pt - prev_pt) / np.linalg.norm(pt - prev_pt)
        d_out = (next_pt - pt) / np.linalg.norm(next_pt - pt)
        turn = np.arctan2(d_in[0] * d_out[1] - d_in[1] * d_out[0], d_in @ d_out)
        t_len = R[i] * np.tan(abs(turn) / 2)
        a = pt - d_in * t_len
        b = pt + d_out * t_len
        left_in = np.array([-d_in[1], d_in[0]])
        center = a + left_in * R[i] * np.sign(turn)
        start_angle = float(np.arctan2(a[1] - center[1], a[0] - center[0]))
        tangent_in.append(a)
        tangent_out.append(b)
        arcs.append(Arc(tuple(center), float(R[i]), start_angle, float(turn)))
    pieces: list[Primitive] = []
    for i in range(n):
        pieces.append(arcs[i])
        j = (i + 1) % n
        if np.linalg.norm(tangent_in[j] - tangent_out[i]) > 1e-9:
            seg = tangent_in[j] - tangent_out[i]
            d = (P[j] - P[i]) / np.linalg.norm(P[j] - P[i])
            if seg @ d < 0:
                raise InvalidInputError(
                    f"fillets at corners {i} and {j} overlap; use smaller radii"
                )
            pieces.append(Line(tuple(tangent_out[i]), tuple(tangent_in[j])))
    return Contour(tuple(pieces), closed=True)
