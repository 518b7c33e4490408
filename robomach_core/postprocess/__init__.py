"""Post-processing of a path-learning recording into a program's path (chapter section 3.3).

``postprocess`` filters the samples by the force band, reduces them by deviation height to the
program's ``Targets`` and sets their speeds by curvature (``targets``); ``arc_targets`` fits
circular moves where the contour is an arc within the tolerance and gives the ``Move`` sequence
every program language emits (``arcs``).
"""

from .arcs import Move as Move
from .arcs import arc_targets as arc_targets
from .arcs import linear_moves as linear_moves
from .arcs import sample_moves as sample_moves
from .arcs import validate_moves as validate_moves
from .targets import PostprocessResult as PostprocessResult
from .targets import PostprocessSettings as PostprocessSettings
from .targets import Targets as Targets
from .targets import curvature_along as curvature_along
from .targets import loop_ridge_m as loop_ridge_m
from .targets import postprocess as postprocess
from .targets import reduce_deviation_height as reduce_deviation_height
from .targets import speeds_by_curvature as speeds_by_curvature

__all__ = [
    "Move",
    "PostprocessResult",
    "PostprocessSettings",
    "Targets",
    "arc_targets",
    "curvature_along",
    "linear_moves",
    "loop_ridge_m",
    "postprocess",
    "reduce_deviation_height",
    "sample_moves",
    "speeds_by_curvature",
    "validate_moves",
]
