"""The paths drawn over the cell, under ``/path``: guide points, the taught wall, where a run
stopped, the recording and the program's targets, proposed guide points and the learned and
CAD-only programs side by side.

Each is redrawn whole from the session's data when that changes; a drawing whose number of
nodes varies (guide points, a proposal, the comparison) removes its subtree first, so nothing
of the earlier one is left. ``ScenePaths.hide`` hides the results of a cell no longer there.
What is drawn on the part itself (the wall a click picked, a calibration's touches) is the
``CellScene``'s, which knows where the part is.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import viser

from robomach_core.transforms import quaternion_from_matrix

from .colors import (
    COMPARISON_COLORS,
    FILTERED_COLOR,
    GUIDE_COLOR,
    PROPOSAL_LINE_COLOR,
    RAW_COLOR,
    REACH_COLORS,
    SELECTED_GUIDE_COLOR,
    STALE_COLOR,
    STOP_COLOR,
    TARGET_COLOR,
    TAUGHT_WALL_COLOR,
    WALL_COLOR,
    deviation_colors,
)

GUIDE_LABEL_LIFT_M = 0.004  # the "G1" label sits just above its marker


class ScenePaths:
    """Scene nodes of the paths (``CellScene.paths``).

    Args:
        server: The viser server.
    """

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.stale_label: viser.LabelHandle | None = None  # "out of date" at the targets
        self.guide_labels: list[viser.LabelHandle] = []
        self.hidden = False  # the drawn paths belong to a cell no longer there
        self._guides_node: viser.SceneNodeHandle | None = None
        self._proposal_node: viser.FrameHandle | None = None
        self._comparison_node: viser.FrameHandle | None = None

    def set_guide_points(
        self,
        Ts_base_guide: Sequence[np.ndarray],
        *,
        selected: int | None = None,
    ) -> None:
        """Show guide points as small axes with "G1", "G2", ... labels; ``selected`` highlighted."""
        scene = self.server.scene
        with self.server.atomic():
            # Rebuild the subtree: removing the parent removes its axes and labels.
            if self._guides_node is not None:
                self._guides_node.remove()
            self.guide_labels = []
            self._guides_node = scene.add_frame("/path/guide_points", show_axes=False)
            if not len(Ts_base_guide):
                return
            Ts = np.asarray(Ts_base_guide, dtype=float)
            positions = Ts[:, :3, 3]
            colors = np.tile(np.array(GUIDE_COLOR, dtype=np.uint8), (len(Ts), 1))
            if selected is not None and 0 <= selected < len(Ts):
                colors[selected] = SELECTED_GUIDE_COLOR
            scene.add_point_cloud(
                "/path/guide_points/points",
                positions,
                colors,
                point_size=0.006,
                point_shape="circle",
                precision="float32",
            )
            scene.add_batched_axes(
                "/path/guide_points/axes",
                np.array([quaternion_from_matrix(T[:3, :3]) for T in Ts]),
                positions,
                axes_length=0.02,
                axes_radius=0.001,
            )
            for k, p in enumerate(positions):
                # "G1" as in the table, just above its own marker.
                self.guide_labels.append(
                    scene.add_label(
                        f"/path/guide_points/labels/G{k + 1}",
                        f"G{k + 1}",
                        position=p + np.array([0.0, 0.0, GUIDE_LABEL_LIFT_M]),
                        anchor="bottom-center",
                    )
                )

    def set_taught_wall(self, points_m: Sequence[np.ndarray | None], text: str = "") -> None:
        """Highlight the wall the next run will follow: the wall point each guide point faces
        (``wall_side.taught_wall_points``), joined in order, and what decided the side."""
        scene = self.server.scene
        pts = np.array([p for p in points_m if p is not None], dtype=float).reshape(-1, 3)
        with self.server.atomic():
            if len(pts) == 0:
                scene.add_point_cloud(
                    "/path/taught_wall/points",
                    np.zeros((1, 3)),
                    TAUGHT_WALL_COLOR,
                    point_size=0.004,
                    visible=False,
                )
                scene.add_line_segments(
                    "/path/taught_wall/line",
                    np.zeros((1, 2, 3)),
                    TAUGHT_WALL_COLOR,
                    visible=False,
                )
                scene.add_label("/path/taught_wall/label", "", visible=False)
                return
            scene.add_point_cloud(
                "/path/taught_wall/points",
                pts,
                TAUGHT_WALL_COLOR,
                point_size=0.004,
                point_shape="diamond",
            )
            segments = (
                np.stack([pts[:-1], pts[1:]], axis=1) if len(pts) > 1 else np.zeros((1, 2, 3))
            )
            scene.add_line_segments(
                "/path/taught_wall/line",
                segments,
                TAUGHT_WALL_COLOR,
                thickness=0.0012,
                visible=len(pts) > 1,
            )
            scene.add_label(
                "/path/taught_wall/label",
                text,
                # Between the first two wall points, not at G1: G1's, the last point's and the
                # live force's labels already stand there, and each later wall point has its
                # guide point's label beside it.
                position=pts[:2].mean(axis=0) + np.array([0.0, 0.0, 0.012]),
                anchor="bottom-left",
                visible=bool(text),
            )

    def set_stop(self, position_m: np.ndarray | None, text: str = "") -> None:
        """Mark where the last path-learning run stopped early (hidden when it completed)."""
        scene = self.server.scene
        p = np.zeros(3) if position_m is None else np.asarray(position_m, dtype=float)
        with self.server.atomic():
            scene.add_icosphere(
                "/path/stop",
                radius=0.003,
                color=STOP_COLOR,
                position=p,
                visible=position_m is not None,
            )
            scene.add_label(
                "/path/stop/label",
                text,
                position=np.array([0.0, 0.0, 0.008]),
                anchor="bottom-center",
                visible=position_m is not None and bool(text),
            )

    def set_samples(
        self,
        raw_m: np.ndarray | None,
        filtered_m: np.ndarray | None = None,
        targets_m: np.ndarray | None = None,
        *,
        filtered_deviation_m: np.ndarray | None = None,
        targets_deviation_m: np.ndarray | None = None,
        deviation_scale_m: float = 0.5e-3,
        stale: bool = False,
        segments_deviation: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        """Show raw samples (grey), filtered samples (blue, or coloured by deviation) and the
        reduced targets (orange points joined by segments, or coloured by deviation). A
        ``stale`` path (out of date with the project's inputs) is drawn dark grey with an
        "out of date" label at its first target."""
        if stale:
            filtered_deviation_m = targets_deviation_m = None
        self.hidden = False
        scene = self.server.scene
        empty = np.zeros((0, 3))
        with self.server.atomic():
            raw = empty if raw_m is None else np.asarray(raw_m)
            scene.add_point_cloud(
                "/path/samples/raw",
                raw,
                RAW_COLOR,
                point_size=0.0008,
                precision="float32",
                visible=len(raw) > 0,
            )
            filt = empty if filtered_m is None else np.asarray(filtered_m)
            colors = (
                (STALE_COLOR if stale else FILTERED_COLOR)
                if filtered_deviation_m is None
                else deviation_colors(filtered_deviation_m, deviation_scale_m)
            )
            scene.add_point_cloud(
                "/path/samples/filtered",
                filt,
                colors,
                point_size=0.0012,
                precision="float32",
                visible=len(filt) > 0,
            )
            tg = empty if targets_m is None else np.asarray(targets_m)
            tcolor = STALE_COLOR if stale else TARGET_COLOR
            tcolors = (
                np.tile(np.array(tcolor, dtype=np.uint8), (len(tg), 1))
                if targets_deviation_m is None
                else deviation_colors(targets_deviation_m, deviation_scale_m)
            )
            scene.add_point_cloud(
                "/path/targets",
                tg,
                tcolors if len(tg) else tcolor,
                point_size=0.003,
                point_shape="diamond",
                precision="float32",
                visible=len(tg) > 0,
            )
            self.stale_label = scene.add_label(
                "/path/targets/out_of_date",
                "out of date",
                position=tuple(tg[0]) if len(tg) else (0.0, 0.0, 0.0),
                visible=bool(stale and len(tg)),
            )
            if segments_deviation is not None and not stale and len(segments_deviation[0]) >= 2:
                # Coloured along the straight moves by the deviation of points between targets.
                dense, dense_dev = segments_deviation
                dense = np.asarray(dense, dtype=float)
                c = deviation_colors(np.asarray(dense_dev), deviation_scale_m)
                scene.add_line_segments(
                    "/path/targets/segments",
                    np.stack([dense[:-1], dense[1:]], axis=1),
                    np.stack([c[:-1], c[1:]], axis=1),
                    thickness=2.0,
                    thickness_units="screen",
                )
            elif len(tg) >= 2:
                segments = np.stack([tg[:-1], tg[1:]], axis=1)
                seg_colors = np.stack([tcolors[:-1], tcolors[1:]], axis=1)
                scene.add_line_segments(
                    "/path/targets/segments",
                    segments,
                    seg_colors,
                    thickness=2.0,
                    thickness_units="screen",
                )
            else:
                scene.add_line_segments(
                    "/path/targets/segments", np.zeros((1, 2, 3)), TARGET_COLOR, visible=False
                )

    def set_proposal(
        self,
        points_base_m: np.ndarray | None,
        reach: Sequence[str] = (),
        *,
        closed: bool = True,
        wall_base_m: np.ndarray | None = None,
        selected: int | None = None,
    ) -> None:
        """The proposed guide points (coloured by reachability: green, orange near a limit,
        red unreachable; the selected one magenta), the test program through them, the wall
        they follow; None removes them."""
        scene = self.server.scene
        with self.server.atomic():
            node = self._proposal_node
            if node is not None:
                node.remove()
            self._proposal_node = scene.add_frame("/path/proposal", show_axes=False)
            if points_base_m is None or len(points_base_m) == 0:
                return
            pts = np.asarray(points_base_m, dtype=float)
            colors = np.array([REACH_COLORS.get(r, REACH_COLORS["near"]) for r in reach],
                              dtype=np.uint8)  # fmt: skip
            if selected is not None and 0 <= selected < len(pts):
                colors[selected] = SELECTED_GUIDE_COLOR
            scene.add_point_cloud(
                "/path/proposal/points", pts, colors, point_size=0.005, point_shape="diamond",
                precision="float32",
            )  # fmt: skip
            chain = np.vstack([pts, pts[:1]]) if closed else pts
            scene.add_line_segments(
                "/path/proposal/program",
                np.stack([chain[:-1], chain[1:]], axis=1),
                PROPOSAL_LINE_COLOR,
                thickness=1.5,
                thickness_units="screen",
            )
            if wall_base_m is not None and len(wall_base_m) >= 2:
                w = np.asarray(wall_base_m, dtype=float)
                scene.add_line_segments(
                    "/path/proposal/wall", np.stack([w[:-1], w[1:]], axis=1), WALL_COLOR,
                    thickness=2.5, thickness_units="screen",
                )  # fmt: skip
            for k, p in enumerate(pts):
                scene.add_label(
                    f"/path/proposal/labels/P{k + 1}",
                    f"P{k + 1}",
                    position=p + np.array([0.0, 0.0, GUIDE_LABEL_LIFT_M]),
                    anchor="bottom-center",
                )

    def set_comparison(
        self, comparison, *, show_learned: bool = True, show_cad_only: bool = True
    ) -> None:
        """The learned program and the CAD-only one in two colours (``COMPARISON_COLORS``:
        the legend the panels show), each labelled at its worst place with its error against
        the (real) wall; ``show_*`` hides one; None removes them."""
        scene = self.server.scene
        with self.server.atomic():
            node = self._comparison_node
            if node is not None:
                node.remove()
            self._comparison_node = scene.add_frame("/path/comparison", show_axes=False)
            if comparison is None:
                return
            for name, score, title, shown in (
                ("cad_only", comparison.cad_only, "CAD-only", show_cad_only),
                ("learned", comparison.learned, "learned", show_learned),
            ):
                if not shown:
                    continue
                pts = score.points_m[:: max(1, len(score.points_m) // 4000)]
                lift = np.array([0.0, 0.0, 0.0015 if name == "cad_only" else 0.0])
                scene.add_line_segments(
                    f"/path/comparison/{name}",
                    np.stack([pts[:-1] + lift, pts[1:] + lift], axis=1),
                    COMPARISON_COLORS[name],
                    thickness=3.5 if name == "cad_only" else 2.5,
                    thickness_units="screen",
                )
                k = int(np.argmax(np.abs(score.deviation_m)))
                scene.add_label(
                    f"/path/comparison/{name}/worst",
                    f"{title}: max {score.max_m * 1e3:.2f} mm",
                    position=score.points_m[k] + lift + np.array([0.0, 0.0, 0.006]),
                    anchor="bottom-center",
                )

    def hide(self) -> None:
        """Hide the recording, targets and comparison (a result of a cell no longer there)."""
        self.hidden = True
        with self.server.atomic():
            for name in ("/path/samples/raw", "/path/samples/filtered", "/path/targets",
                         "/path/targets/segments"):  # fmt: skip
                self.server.scene.add_point_cloud(
                    name, np.zeros((0, 3)), RAW_COLOR, point_size=0.001, visible=False
                ) if "segments" not in name else self.server.scene.add_line_segments(
                    name, np.zeros((1, 2, 3)), TARGET_COLOR, visible=False
                )
        self.set_comparison(None)
