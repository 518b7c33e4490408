"""Tool/workpiece contact through coal: penalty normal force and Coulomb friction.

PROBLEM   The simulated cutter must feel the part: a normal force that grows with penetration
          (the interaction stiffness the papers measured, 85-143 N/mm) and friction along the
          motion, computed fast enough for a 4 ms control loop. A mesh is a surface, not a solid:
          measured against the nearest triangle alone, a ball whose centre slips behind a face
          is pushed on through it (the normal flips), and coal reports degenerate contacts
          (depth equal to the radius, no normal) for a centre in a facet's plane, which read as
          no contact at all: learning then ran through 20 mm of wall with no force.
STRATEGY  coal finds the triangles the cutter overlaps (one BVH of the part, built once). For
          the ball cutter the exact geometry is then computed from them:
          the nearest triangle's closest point, and the side of the part the centre is on from
          that face's outward normal (``_kernels.ball_contact``): outside, depth = r - d along
          the direction from the surface to the centre; behind the surface (inside the
          material), depth = r + d along the face's normal, so the force always pushes the ball
          out to the free side. coal is asked for the triangles within r + ``SKIN_M`` of the
          centre, and they serve every period while the centre stays within ``SKIN_M`` of where
          it asked (a Verlet list): every face the ball can overlap there is among them, and the
          kernel keeps those it overlaps. Other cutter shapes use coal's deepest valid contact.
SOLUTION  F_n = k_c * depth + c_c * d(depth)/dt (>= 0), F_t = -mu * F_n * v_t / |v_t| regularised
          by tanh(|v_t| / v_0); the wrench is reported at the TCP in base-aligned axes.
"""

from __future__ import annotations

from typing import NamedTuple

import coal
import numpy as np

from .. import _kernels
from ..part import Workpiece, bvh_from_mesh
from .tool import Tool

CONTACT_DAMPING_N_S_M = 100.0
MAX_CONTACTS = 64  # triangles coal reports per query (a wall of 0.4 mm facets: ~10 at once)
# The ball's candidate faces come from a query this much wider than the ball, and serve while
# its centre stays this close to the query's; more candidates than SKIN_MAX_FACES: the ball's
# own query, each period.
SKIN_M = 0.0005
SKIN_MAX_FACES = 512
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


class ContactModel:
    """Penalty contact between a tool and a workpiece (coal geometry, built once)."""

    def __init__(self, tool: Tool, workpiece: Workpiece) -> None:
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
        else:
            self._cutter = coal.Cylinder(tool.radius_m, tool.flute_length_m)
            # The cylinder's centre sits half a flute length behind the tip (towards the flange).
            self._cutter_offset = -0.5 * tool.flute_length_m
        self._bvh = bvh_from_mesh(workpiece.mesh.vertices, workpiece.mesh.faces)
        self._request = coal.CollisionRequest(coal.CollisionRequestFlag.CONTACT, MAX_CONTACTS)
        # The part's triangles and outward normals in the base frame (the ball's exact contact).
        R, t = workpiece.T_base_wobj[:3, :3], workpiece.T_base_wobj[:3, 3]
        mesh = workpiece.mesh
        self._triangles = np.ascontiguousarray(mesh.vertices[mesh.faces] @ R.T + t)
        self._normals = np.ascontiguousarray(np.asarray(mesh.face_normals) @ R.T)
        self._result = coal.CollisionResult()
        self._T_cutter = coal.Transform3s()
        # The ball's candidate faces (``SKIN_M``): where coal was asked, and what it found.
        self._params = np.array(
            [tool.radius_m, self.stiffness_N_m, self.damping_N_s_m, self.friction]
            + [FRICTION_VELOCITY_M_S]
        )
        self._skin_sphere = coal.Sphere(tool.radius_m + SKIN_M + 1e-6)
        self._skin_request = coal.CollisionRequest(
            coal.CollisionRequestFlag.CONTACT, SKIN_MAX_FACES
        )
        self._skin_center = np.full(3, np.inf)
        self._skin_valid_m = 0.0
        self._candidates = np.empty(0, dtype=np.int64)

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
        p_tcp = T_base_tcp[:3, 3]
        if self._cutter_offset == 0.0:  # the ball: exact nearest face and side
            for _ in range(2):
                status, distance, depth, out = _kernels.ball_contact(
                    p_tcp,
                    self._skin_center,
                    self._skin_valid_m,
                    self._candidates,
                    self._triangles,
                    self._normals,
                    p_tcp,
                    velocity_m_s,
                    previous_depth_m,
                    dt,
                    self._params,
                )
                if status >= 0:
                    break
                self._query_candidates(p_tcp)
            if status <= 0:
                return NO_CONTACT
            return ContactResult(True, distance, depth, out[:3], out[3:])
        R = T_base_tcp[:3, :3]
        self._T_cutter.setRotation(R)
        self._T_cutter.setTranslation(p_tcp + R[:, 2] * self._cutter_offset)
        self._result.clear()
        if not coal.collide(
            self._bvh, self._T_part, self._cutter, self._T_cutter, self._request, self._result
        ):
            return NO_CONTACT
        deepest = None
        for i in range(self._result.numContacts()):
            contact = self._result.getContact(i)
            if float(np.linalg.norm(contact.normal)) < 1e-9:
                continue  # degenerate contact (a centre in a facet's plane): no normal
            if deepest is None or contact.penetration_depth < deepest.penetration_depth:
                deepest = contact
        if deepest is None or deepest.penetration_depth >= 0.0:
            return NO_CONTACT
        depth = -float(deepest.penetration_depth)
        # coal: the contact normal points from o1 (the part) to o2 (the cutter).
        normal = deepest.normal / np.linalg.norm(deepest.normal)
        out = _kernels.penalty_wrench(
            depth, normal, deepest.pos, p_tcp, velocity_m_s, previous_depth_m, dt, self._params
        )
        return ContactResult(True, -depth, depth, out[:3], out[3:])

    def _query_candidates(self, center: np.ndarray) -> None:
        """coal's faces within the ball's radius + ``SKIN_M`` of ``center``: the ball's
        candidates while it stays within ``SKIN_M`` of ``center``. When coal finds more than
        it reports, the faces the ball itself overlaps, valid at ``center`` alone."""
        self._skin_center = center.copy()
        self._T_cutter.setTranslation(center)
        self._skin_valid_m = SKIN_M
        for sphere, request in (
            (self._skin_sphere, self._skin_request),
            (self._cutter, self._request),
        ):
            self._result.clear()
            coal.collide(self._bvh, self._T_part, sphere, self._T_cutter, request, self._result)
            n = self._result.numContacts()
            if n < request.num_max_contacts:
                break
            self._skin_valid_m = 0.0
        self._candidates = np.array(
            [self._result.getContact(i).b1 for i in range(n)], dtype=np.int64
        )
