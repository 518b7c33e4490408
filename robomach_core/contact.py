"""Tool/workpiece contact through coal: penalty normal force and Coulomb friction.

PROBLEM   The simulated cutter must feel the part: a normal force that grows with penetration
          (the interaction stiffness the papers measured, 85-143 N/mm) and friction along the
          motion, computed fast enough for a 4 ms control loop. A mesh is a surface, not a solid:
          measured against the nearest triangle alone, a ball whose centre slips behind a face
          is pushed on through it (the normal flips), and coal reports degenerate contacts
          (depth equal to the radius, no normal) for a centre in a facet's plane, which read as
          no contact at all: learning then ran through 20 mm of wall with no force.
STRATEGY  coal finds the triangles the cutter overlaps (a BVH per cell of a uniform grid, built
          when first visited). For the ball cutter the exact geometry is then computed from them:
          the nearest triangle's closest point, and the side of the part the centre is on from
          that face's outward normal (``_kernels.nearest_face``): outside, depth = r - d along
          the direction from the surface to the centre; behind the surface (inside the
          material), depth = r + d along the face's normal, so the force always pushes the ball
          out to the free side. Other cutter shapes use coal's deepest valid contact.
SOLUTION  F_n = k_c * depth + c_c * d(depth)/dt (>= 0), F_t = -mu * F_n * v_t / |v_t| regularised
          by tanh(|v_t| / v_0); the wrench is reported at the TCP in base-aligned axes.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import coal
import numpy as np

from . import _kernels
from .tool import Tool
from .workpiece import Workpiece

CONTACT_DAMPING_N_S_M = 100.0
MAX_CONTACTS = 64  # triangles coal reports per query (a wall of 0.4 mm facets: ~10 at once)
FRICTION_VELOCITY_M_S = 0.0005  # below this the friction force is scaled down (tanh)


class ContactResult(NamedTuple):
    """Contact of the cutter with the part at one instant.

    Attributes:
        in_contact: True when the cutter penetrates the part.
        depth_m: Penetration depth (0 when apart); ``distance_m`` is the signed distance.
        normal: (3,) unit normal from the part towards the cutter, base frame.
        wrench: (6,) [force N, torque N*m about the TCP] that the part applies to the cutter,
            base-aligned axes.
    """

    in_contact: bool
    distance_m: float
    depth_m: float
    normal: np.ndarray
    wrench: np.ndarray


NO_CONTACT = ContactResult(False, np.inf, 0.0, np.zeros(3), np.zeros(6))


def _bvh_from_mesh(vertices: np.ndarray, faces: np.ndarray) -> coal.BVHModelOBBRSS:
    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(len(faces), len(vertices))
    bvh.addVertices(np.ascontiguousarray(vertices, dtype=float))
    bvh.addTriangles(np.ascontiguousarray(faces, dtype=np.int32))
    bvh.endModel()
    return bvh


class _CellGrid:
    """Uniform-grid broad phase: one small coal BVH per grid cell, built when first visited.

    Extruded parts have long sliver triangles (polygon caps) whose bounding volumes overlap
    everywhere, which makes a single BVH slow to traverse; a cell's BVH holds only the triangles
    within ``margin`` of the cell, so the narrow phase sees tens of triangles, not thousands.
    """

    def __init__(
        self,
        vertices: np.ndarray,
        faces: np.ndarray,
        cell_m: float,
        margin_m: float,
        T_base_wobj: np.ndarray,
    ) -> None:
        self.vertices = np.asarray(vertices, dtype=float)
        self.faces = np.asarray(faces, dtype=np.int64)
        tri = self.vertices[self.faces]
        self.lo = tri.min(axis=1)
        self.hi = tri.max(axis=1)
        self.cell_m = cell_m
        self.margin_m = margin_m
        self._cells: dict[tuple[int, int, int], tuple[coal.BVHModelOBBRSS, np.ndarray] | None] = {}
        # p_wobj = R^T (p_base - t), as plain floats (this runs every control period).
        self._rows = T_base_wobj[:3, :3].T.tolist()
        self._origin = T_base_wobj[:3, 3].tolist()

    def bvh_at(self, p_base: np.ndarray) -> tuple[coal.BVHModelOBBRSS, np.ndarray] | None:
        """The BVH of the cell holding ``p_base`` (base frame), built on first visit, and the
        mesh's face index of each of its triangles."""
        x, y, z = p_base.tolist()
        ox, oy, oz = self._origin
        x, y, z = x - ox, y - oy, z - oz
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = self._rows
        c = self.cell_m
        key = (
            math.floor((r00 * x + r01 * y + r02 * z) / c),
            math.floor((r10 * x + r11 * y + r12 * z) / c),
            math.floor((r20 * x + r21 * y + r22 * z) / c),
        )
        if key not in self._cells:
            cmin = np.asarray(key, dtype=float) * self.cell_m - self.margin_m
            cmax = cmin + self.cell_m + 2 * self.margin_m
            sel = np.all((self.hi >= cmin) & (self.lo <= cmax), axis=1)
            faces = np.flatnonzero(sel)
            self._cells[key] = (
                (_bvh_from_mesh(self.vertices, self.faces[faces]), faces) if len(faces) else None
            )
        return self._cells[key]


class ContactModel:
    """Penalty contact between a tool and a workpiece (coal geometry, built once)."""

    def __init__(self, tool: Tool, workpiece: Workpiece, *, cell_m: float = 0.004) -> None:
        self.tool = tool
        self.stiffness_N_m = float(workpiece.contact_stiffness_N_m)
        self.damping_N_s_m = CONTACT_DAMPING_N_S_M
        self.friction = float(workpiece.friction_coefficient)
        self._T_part = coal.Transform3s(
            workpiece.T_base_wobj[:3, :3].copy(), workpiece.T_base_wobj[:3, 3].copy()
        )
        if tool.shape == "ball":
            self._cutter = coal.Sphere(tool.radius_m)
            self._cutter_offset = 0.0
            bounding_radius = tool.radius_m
        else:
            self._cutter = coal.Cylinder(tool.radius_m, tool.flute_length_m)
            # The cylinder's centre sits half a flute length behind the tip (towards the flange).
            self._cutter_offset = -0.5 * tool.flute_length_m
            bounding_radius = float(np.hypot(tool.radius_m, 0.5 * tool.flute_length_m))
        # A cell must hold every triangle the cutter can touch from anywhere inside the cell,
        # including while it penetrates by up to its radius.
        self._grid = _CellGrid(
            workpiece.mesh.vertices,
            workpiece.mesh.faces,
            cell_m,
            margin_m=bounding_radius + tool.radius_m,
            T_base_wobj=workpiece.T_base_wobj,
        )
        self._request = coal.CollisionRequest(coal.CollisionRequestFlag.CONTACT, MAX_CONTACTS)
        # The part's triangles and outward normals in the base frame (the ball's exact contact).
        R, t = workpiece.T_base_wobj[:3, :3], workpiece.T_base_wobj[:3, 3]
        mesh = workpiece.mesh
        self._triangles = np.ascontiguousarray(mesh.vertices[mesh.faces] @ R.T + t)
        self._normals = np.ascontiguousarray(np.asarray(mesh.face_normals) @ R.T)
        self._radius = tool.radius_m
        self._result = coal.CollisionResult()
        self._T_cutter = coal.Transform3s()

    def evaluate(
        self,
        T_base_tcp: np.ndarray,
        velocity_m_s: np.ndarray,
        previous_depth_m: float,
        dt: float,
    ) -> ContactResult:
        """Contact wrench on the cutter at pose ``T_base_tcp`` moving at ``velocity_m_s``.

        The ball: the nearest of the triangles coal reports defines depth, normal and contact
        point, on the free side of the part (module docstring); adjacent facets of one wall
        report the same penetration, so summing them would count it twice. Other cutters: the
        deepest of coal's non-degenerate contacts.
        """
        R = T_base_tcp[:3, :3]
        p_tcp = T_base_tcp[:3, 3]
        center = p_tcp + R[:, 2] * self._cutter_offset if self._cutter_offset else p_tcp
        cell = self._grid.bvh_at(center)
        if cell is None:
            return NO_CONTACT
        bvh, faces = cell
        self._T_cutter.setRotation(R)
        self._T_cutter.setTranslation(center)
        self._result.clear()
        if not coal.collide(
            bvh, self._T_part, self._cutter, self._T_cutter, self._request, self._result
        ):
            return NO_CONTACT
        result = self._result
        if self._cutter_offset == 0.0:  # the ball: exact nearest face and side
            touched = np.array(
                [faces[result.getContact(i).b1] for i in range(result.numContacts())],
                dtype=np.int64,
            )
            dist, closest, face_normal, inside = _kernels.nearest_face(
                center, self._triangles, self._normals, touched
            )
            if inside:
                depth = self._radius + dist
                nx, ny, nz = face_normal.tolist()
            else:
                depth = self._radius - dist
                if depth <= 0.0:
                    return NO_CONTACT
                if dist > 1e-9:
                    nx, ny, nz = ((center - closest) / dist).tolist()
                else:
                    nx, ny, nz = face_normal.tolist()
            px, py, pz = closest.tolist()
        else:
            deepest = None
            for i in range(result.numContacts()):
                contact = result.getContact(i)
                if float(np.linalg.norm(contact.normal)) < 1e-9:
                    continue  # degenerate contact (a centre in a facet's plane): no normal
                if deepest is None or contact.penetration_depth < deepest.penetration_depth:
                    deepest = contact
            if deepest is None:
                return NO_CONTACT
            depth = -float(deepest.penetration_depth)
            if depth <= 0.0:
                return NO_CONTACT
            # coal: the contact normal points from o1 (the part) to o2 (the cutter).
            nx, ny, nz = deepest.normal.tolist()
            px, py, pz = deepest.pos.tolist()
            norm = math.sqrt(nx * nx + ny * ny + nz * nz)
            nx, ny, nz = nx / norm, ny / norm, nz / norm
        depth_rate = (depth - previous_depth_m) / dt
        f_n = max(0.0, self.stiffness_N_m * depth + self.damping_N_s_m * depth_rate)
        vx, vy, vz = velocity_m_s.tolist()
        vn = vx * nx + vy * ny + vz * nz
        tx, ty, tz = vx - vn * nx, vy - vn * ny, vz - vn * nz
        speed_t = math.sqrt(tx * tx + ty * ty + tz * tz)
        fx, fy, fz = f_n * nx, f_n * ny, f_n * nz
        if speed_t > 1e-12 and self.friction > 0.0:
            k = self.friction * f_n * math.tanh(speed_t / FRICTION_VELOCITY_M_S) / speed_t
            fx, fy, fz = fx - k * tx, fy - k * ty, fz - k * tz
        ox, oy, oz = p_tcp.tolist()
        rx, ry, rz = px - ox, py - oy, pz - oz
        wrench = np.array([fx, fy, fz, ry * fz - rz * fy, rz * fx - rx * fz, rx * fy - ry * fx])
        return ContactResult(True, -depth, depth, np.array([nx, ny, nz]), wrench)
