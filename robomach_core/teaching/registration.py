"""Work-object calibration: the CAD registered to touches of the real part.

PROBLEM   A casting sits in its fixture a few millimetres and a degree or two off where its CAD
          is placed (``real_part``): points taught on the CAD then land on the rim of a 5 mm
          groove. A robot pendant answers with a measured work object (ABB's 3-point user
          frame, KUKA's base measurement): touch the real part, and place the frame there.
STRATEGY  A touch is a guarded move of the ball cutter along a direction d until the part
          pushes back at the set force F (``LeadThrough.touch_off_along``). Its centre q then
          stands r - F/k off the real surface (r the ball's radius; F/k its press into the part
          at the interaction stiffness k, the same k post-processing takes). A touch fixes one
          coordinate of the part (its distance along the face's normal), not a point, so the
          fit is point-to-plane, not Kabsch's point-to-point: find the rigid motion M of the
          CAD (work-object frame) minimising

              sum_i ( n_i . (M^-1 q_i - p_i) - (r_i - F_i / k) )^2

          with p_i, n_i the nearest point of the CAD's faces that face the touch
          (n . d < -``FACING_COS``) and that face's normal, found anew each iteration
          (iterative closest point, point-to-plane: Chen and Medioni 1992). For fixed faces
          the problem is smooth and ``scipy.optimize.least_squares`` solves it over
          (rotation vector about the touches' centroid, translation). Six well-spread touches
          fix a frame, three-two-one: three on a top face (z, rx, ry), two on a side (y, rz),
          one on another side (x); more give a residual that says how well the CAD fits.
SOLUTION  ``fit_wobj(cad, touches, contact_stiffness_N_m=) -> WobjFit`` (the registered frame,
          the residual per touch, the one-sigma uncertainty; ``CalibrationError`` naming the
          directions the touches leave free); ``WobjRegistration`` is the accepted fit a project
          keeps in its cell settings; ``registered_workpiece(part, T)`` the part with its CAD
          placed at the registered frame (what teaching, the checks and the CAD-only program
          then use).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
import scipy.optimize
from scipy.spatial.transform import Rotation

from ..errors import InvalidInputError
from ..part import Workpiece, mesh_query
from ..transforms import inverse_transform, make_transform, unit_vector

FACING_COS = 0.5  # a touch meets faces whose normal is within 60 deg of against its direction
MIN_TOUCHES = 6  # a rigid frame has six unknowns
# A direction of the frame (1 mm of shift, or a turn moving the part's farthest point 1 mm)
# that moves the touches' residuals by less than sqrt(this) mm altogether (0.03 mm: what a
# touch resolves, the sensor's noise over the contact stiffness and the arm's bending) is not
# fixed by them.
WEAK_EIGENVALUE = 1e-3
MAX_ICP_ITERATIONS = 40
CONVERGED_M = 1e-9  # the correspondences settle and a step moves the frame less than this
DEFAULT_CONTACT_STIFFNESS_N_M = 100e3  # post-processing's default: the papers' 85-143 N/mm
METHOD = "point-to-plane"
# A touch that stands this far from where the other touches put its face met something else
# (a chip, a clamp): a casting's walls are within 0.5 mm of their CAD.
ODD_TOUCH_M = 1.0e-3
AGREE_M = 0.3e-3  # ... and the others agree without it within this (RMS)


class CalibrationError(InvalidInputError):
    """The touches cannot place the work object: too few, or directions they leave free."""


# --- the values ------------------------------------------------------------------------------


def _vector(value: Any, name: str) -> tuple[float, float, float]:
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InvalidInputError(f"{name} must be 3 finite numbers")
    return (float(v[0]), float(v[1]), float(v[2]))


@dataclass(frozen=True)
class Touch:
    """One touch of the real part (SI, robot base frame).

    Attributes:
        tcp_m: The ball's centre where the guarded move stopped (the motor-side TCP: what the
            controller knows).
        direction: Unit direction of the move (into the part).
        force_N: Contact force pushing back along -direction when it stopped.
        tool_radius_m: The ball's radius.
        feature: What was touched, for people ("top", "side facing -y"; "" when not said).
    """

    tcp_m: tuple[float, float, float]
    direction: tuple[float, float, float]
    force_N: float
    tool_radius_m: float
    feature: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "tcp_m", _vector(self.tcp_m, "a touch's position"))
        d = np.asarray(_vector(self.direction, "a touch's direction"))
        if abs(float(np.linalg.norm(d)) - 1.0) > 1e-12:  # a unit one stays (a saved touch)
            d = unit_vector(d, "a touch's direction")
        object.__setattr__(self, "direction", _vector(d, "direction"))
        if not (math.isfinite(self.force_N) and 0.0 <= self.force_N <= 1000.0):
            raise InvalidInputError("a touch's force must be within 0-1000 N")
        if not (math.isfinite(self.tool_radius_m) and 0.0 < self.tool_radius_m < 0.05):
            raise InvalidInputError("a touch's tool radius must be within 0-50 mm")
        object.__setattr__(self, "force_N", float(self.force_N))
        object.__setattr__(self, "tool_radius_m", float(self.tool_radius_m))
        object.__setattr__(self, "feature", str(self.feature)[:80])

    @classmethod
    def from_value(cls, value: Any) -> Touch:
        if isinstance(value, Touch):
            return value
        if not isinstance(value, dict):
            raise InvalidInputError("a touch is a dict of its fields")
        unknown = set(value) - set(cls.__dataclass_fields__)
        if unknown:
            raise InvalidInputError(f"unknown touch fields {sorted(unknown)}")
        return cls(**value)

    def document(self) -> dict[str, Any]:
        """The touch at the boundary (mm)."""
        return {
            "tcp_mm": [round(v * 1e3, 4) for v in self.tcp_m],
            "direction": [round(v, 6) for v in self.direction],
            "force_N": round(self.force_N, 3),
            "tool_radius_mm": round(self.tool_radius_m * 1e3, 4),
            "feature": self.feature,
        }


@dataclass(frozen=True)
class WobjRegistration:
    """An accepted work-object calibration: where the CAD is placed on the real part.

    Attributes:
        wobj_mm_deg: The registered work-object frame: x, y, z [mm], rx, ry, rz [deg]
            (rotations about the fixed base axes x, then y, then z: ``--wobj``'s convention).
        touches: The touches it was fitted to.
        rms_mm: RMS of the touches' residuals.
        max_mm: Largest residual.
        method: The fit (``METHOD``).
    """

    wobj_mm_deg: tuple[float, ...]
    touches: tuple[Touch, ...] = ()
    rms_mm: float = 0.0
    max_mm: float = 0.0
    method: str = METHOD

    def __post_init__(self) -> None:
        v = np.asarray(self.wobj_mm_deg, dtype=float).reshape(-1)
        if v.shape != (6,) or not np.all(np.isfinite(v)):
            raise InvalidInputError("a registered work object is x, y, z [mm], rx, ry, rz [deg]")
        object.__setattr__(self, "wobj_mm_deg", tuple(float(x) for x in v))
        object.__setattr__(self, "touches", tuple(Touch.from_value(t) for t in self.touches))
        object.__setattr__(self, "rms_mm", float(self.rms_mm))
        object.__setattr__(self, "max_mm", float(self.max_mm))

    @classmethod
    def from_value(cls, value: Any) -> WobjRegistration | None:
        """A registration from itself, a dict (a saved document) or None."""
        if value is None or isinstance(value, WobjRegistration):
            return value
        if not isinstance(value, dict):
            raise InvalidInputError("a work-object registration is a dict of its fields, or null")
        unknown = set(value) - set(cls.__dataclass_fields__)
        if unknown:
            raise InvalidInputError(f"unknown registration fields {sorted(unknown)}")
        return cls(**value)

    @property
    def T_base_wobj(self) -> np.ndarray:
        """4x4 registered work-object frame [m]."""
        return transform_from_mm_deg(self.wobj_mm_deg)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def document(self) -> dict[str, Any]:
        """The registration at the boundary (mm, deg)."""
        return {
            "wobj_mm_deg": [round(v, 6) for v in self.wobj_mm_deg],
            "touches": len(self.touches),
            "rms_mm": round(self.rms_mm, 4),
            "max_mm": round(self.max_mm, 4),
            "method": self.method,
        }


def transform_from_mm_deg(values: Sequence[float]) -> np.ndarray:
    """4x4 frame from x, y, z [mm], rx, ry, rz [deg] (R = Rz Ry Rx, scipy's extrinsic "xyz")."""
    v = np.asarray(values, dtype=float)
    R = Rotation.from_euler("xyz", v[3:6], degrees=True).as_matrix()
    return make_transform(R, v[:3] * 1e-3)


def mm_deg_from_transform(T: np.ndarray) -> tuple[float, ...]:
    """The six numbers of ``transform_from_mm_deg`` for a 4x4 frame (angles in (-180, 180])."""
    T = np.asarray(T, dtype=float)
    angles = Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
    return tuple(float(x) for x in (*(T[:3, 3] * 1e3), *angles))


# --- the fit ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class WobjFit:
    """The CAD registered to the touches (``fit_wobj``).

    Attributes:
        T_base_wobj: 4x4 registered work-object frame (the CAD placed on the real part).
        T_base_wobj_before: Where the CAD was placed before.
        touches: The touches.
        residuals_m: (n,) per touch: the ball centre's distance from the registered CAD's face
            minus (r - F/k); + the CAD's face stands short of the real one.
        surface_base_m: (n, 3) the point of the registered CAD each touch met (base frame).
        normals_base: (n, 3) the normal of that face (base frame).
        faces: Per touch, the face it met, for people ("a face facing -y (work object)").
        std_position_m: One-sigma uncertainty of the frame's position at the touches' centroid
            (from the residual: sigma^2 (J^T J)^-1), None with six touches or fewer.
        std_rotation_rad: One-sigma uncertainty of its rotation, None likewise.
        iterations: Iterations of the closest-point loop.
        contact_stiffness_N_m: The k the presses were corrected with.
        moved_max_m: The farthest the registration moved a point of the CAD.
        disagreement_m: (n,) per touch, how far it stands from where the fit of the other
            touches puts its face (leave-one-out, linearised at the fit); NaN for a touch the
            frame needs (the others leave a direction free without it).
        consistent_without: (n,) per touch, True when the other touches agree (RMS within
            ``AGREE_M``) once it is left out: the candidates for a touch that met something
            else.
    """

    T_base_wobj: np.ndarray
    T_base_wobj_before: np.ndarray
    touches: tuple[Touch, ...]
    residuals_m: np.ndarray
    surface_base_m: np.ndarray
    normals_base: np.ndarray
    faces: tuple[str, ...]
    std_position_m: float | None
    std_rotation_rad: float | None
    iterations: int
    contact_stiffness_N_m: float
    moved_max_m: float = 0.0
    disagreement_m: np.ndarray | None = None
    consistent_without: np.ndarray | None = None
    method: str = field(default=METHOD)

    @property
    def rms_m(self) -> float:
        return float(np.sqrt(np.mean(self.residuals_m**2)))

    @property
    def max_m(self) -> float:
        return float(np.max(np.abs(self.residuals_m)))

    @property
    def redundancy(self) -> int:
        """Touches beyond the six a frame needs (what the residual is measured with)."""
        return len(self.touches) - MIN_TOUCHES

    @property
    def correction(self) -> np.ndarray:
        """4x4 motion of the CAD in its former work-object frame: T_after = T_before @ this."""
        return inverse_transform(self.T_base_wobj_before) @ self.T_base_wobj

    @property
    def rotation_rad(self) -> float:
        """How far it turned the CAD."""
        return float(np.linalg.norm(Rotation.from_matrix(self.correction[:3, :3]).as_rotvec()))

    @property
    def wobj_mm_deg(self) -> tuple[float, ...]:
        return mm_deg_from_transform(self.T_base_wobj)

    def registration(self) -> WobjRegistration:
        """The value a project keeps (``CellSettings.registration``)."""
        return WobjRegistration(
            self.wobj_mm_deg, self.touches, self.rms_m * 1e3, self.max_m * 1e3, self.method
        )

    def describe(self) -> str:
        """One sentence for people."""
        faces = len(set(self.faces))
        extra = (
            f" ({self.redundancy} more than the {MIN_TOUCHES} a frame needs)"
            if self.redundancy > 0
            else f" (exactly the {MIN_TOUCHES} a frame needs: no residual to judge it by; "
            "touch more)"
        )
        sigma = ""
        if self.std_position_m is not None and self.std_rotation_rad is not None:
            sigma = (
                f"; one sigma {self.std_position_m * 1e3:.3f} mm, "
                f"{math.degrees(self.std_rotation_rad):.3f} deg"
            )
        odd, d = self.odd_touches(), self.disagreement_m
        if not odd or d is None:  # odd touches are found from the disagreements
            odd_text = ""
        elif len(odd) == 1:
            k = odd[0]
            odd_text = (
                f"; touch {k + 1} stands {abs(d[k]) * 1e3:.2f} mm off where "
                "the others put its face (it met something else): delete it and touch again"
            )
        else:
            listed = ", ".join(str(k + 1) for k in odd)
            worst = float(np.nanmax(np.abs(d)))
            odd_text = (
                f"; the touches disagree by up to {worst * 1e3:.2f} mm: one of touches {listed} "
                "met something else (the others agree without it); touch that face again at "
                "more places"
            )
        return (
            f"registered on {len(self.touches)} touches of {faces} faces{extra} by a "
            f"{self.method} least-squares fit: the CAD moved up to {self.moved_max_m * 1e3:.2f} "
            f"mm and turned {math.degrees(self.rotation_rad):.2f} deg onto the part; residual RMS "
            f"{self.rms_m * 1e3:.3f} mm, max {self.max_m * 1e3:.3f} mm{sigma}{odd_text}"
        )

    def odd_touches(self) -> list[int]:
        """When a touch stands more than ``ODD_TOUCH_M`` from where the others put its face:
        the touches of the faces such touches met whose leaving out makes the rest agree (one:
        that one; several on one face: it is one of them, and the touches cannot tell which);
        else []. A chip under one of a face's touches moves every touch of that face off where
        the others put it, but hardly those of the other faces (which, with every face touched
        once more than it needs, agree without any one touch: named, they said nothing)."""
        d, agree = self.disagreement_m, self.consistent_without
        if d is None or agree is None:
            return []
        beyond = np.abs(np.nan_to_num(d)) > ODD_TOUCH_M
        faces = {self.faces[k] for k in np.flatnonzero(beyond)}
        return [int(k) for k in np.flatnonzero(agree) if self.faces[k] in faces]

    def document(self) -> dict[str, Any]:
        """The fit at the boundary (mm, deg), for the API and summary.json."""
        return {
            "method": self.method,
            "wobj_mm_deg": [round(v, 4) for v in self.wobj_mm_deg],
            "wobj_before_mm_deg": [round(v, 4) for v in mm_deg_from_transform(
                self.T_base_wobj_before)],
            "moved_max_mm": round(self.moved_max_m * 1e3, 4),
            "turned_deg": round(math.degrees(self.rotation_rad), 4),
            "touches": len(self.touches),
            "redundancy": self.redundancy,
            "rms_mm": round(self.rms_m * 1e3, 4),
            "max_mm": round(self.max_m * 1e3, 4),
            "std_position_mm": None
            if self.std_position_m is None
            else round(self.std_position_m * 1e3, 4),
            "std_rotation_deg": None
            if self.std_rotation_rad is None
            else round(math.degrees(self.std_rotation_rad), 4),
            "contact_stiffness_N_mm": round(self.contact_stiffness_N_m * 1e-3, 3),
            "residuals_mm": [round(float(r) * 1e3, 4) for r in self.residuals_m],
            "disagreement_mm": [
                None if not np.isfinite(d) else round(float(d) * 1e3, 4)
                for d in (self.disagreement_m if self.disagreement_m is not None else ())
            ],
            "odd_touches": self.odd_touches(),
            "surface_mm": [[round(float(v) * 1e3, 3) for v in p] for p in self.surface_base_m],
            "faces": list(self.faces),
            "message": self.describe(),
        }  # fmt: skip


def _face_name(normal_wobj: np.ndarray) -> str:
    """The face's name ("the face facing -y (work object)"), or its normal off the axes."""
    n = np.asarray(normal_wobj, dtype=float)
    i = int(np.argmax(np.abs(n)))
    if abs(n[i]) > math.cos(math.radians(10.0)):
        return f"the face facing {'+' if n[i] > 0 else '-'}{'xyz'[i]} (work object)"
    return "the face facing ({:+.2f}, {:+.2f}, {:+.2f}) (work object)".format(*n)


class _Correspondence:
    """The nearest facing face of the CAD (work-object frame) for each touch."""

    def __init__(self, cad: Workpiece, directions_wobj: np.ndarray) -> None:
        self.mesh = cad.mesh
        normals = np.asarray(self.mesh.face_normals)
        self.groups: list[tuple[np.ndarray, Any]] = []
        self.index = np.zeros(len(directions_wobj), dtype=int)
        keys: dict[tuple, int] = {}
        for i, d in enumerate(directions_wobj):
            key = tuple(np.round(d, 3))
            if key not in keys:
                faces = np.flatnonzero(normals @ d < -FACING_COS)
                if len(faces) == 0:
                    raise CalibrationError(
                        "touch {} moves along ({:+.2f}, {:+.2f}, {:+.2f}) (work object), and no "
                        "face of the CAD faces that way".format(i + 1, *d)
                    )
                sub = self.mesh.submesh([faces], append=True)
                keys[key] = len(self.groups)
                self.groups.append((faces, sub))
            self.index[i] = keys[key]

    def find(self, points_wobj: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(closest points (n, 3), face normals (n, 3), face ids (n,)) for ``points_wobj``."""
        n = len(points_wobj)
        closest, normals, faces = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, dtype=int)
        for g, (ids, sub) in enumerate(self.groups):
            rows = np.flatnonzero(self.index == g)
            if len(rows) == 0:
                continue
            c, _, tri = mesh_query.closest_point(sub, points_wobj[rows])
            closest[rows] = c
            normals[rows] = np.asarray(sub.face_normals)[tri]
            faces[rows] = ids[tri]
        return closest, normals, faces


def _moved(x: np.ndarray, q: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """M^-1 q: the touches in the CAD's frame under x = (rotation vector, translation)."""
    R = Rotation.from_rotvec(x[:3]).as_matrix()
    return (q - centre) @ R.T + centre + x[3:]


def fit_wobj(
    cad: Workpiece,
    touches: Sequence[Touch],
    *,
    contact_stiffness_N_m: float = DEFAULT_CONTACT_STIFFNESS_N_M,
) -> WobjFit:
    """The CAD registered to ``touches`` (module docstring), starting where it is placed now.

    Args:
        cad: The part as its CAD (``Workpiece.cad()``), placed where it is believed to be.
        touches: Six or more touches of the real part.
        contact_stiffness_N_m: The interaction stiffness k: a touch at F presses F/k in.

    Raises:
        CalibrationError: fewer than six touches, or touches that leave a direction of the
            frame free (named, with what to touch).
    """
    touches = tuple(Touch.from_value(t) for t in touches)
    if len(touches) < MIN_TOUCHES:
        raise CalibrationError(
            f"{len(touches)} touches cannot place the work object: it needs at least "
            f"{MIN_TOUCHES}, on three faces (three on a top face, two on a side, one on another "
            "side)"
        )
    if not (math.isfinite(contact_stiffness_N_m) and contact_stiffness_N_m > 0):
        raise InvalidInputError("the contact stiffness must be a positive number of N/m")
    T0 = np.asarray(cad.T_base_wobj, dtype=float)
    R0, t0 = T0[:3, :3], T0[:3, 3]
    q = (np.array([t.tcp_m for t in touches]) - t0) @ R0  # in the CAD's frame
    d = np.array([t.direction for t in touches]) @ R0
    offset = np.array([t.tool_radius_m - t.force_N / contact_stiffness_N_m for t in touches])
    centre = q.mean(axis=0)
    spread = max(float(np.sqrt(np.mean(np.sum((q - centre) ** 2, axis=1)))), 1e-3)
    found = _Correspondence(cad, d)
    x = np.zeros(6)
    faces = None
    iterations = 0
    for iterations in range(1, MAX_ICP_ITERATIONS + 1):  # noqa: B007 - reported
        p, n, now = found.find(_moved(x, q, centre))

        def residual(xx: np.ndarray, p: np.ndarray = p, n: np.ndarray = n) -> np.ndarray:
            return np.einsum("ij,ij->i", n, _moved(xx, q, centre) - p) - offset

        scale = np.array([1e-3 / spread] * 3 + [1e-3] * 3)  # a millimetre at the touches
        step = scipy.optimize.least_squares(
            residual, x, jac="3-point", x_scale=scale, xtol=1e-12, ftol=1e-12
        )
        shift = _moved(step.x, q, centre) - _moved(x, q, centre)
        moved = float(np.max(np.linalg.norm(shift, axis=1)))
        x = step.x
        settled = faces is not None and np.array_equal(faces, now)
        faces = now
        if settled and moved < CONVERGED_M:
            break
    y = _moved(x, q, centre)
    p, n, faces = found.find(y)
    r = np.einsum("ij,ij->i", n, y - p) - offset
    # The Jacobian of the residuals at the solution (a small turn dw of the touches about their
    # centroid, scaled by the part's size so that a unit turn moves its farthest point as far
    # as a unit shift, and a shift dt): dr = ((y - c) x n) . dw + n . dt.
    size = max(float(np.max(np.linalg.norm(np.asarray(cad.mesh.vertices) - centre, axis=1))),
               1e-3)  # fmt: skip
    J = np.hstack([np.cross(y - centre, n) / size, n])
    _refuse_free_directions(J, R0)
    JtJ_inv = np.linalg.inv(J.T @ J)
    disagreement, agree = _left_out(J, r)
    std_p = std_r = None
    if len(touches) > MIN_TOUCHES:
        sigma2 = float(r @ r) / (len(touches) - MIN_TOUCHES)
        cov = sigma2 * JtJ_inv
        std_r = float(np.sqrt(np.trace(cov[:3, :3]))) / size
        std_p = float(np.sqrt(np.trace(cov[3:, 3:])))
    # M^-1 y = R (y - c) + c + t, so M y = R^T (y - c - t) + c: the CAD moves by M.
    R = Rotation.from_rotvec(x[:3]).as_matrix()
    M = make_transform(R.T, centre - R.T @ (centre + x[3:]))
    T = T0 @ M
    names = tuple(_face_name(nn) for nn in n)
    V = np.asarray(cad.mesh.vertices)
    moved = float(np.max(np.linalg.norm(V @ M[:3, :3].T + M[:3, 3] - V, axis=1)))
    return WobjFit(
        T_base_wobj=T,
        T_base_wobj_before=T0,
        touches=touches,
        residuals_m=r,
        surface_base_m=(p @ M[:3, :3].T + M[:3, 3]) @ R0.T + t0,
        normals_base=n @ M[:3, :3].T @ R0.T,
        faces=names,
        std_position_m=std_p,
        std_rotation_rad=std_r,
        iterations=iterations,
        contact_stiffness_N_m=float(contact_stiffness_N_m),
        moved_max_m=moved,
        disagreement_m=disagreement,
        consistent_without=agree,
    )


def _left_out(J: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per touch k, the fit of the others (one Gauss-Newton step from the fit, linear in the
    residuals r with Jacobian J): how far touch k stands from it (NaN when the others leave a
    direction free), and whether the others agree without it."""
    n = len(r)
    out, agree = np.full(n, np.nan), np.zeros(n, dtype=bool)
    for k in range(n):
        keep = np.arange(n) != k
        Jk, rk = J[keep], r[keep]
        if np.linalg.eigvalsh(Jk.T @ Jk)[0] < WEAK_EIGENVALUE:
            continue
        step = np.linalg.lstsq(Jk, rk, rcond=None)[0]
        out[k] = r[k] - J[k] @ step
        rest = rk - Jk @ step
        agree[k] = float(np.sqrt(np.mean(rest**2))) <= AGREE_M
    return out, agree


def _refuse_free_directions(J: np.ndarray, R_base_wobj: np.ndarray) -> None:
    """``CalibrationError`` naming each direction of the frame the touches do not fix."""
    values, vectors = np.linalg.eigh(J.T @ J)
    weak = [vectors[:, k] for k in range(6) if values[k] < WEAK_EIGENVALUE]
    if not weak:
        return
    names = []
    for u in weak:
        turn, shift = u[:3], u[3:]
        if np.linalg.norm(shift) >= np.linalg.norm(turn):
            axis = R_base_wobj @ shift
            names.append(f"a shift along {_axis_name(axis)}")
        else:
            axis = R_base_wobj @ turn
            names.append(f"a turn about {_axis_name(axis)}")
    raise CalibrationError(
        f"the touches do not fix {', '.join(dict.fromkeys(names))} of the part: touch faces "
        "that face those ways (three on a top face, two on a side, one on a side across it), "
        "spread apart"
    )


def _axis_name(v: np.ndarray) -> str:
    i = int(np.argmax(np.abs(v)))
    if abs(v[i]) / max(np.linalg.norm(v), 1e-12) > 0.9:
        return f"base {'xyz'[i]}"
    return "({:+.2f}, {:+.2f}, {:+.2f}) (base)".format(*(v / np.linalg.norm(v)))


# --- the registered part ---------------------------------------------------------------------


def registered_workpiece(part: Workpiece, T_base_wobj: np.ndarray) -> Workpiece:
    """``part`` (the real one the tool meets) with its CAD placed at the registered
    ``T_base_wobj``: ``cad()`` is then the registered CAD, and ``unregistered`` the CAD where
    it stood before (the CAD-only program without calibration is scored from it)."""
    cad = part.cad() if part.unregistered is None else part.unregistered
    T = np.asarray(T_base_wobj, dtype=float)
    registered = replace(cad, T_base_wobj=T, nominal=None, unregistered=None)
    return replace(part, nominal=registered, unregistered=cad)
