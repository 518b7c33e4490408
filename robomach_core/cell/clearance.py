"""The gap between the cutter and the nearest face of the part, for the teach displays.

PROBLEM   Leading the tool to a wall by eye is slow: the spindle hides the 1 mm ball, and only
          the pose numbers say where it is. The operator wants the gap to the nearest wall live
          beside the contact force, as a dial gauge would show it.
STRATEGY  coal's distance query between the cutter primitive (the same sphere or cylinder the
          contact model uses) and one BVH of the whole part mesh, built once per workpiece;
          the part is fixed, so only the cutter's transform changes per query.
SOLUTION  ``ClearanceProbe(tool, workpiece).gap(T_base_tcp) -> Gap``: the signed distance
          (negative while the cutter penetrates), the nearest point on the part and the unit
          normal from the part towards the cutter, base frame; and the height of the cutter's
          lowest point above the table plane.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import coal
import numpy as np

from ..part import Workpiece, bvh_from_mesh
from .tool import Tool


class Gap(NamedTuple):
    """Clearance of the cutter to the part at one pose (base frame, metres).

    Attributes:
        distance_m: Signed distance cutter-part (< 0: penetrating, then the depth is approximate).
        point_m: (3,) nearest point on the part.
        normal: (3,) unit vector from the part towards the cutter (zeros when undefined).
    """

    distance_m: float
    point_m: np.ndarray
    normal: np.ndarray


class ClearanceProbe:
    """Distance queries of one tool against one workpiece (the BVH is built once)."""

    def __init__(self, tool: Tool, workpiece: Workpiece) -> None:
        self.tool = tool
        self._bvh = bvh_from_mesh(workpiece.mesh.vertices, workpiece.mesh.faces)
        T = workpiece.T_base_wobj
        self._T_part = coal.Transform3s(T[:3, :3].copy(), T[:3, 3].copy())
        if tool.shape == "ball":
            self._cutter = coal.Sphere(tool.radius_m)
            self._offset = 0.0
        else:
            self._cutter = coal.Cylinder(tool.radius_m, tool.flute_length_m)
            self._offset = -0.5 * tool.flute_length_m
        self._request = coal.DistanceRequest()
        self._request.enable_signed_distance = True
        self._T_cutter = coal.Transform3s()

    def gap(self, T_base_tcp: np.ndarray) -> Gap:
        """The signed gap of the cutter at ``T_base_tcp`` (4x4) to the part."""
        R = np.asarray(T_base_tcp[:3, :3], dtype=float)
        center = T_base_tcp[:3, 3] + R[:, 2] * self._offset
        self._T_cutter.setRotation(R.copy())
        self._T_cutter.setTranslation(np.asarray(center, dtype=float).copy())
        result = coal.DistanceResult()
        distance = float(
            coal.distance(
                self._bvh, self._T_part, self._cutter, self._T_cutter, self._request, result
            )  # fmt: skip
        )
        on_part = np.asarray(result.getNearestPoint1(), dtype=float).copy()
        on_cutter = np.asarray(result.getNearestPoint2(), dtype=float).copy()
        d = on_cutter - on_part
        norm = float(np.linalg.norm(d))
        if norm > 1e-9 and math.isfinite(distance):
            normal = d / norm * (1.0 if distance >= 0 else -1.0)
        else:
            normal = np.zeros(3)
        return Gap(distance, on_part, normal)

    def height_above_m(self, T_base_tcp: np.ndarray, plane_z_m: float) -> float:
        """Height of the cutter's lowest point above the horizontal plane ``z = plane_z_m``."""
        R = np.asarray(T_base_tcp[:3, :3], dtype=float)
        p = T_base_tcp[:3, 3]
        if self.tool.shape == "ball":
            return float(p[2] - self.tool.radius_m - plane_z_m)
        axis = R[:, 2]
        tip_low = min(p[2], p[2] - axis[2] * self.tool.flute_length_m)
        radial = self.tool.radius_m * math.sqrt(max(0.0, 1.0 - axis[2] ** 2))
        return float(tip_low - radial - plane_z_m)
