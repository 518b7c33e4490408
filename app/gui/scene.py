"""The workbench's 3D scene: robot, tool, workpiece, TCP frame, force arrows, guide points, paths.

Scene paths follow the cell: ``/robot/...`` (URDF meshes, ``tcp`` carrying ``tcp/tool``,
``force``, ``push``, ``handle``), ``/workpiece``, ``/wobj``, ``/table``, ``/calibration``,
``/path/picked``, and the paths drawn over the cell (``paths``): ``/path/guide_points``,
``/path/samples`` (``raw``, ``filtered``), ``/path/targets``, ``/path/proposal`` and
``/path/comparison``. Everything is in the robot base frame, metres. The robot is drawn at the
motor-side joints (what the controller knows); the tool hangs on the TCP frame.

``CellScene`` draws the cell and keeps it up to date; ``CellScene.paths`` (``paths.ScenePaths``)
draws the paths. How the arm and the tool are built is in ``arm``, where the camera stands in
``camera``, the colours in ``colors``.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from typing import cast

import numpy as np
import trimesh
import viser
from viser.extras import ViserUrdf

from robomach_core.cell import Tool
from robomach_core.part import Workpiece
from robomach_core.transforms import quaternion_from_matrix

from .arm import RobotPose, cutter_mesh, load_urdf, tool_mesh
from .camera import part_view_pose, top_view_pose
from .colors import (
    CONTACT_COLOR,
    CUTTER_COLOR,
    FIT_COLOR,
    OTHER_WALL_COLOR,
    PICKED_WALL_COLOR,
    PUSH_COLOR,
    TABLE_COLOR,
    TOOL_COLOR,
    TOUCH_COLOR,
    WORKPIECE_COLOR,
    deviation_colors,
)
from .paths import ScenePaths

FORCE_ARROW_M_PER_N = 0.002  # 10 N draws a 20 mm arrow: beside a 1 mm cutter, not over the part
FORCE_ARROW_MAX_M = 0.04  # a 60 N spike stays a 40 mm arrow
ARROW_MIN_N = 1.0  # weaker forces draw no arrow (noise; path learning's contact flag is 1 N)
SPINDLE_OPACITY = 0.3
HANDLE_SCALE = 0.05  # the push handle: small, beside the tool rather than over it
WOBJ_AXES_M = 0.05
PICKED_ARROW_M = 0.008  # from the picked wall to the side the tool stands on
TOUCH_ARROW_M = 0.008  # the arrow of a touch's move, ending at the ball
CALIBRATION_SCALE_M = 0.2e-3  # a touch's residual: green at 0, red from 0.2 mm
TABLE_MARGIN_M = 0.08  # the table reaches this far beyond the part
TABLE_STAND_FROM_M = 0.05  # a part this high stands on a stand from the floor
TABLE_PLATE_M = 0.02  # else a plate this thick
TABLE_GAP_M = 0.0002  # the table's top just under the part's bottom (no flicker)


def _labelled_arrow(scene, name: str, color: tuple[int, int, int], anchor: str) -> tuple:
    """A hidden arrow at ``/robot/{name}`` and its hidden label (the contact force, the push)."""
    arrow = scene.add_arrows(
        f"/robot/{name}",
        np.zeros((1, 2, 3)),
        color,
        shaft_radius=0.002,
        head_radius=0.005,
        head_length=0.01,
        visible=False,
    )
    return arrow, scene.add_label(f"/robot/{name}/label", "", anchor=anchor, visible=False)


class CellScene:
    """Scene nodes of the cell, updated from the session's state.

    Args:
        server: The viser server.
    """

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.paths = ScenePaths(server)
        self._lock = threading.Lock()
        self._urdf: ViserUrdf | None = None
        self._urdf_model = None  # its yourdfpy URDF (the arm's meshes), read by ``arm_mesh``
        self._pose: RobotPose | None = None
        self._robot_name = ""
        self._last_joints = np.full(6, np.nan)
        scene = server.scene
        scene.set_up_direction("+z")
        scene.add_grid("/grid", width=2.0, height=2.0, cell_size=0.1, section_size=0.5)
        self.robot_root = scene.add_frame("/robot", show_axes=False)
        self.tcp = scene.add_frame("/robot/tcp", axes_length=0.03, axes_radius=0.0015)
        self.tool = scene.add_frame("/robot/tcp/tool", show_axes=False)
        self.force, self.force_label = _labelled_arrow(scene, "force", CONTACT_COLOR, "bottom-left")
        self.push, self.push_label = _labelled_arrow(scene, "push", PUSH_COLOR, "top-left")
        self.handle = scene.add_transform_controls(
            "/robot/handle",
            scale=HANDLE_SCALE,
            disable_rotations=True,
            depth_test=False,
        )
        self.workpiece_node: viser.SceneNodeHandle | None = None
        self.placement_previewed = False  # the part is drawn where a placement is being tried
        # Clicks are the scene's (anywhere on the canvas), met against the part's mesh here:
        # nothing drawn in front of the part takes them (``on_part_click``).
        scene.on_click()(self._scene_clicked)

    # ----------------------------------------------------------------- cell set-up

    def set_robot(self, robot: str) -> None:
        """Load and show the URDF of ``robot`` (``"ur10"``, ``"ur5"``, ``"ur3"``)."""
        if robot == self._robot_name and self._urdf is not None:
            return
        urdf = load_urdf(robot)
        with self._lock:
            if self._urdf is not None:
                self._urdf.remove()
            self._urdf = ViserUrdf(self.server, urdf, root_node_name="/robot")
            self._urdf_model = urdf
            self._pose = RobotPose(self._urdf, urdf)
            self._robot_name = robot
            self._last_joints = np.full(6, np.nan)

    def set_tool(self, tool: Tool) -> None:
        """Draw the spindle and cutter of ``tool`` on the TCP."""
        body = tool_mesh(tool)
        self._tool_body = body
        cutter = cutter_mesh(tool)
        with self.server.atomic():
            self.server.scene.add_mesh_simple(
                "/robot/tcp/tool/body",
                body.vertices,
                body.faces,
                color=TOOL_COLOR,
                opacity=SPINDLE_OPACITY,  # the 1 mm ball stays visible through it
            )
            self.server.scene.add_mesh_simple(
                "/robot/tcp/tool/cutter", cutter.vertices, cutter.faces, color=CUTTER_COLOR
            )

    def set_workpiece(self, workpiece: Workpiece) -> None:
        """Show the workpiece mesh (as its CAD: what the user teaches on) at its place in the
        base frame, with its work-object frame and coordinates, and the table it stands on.

        The mesh is drawn in its work-object frame under a node placed at ``T_base_wobj``, so
        that a placement being tried (``preview_placement``) moves the part without sending
        its mesh again."""
        cad = workpiece.cad()
        self._cad_mesh = cad.mesh  # work-object frame: what a click's ray is met against
        self._T_base_wobj = cad.T_base_wobj.copy()
        self.workpiece_node = self.server.scene.add_mesh_simple(
            "/workpiece",
            cad.mesh.vertices,
            cad.mesh.faces,
            color=WORKPIECE_COLOR,
            flat_shading=True,
            side="double",
            wxyz=quaternion_from_matrix(cad.T_base_wobj[:3, :3]),
            position=cad.T_base_wobj[:3, 3],
        )
        self.placement_previewed = False
        self._show_wobj_frame(cad.T_base_wobj)
        self._show_table(cad.mesh_in_base())
        self.set_picked_wall(None)

    def preview_placement(self, T_base_wobj: np.ndarray | None) -> None:
        """Draw the part (and its work-object frame and table) at ``T_base_wobj`` while a
        placement is being tried; None puts it back where the cell has it."""
        T = self._T_base_wobj if T_base_wobj is None else np.asarray(T_base_wobj, dtype=float)
        node = self.workpiece_node
        if node is None:
            return
        with self.server.atomic():
            node.wxyz = quaternion_from_matrix(T[:3, :3])
            node.position = T[:3, 3]
            self._show_wobj_frame(T, preview=T_base_wobj is not None)
            mesh = self._cad_mesh.copy()
            mesh.apply_transform(T)
            self._show_table(mesh)
        self.placement_previewed = T_base_wobj is not None

    def _show_table(self, part_in_base: trimesh.Trimesh) -> None:
        """The table the part stands on (the supervision's table plane is the part's lowest
        point): a stand from the floor when the part is raised, else a thin plate."""
        lo, hi = part_in_base.bounds
        top = float(lo[2])
        bottom = 0.0 if top > TABLE_STAND_FROM_M else top - TABLE_PLATE_M
        size = np.array([*(hi[:2] - lo[:2] + 2 * TABLE_MARGIN_M), max(top - bottom, 1e-3)])
        centre = np.array([*(0.5 * (lo[:2] + hi[:2])), 0.5 * (top + bottom)])
        self.server.scene.add_box(
            "/table",
            color=TABLE_COLOR,
            dimensions=tuple(size),
            position=tuple(centre - np.array([0.0, 0.0, TABLE_GAP_M])),
            cast_shadow=False,
            receive_shadow=True,
        )

    def _show_wobj_frame(self, T_base_wobj: np.ndarray, *, preview: bool = False) -> None:
        """The work-object frame (axes at its origin) and its coordinates in the base frame."""
        x, y, z = T_base_wobj[:3, 3] * 1e3
        text = f"work object ({x:.0f}, {y:.0f}, {z:.0f}) mm"
        with self.server.atomic():
            self.server.scene.add_frame(
                "/wobj",
                wxyz=quaternion_from_matrix(T_base_wobj[:3, :3]),
                position=T_base_wobj[:3, 3],
                axes_length=WOBJ_AXES_M,
                axes_radius=0.0012,
            )
            self.server.scene.add_label(
                "/wobj/label",
                f"{text}: not placed yet" if preview else text,
                position=(0.0, 0.0, 0.004),
                anchor="bottom-left",
            )

    # ----------------------------------------------------------------- pointing at the part

    def on_part_click(self, callback) -> None:
        """Call ``callback(point_wobj_m, normal_wobj, client)`` when the user clicks the part
        (the first surface the click's ray meets, and its normal, in the work-object frame).

        The click is the scene's, not the part node's: its ray is met against the part's mesh
        here, so the robot, the translucent spindle, labels and arrows between the camera and
        the part never take a click meant for it."""
        self._click_callback = callback

    def hit_part(
        self, origin: np.ndarray, direction: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """(point, normal) in the work-object frame where a base-frame ray meets the part."""
        mesh = getattr(self, "_cad_mesh", None)
        if mesh is None or self.placement_previewed:
            return None  # the part drawn is not where the cell has it
        from robomach_core.part.mesh_query import ray_hits

        T = self._T_base_wobj
        o = (np.asarray(origin, dtype=float) - T[:3, 3]) @ T[:3, :3]
        d = np.asarray(direction, dtype=float) @ T[:3, :3]
        hits, _, faces = ray_hits(mesh, o[None, :], d[None, :])
        if len(hits) == 0:
            return None
        k = int(np.argmin(np.linalg.norm(hits - o, axis=1)))
        return hits[k], np.asarray(mesh.face_normals[faces[k]], dtype=float)

    def _scene_clicked(self, event) -> None:
        callback = getattr(self, "_click_callback", None)
        if callback is None:
            return
        hit = self.hit_part(np.asarray(event.ray_origin), np.asarray(event.ray_direction))
        if hit is not None:
            callback(hit[0], hit[1], event.client)

    def set_picked_wall(self, pick, text: str = "") -> None:
        """Highlight the wall a click picked (``walls.WallPick``), before anything moves: the
        wall at the machining height (thick), the other walls there (thin grey: the groove's
        other side), the clicked point and an arrow to the side the tool stands on; None
        removes it."""
        scene = self.server.scene
        with self.server.atomic():
            node = getattr(self, "_picked_node", None)
            if node is not None:
                node.remove()
            self._picked_node = scene.add_frame("/path/picked", show_axes=False)
            if pick is None:
                return
            T = self._T_base_wobj @ pick.T_wobj_floor

            def base(loop) -> np.ndarray:
                xy = np.asarray(loop.points_m, dtype=float)
                if loop.closed:
                    xy = np.vstack([xy, xy[:1]])
                p = np.column_stack([xy, np.full(len(xy), loop.z_m)])
                return p @ T[:3, :3].T + T[:3, 3]

            wall = base(pick.loop)
            scene.add_line_segments(
                "/path/picked/wall", np.stack([wall[:-1], wall[1:]], axis=1), PICKED_WALL_COLOR,
                thickness=5.0, thickness_units="screen",
            )  # fmt: skip
            for k, other in enumerate(pick.others):
                w = base(other)
                scene.add_line_segments(
                    f"/path/picked/other{k}", np.stack([w[:-1], w[1:]], axis=1),
                    OTHER_WALL_COLOR, thickness=1.5, thickness_units="screen",
                )  # fmt: skip
            s = np.array([pick.s_m])
            foot = np.array([*pick.loop.point_at(s)[0], pick.loop.z_m])
            free = np.array([*pick.loop.free_normal_at(s)[0], 0.0])
            at = T[:3, :3] @ foot + T[:3, 3]
            tip = at + T[:3, :3] @ free * PICKED_ARROW_M
            scene.add_arrows(
                "/path/picked/side", np.array([[at, tip]]), PICKED_WALL_COLOR,
                shaft_radius=0.0008, head_radius=0.002, head_length=0.003,
            )  # fmt: skip
            scene.add_icosphere(
                "/path/picked/point", radius=0.0015, color=PICKED_WALL_COLOR,
                position=tuple(self._T_base_wobj[:3, :3] @ pick.point_m
                               + self._T_base_wobj[:3, 3]),
            )  # fmt: skip
            scene.add_label(
                "/path/picked/label", text or "the wall you clicked",
                position=tuple(tip + np.array([0.0, 0.0, 0.006])), anchor="bottom-center",
            )  # fmt: skip

    def set_calibration(
        self,
        touches: Sequence,
        residuals_m: np.ndarray | None = None,
        T_fit: np.ndarray | None = None,
        *,
        labelled: bool = True,
    ) -> None:
        """The touches of a work-object calibration (``registration.Touch``: the ball where it
        stopped, an arrow along its move, "T1" with its residual once fitted unless not
        ``labelled`` (accepted: the labels would crowd the teaching; the panel lists them),
        coloured green to red at ``CALIBRATION_SCALE_M``) and, before it is accepted, the CAD
        where the fit places it (translucent green: where the part really is); nothing for no
        touches."""
        scene = self.server.scene
        with self.server.atomic():
            node = getattr(self, "_calibration_node", None)
            if node is not None:
                node.remove()
            self._calibration_node = scene.add_frame("/calibration", show_axes=False)
            for k, touch in enumerate(touches):
                at = np.asarray(touch.tcp_m, dtype=float)
                d = np.asarray(touch.direction, dtype=float)
                res = None if residuals_m is None else float(residuals_m[k])
                color = TOUCH_COLOR
                if res is not None:
                    r, g, b = deviation_colors(np.array([abs(res)]), CALIBRATION_SCALE_M)[0]
                    color = (int(r), int(g), int(b))
                scene.add_icosphere(
                    f"/calibration/T{k + 1}", radius=max(touch.tool_radius_m, 5e-4), color=color,
                    position=tuple(at),
                )  # fmt: skip
                scene.add_arrows(
                    f"/calibration/T{k + 1}/move",
                    np.array([[-d * TOUCH_ARROW_M, -d * touch.tool_radius_m]]),
                    color, shaft_radius=0.0005, head_radius=0.0012, head_length=0.002,
                )  # fmt: skip
                text = f"T{k + 1}" if res is None else f"T{k + 1} {res * 1e3:+.2f} mm"
                if not labelled:
                    continue
                scene.add_label(
                    f"/calibration/T{k + 1}/label", text,
                    position=tuple(-d * TOUCH_ARROW_M + np.array([0.0, 0.0, 0.002])),
                    anchor="bottom-center",
                )  # fmt: skip
            mesh = getattr(self, "_cad_mesh", None)
            if T_fit is not None and mesh is not None:
                scene.add_mesh_simple(
                    "/calibration/fit", mesh.vertices, mesh.faces, color=FIT_COLOR,
                    opacity=0.35, flat_shading=True, side="double", cast_shadow=False,
                    wxyz=quaternion_from_matrix(T_fit[:3, :3]), position=T_fit[:3, 3],
                )  # fmt: skip

    # ----------------------------------------------------------------- camera

    def top_view(self, client, workpiece: Workpiece) -> None:
        """Put ``client``'s camera straight above the part, looking down, the whole part in
        view (x to the right, y up)."""
        bounds = workpiece.cad().mesh_in_base().bounds
        fov = float(getattr(client.camera, "fov", math.radians(50.0)))
        eye, look_at = top_view_pose(bounds, fov)
        with client.atomic():
            client.camera.up_direction = (0.0, 1.0, 0.0)
            client.camera.position = tuple(float(v) for v in eye)
            client.camera.look_at = tuple(float(v) for v in look_at)

    def part_view(
        self,
        client,
        workpiece: Workpiece,
        joints_rad: np.ndarray | None = None,
        T_base_tcp: np.ndarray | None = None,
    ) -> None:
        """Frame the whole part from where the arm (at ``joints_rad``, its tool at
        ``T_base_tcp``) hides none of it (``part_view_pose``), looking down at its walls."""
        bounds = workpiece.cad().mesh_in_base().bounds
        fov = float(getattr(client.camera, "fov", math.radians(50.0)))
        arm = None if joints_rad is None else self.arm_mesh(joints_rad, T_base_tcp)
        eye, centre = part_view_pose(bounds, fov, arm)
        with client.atomic():
            client.camera.up_direction = (0.0, 0.0, 1.0)
            client.camera.position = tuple(float(v) for v in eye)
            client.camera.look_at = tuple(float(v) for v in centre)

    def arm_mesh(self, joints_rad: np.ndarray, T_base_tcp: np.ndarray | None) -> trimesh.Trimesh:
        """The arm as drawn at ``joints_rad`` (its visual meshes) with the spindle on its TCP,
        base frame: what may stand between the camera and the part.

        Posed on the drawn arm's own URDF, under the scene's lock: the drawing turns its
        frames without that URDF's configuration (``RobotPose``), and sets it whole where it
        does use it, so posing it here draws nothing. A URDF of its own cost a second load of
        the arm's meshes at each change of arm (0.3 s of the cell change)."""
        q = np.asarray(joints_rad, dtype=float)
        with self._lock:
            urdf = self._urdf_model
            if urdf is None:
                raise RuntimeError("no arm drawn yet (set_robot)")
            urdf.update_cfg(q)
            parts = [urdf.scene.to_mesh()]
        body = getattr(self, "_tool_body", None)
        if body is not None and T_base_tcp is not None:
            parts.append(body.copy().apply_transform(np.asarray(T_base_tcp, dtype=float)))
        # trimesh annotates concatenate as returning any Geometry: meshes in, it is a Trimesh.
        return cast(trimesh.Trimesh, trimesh.util.concatenate(parts))

    # ----------------------------------------------------------------- live state

    def update_robot(
        self,
        joints_rad: np.ndarray,
        T_base_tcp: np.ndarray,
        force_N: np.ndarray,
        push_N: np.ndarray | None = None,
    ) -> None:
        """Move the robot, the tool and the TCP frame; redraw the contact and push arrows.

        Args:
            joints_rad: (6,) motor-side joints.
            T_base_tcp: 4x4 TCP pose.
            force_N: (3,) measured contact force on the tool, base axes.
            push_N: (3,) virtual push force, base axes (None hides the arrow).
        """
        p = T_base_tcp[:3, 3]
        wxyz = quaternion_from_matrix(T_base_tcp[:3, :3])
        with self.server.atomic():
            if self._pose is not None and not np.array_equal(joints_rad, self._last_joints):
                with self._lock:
                    self._pose.update(np.asarray(joints_rad, dtype=float))
                self._last_joints = np.array(joints_rad, dtype=float)
            self.tcp.position = p
            self.tcp.wxyz = wxyz
            self._arrow(self.force, self.force_label, p, force_N, "contact")
            self._arrow(self.push, self.push_label, p, push_N, "push")

    @staticmethod
    def _arrow(
        arrow: viser.ArrowsHandle,
        label: viser.LabelHandle,
        origin: np.ndarray,
        force_N: np.ndarray | None,
        what: str,
    ) -> None:
        magnitude = 0.0 if force_N is None else float(np.linalg.norm(force_N))
        if magnitude < ARROW_MIN_N:
            if arrow.visible:
                arrow.visible = False
                label.visible = False
            return
        length = min(magnitude * FORCE_ARROW_M_PER_N, FORCE_ARROW_MAX_M)
        tip = origin + np.asarray(force_N) / magnitude * length
        arrow.points = np.array([[origin, tip]], dtype=np.float32)
        label.position = tip
        label.text = f"{what} {magnitude:.1f} N"
        if not arrow.visible:
            arrow.visible = True
            label.visible = True

    def handle_to(self, position_m: np.ndarray) -> None:
        """Put the push handle at ``position_m`` (no message when it is already there)."""
        p = np.asarray(position_m, dtype=float)
        if not np.allclose(self.handle.position, p, rtol=0.0, atol=1e-6):
            self.handle.position = p
