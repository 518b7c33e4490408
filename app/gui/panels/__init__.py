"""Workbench panels: one small class per folder of the GUI sidebar."""

from .cell import CellPanel as CellPanel
from .export import ExportPanel as ExportPanel
from .guide_points import GuidePointsPanel as GuidePointsPanel
from .leadthrough import LeadThroughPanel as LeadThroughPanel
from .path_learning import PathLearningPanel as PathLearningPanel
from .postprocess import PostprocessPanel as PostprocessPanel
