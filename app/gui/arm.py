"""The arm and its tool as the scene draws them: the URDF with its meshes, a fast joint pose,
the spindle and the cutter.

The arm is drawn from its URDF's visual meshes (yourdfpy through ``viser.extras.ViserUrdf``);
the built-in arms' meshes come from example-robot-data, an uploaded arm's from its own folder
only. The tool is two meshes in the TCP frame (tool axis +Z): the spindle body and shank, and
the cutter, which the scene colours apart.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import cast

import numpy as np
import trimesh
from viser.extras import ViserUrdf

from robomach_core.cell import (
    ROBOT_URDFS,
    SHANK_LENGTH_M,
    SHANK_RADIUS_FRACTION,
    SPINDLE_RADIUS_M,
    Tool,
    robots_directory,
)
from robomach_core.transforms import quaternion_from_matrix, rotation_about

# The example-robot-data URDFs name their meshes package://example-robot-data/robots/...
_PACKAGE_PREFIXES = ("package://example-robot-data/robots/", "package://")
MIN_BODY_DRAWN_M = 0.01  # the spindle body is drawn at least this long on a short tool


def _mesh_filename(fname: str) -> str:
    """yourdfpy filename handler: resolve ``package://`` mesh names in example-robot-data."""
    root = robots_directory()
    for prefix in _PACKAGE_PREFIXES:
        if fname.startswith(prefix):
            rest = fname[len(prefix) :]
            candidate = root / rest
            return str(candidate if candidate.exists() else root.parent / rest)
    return fname


@functools.lru_cache(maxsize=4)
def _load_urdf_bytes(robot: str) -> tuple[Path, bytes]:
    path = robots_directory() / ROBOT_URDFS[robot]
    return path, path.read_bytes()


def load_urdf(robot: str):  # -> yourdfpy.URDF
    """A fresh yourdfpy URDF of ``robot`` with its visual meshes (each ViserUrdf owns one).

    An uploaded arm's meshes are resolved by ``robots.custom.mesh_path`` inside its own
    folder only: a reference to any other file loads nothing (an absolute path or ``file://``
    read the server's disk, issue 32)."""
    import yourdfpy

    from robomach_core.robots import registry
    from robomach_core.robots.custom import mesh_path

    record = registry.arm(robot)

    def handler(fname: str) -> str:  # yourdfpy passes the name as ``fname=``
        return mesh_path(record, fname) if record.uploaded else _mesh_filename(fname)

    path = record.urdf_path() if record.uploaded else _load_urdf_bytes(robot)[0]
    return yourdfpy.URDF.load(
        str(path),
        filename_handler=handler,
        build_collision_scene_graph=False,
        load_collision_meshes=False,
    )


def tool_mesh(tool: Tool) -> trimesh.Trimesh:
    """Spindle body and shank in the TCP frame (tool axis +Z, the body towards -Z); the
    cutter is ``cutter_mesh``, drawn in its own colour."""
    length = float(tool.tcp_offset_m[2])
    cutter_len = tool.flute_length_m
    parts = []
    body_len = max(length - cutter_len - SHANK_LENGTH_M, MIN_BODY_DRAWN_M)
    body = trimesh.creation.cylinder(radius=SPINDLE_RADIUS_M, height=body_len, sections=32)
    body.apply_translation([0.0, 0.0, -length + body_len / 2])
    parts.append(body)
    shank_len = max(length - body_len - cutter_len, 0.002)
    shank = trimesh.creation.cylinder(
        radius=tool.radius_m * SHANK_RADIUS_FRACTION, height=shank_len, sections=16
    )
    shank.apply_translation([0.0, 0.0, -cutter_len - shank_len / 2])
    parts.append(shank)
    # trimesh annotates concatenate as returning any Geometry: meshes in, it is a Trimesh.
    return cast(trimesh.Trimesh, trimesh.util.concatenate(parts))


def cutter_mesh(tool: Tool) -> trimesh.Trimesh:
    """The cutting part in the TCP frame: a ball at the TCP or a cylinder ending at it."""
    if tool.shape == "ball":
        ball = trimesh.creation.icosphere(subdivisions=3, radius=tool.radius_m)
        stem = trimesh.creation.cylinder(radius=tool.radius_m, height=tool.flute_length_m)
        stem.apply_translation([0.0, 0.0, -tool.flute_length_m / 2])
        # trimesh annotates concatenate as returning any Geometry: meshes in, it is a Trimesh.
        return cast(trimesh.Trimesh, trimesh.util.concatenate([ball, stem]))
    mesh = trimesh.creation.cylinder(radius=tool.radius_m, height=tool.flute_length_m, sections=24)
    mesh.apply_translation([0.0, 0.0, -tool.flute_length_m / 2])
    return mesh


class RobotPose:
    """Moves a ViserUrdf's joint frames fast: only the revolute joints' orientations.

    ``ViserUrdf.update_cfg`` recomputes every joint through the trimesh scene graph and sets
    position and orientation of every frame (~5 ms for a UR arm); a revolute joint's child
    frame only turns about its axis, at a fixed origin, so six orientation updates suffice
    (~1 ms), which keeps the 30+ Hz redraw cheap next to a running simulation. Relies on
    ViserUrdf's joint-frame list (one frame per ``urdf.joint_map`` entry, in order); without it
    falls back to ``update_cfg``.
    """

    def __init__(self, viser_urdf: ViserUrdf, urdf) -> None:  # urdf: yourdfpy.URDF
        self._viser_urdf = viser_urdf
        joints = list(urdf.joint_map.values())
        frames = getattr(viser_urdf, "_joint_frames", None)
        names = list(urdf.actuated_joint_names)
        self._moving = []
        if frames is not None and len(frames) == len(joints):
            for frame, joint in zip(frames, joints, strict=True):
                if joint.name in names and joint.type in ("revolute", "continuous"):
                    axis = np.asarray(joint.axis, dtype=float)
                    self._moving.append(
                        (
                            frame,
                            names.index(joint.name),
                            joint.origin[:3, :3].copy(),
                            axis / np.linalg.norm(axis),
                        )
                    )
        self._fast = len(self._moving) == len(names)
        self._q: np.ndarray | None = None

    def update(self, q: np.ndarray) -> None:
        if not self._fast or self._q is None:
            self._viser_urdf.update_cfg(q)  # the first call places every frame
            self._q = q.copy()
            return
        for frame, i, R_origin, axis in self._moving:
            if q[i] != self._q[i]:
                frame.wxyz = quaternion_from_matrix(R_origin @ rotation_about(axis, q[i]))
        self._q = q.copy()
