"""Scores: how far a program's path is from the truth, the product's honesty.

``score_path`` and ``score_moves`` measure the straight or arc program against the true wall of
a built-in part (``true_wall``); ``score_mesh`` measures it against the part's mesh, signed (an
overcut is never a small number), for any part (``mesh_score``); ``compare_with_cad`` scores the
program a CAD/CAM tool would make from the mesh beside the learned one, against the real wall
(``cad_program``). Path learning's own checks call ``mesh_score`` directly: this package sits
above learning, since the CAD-only program is cut from learning's wall sections.
"""

from .cad_program import CadComparison as CadComparison
from .cad_program import compare_with_cad as compare_with_cad
from .mesh_score import mesh_deviation as mesh_deviation
from .mesh_score import score_mesh as score_mesh
from .true_wall import PathScore as PathScore
from .true_wall import score_moves as score_moves
from .true_wall import score_path as score_path
from .true_wall import true_tool_path_distance as true_tool_path_distance

__all__ = [
    "CadComparison",
    "PathScore",
    "compare_with_cad",
    "mesh_deviation",
    "score_mesh",
    "score_moves",
    "score_path",
    "true_tool_path_distance",
]
