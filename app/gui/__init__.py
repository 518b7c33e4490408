"""The viser workbench: a 3D scene of the cell and one panel per stage of the PbD pipeline."""

from .workbench import Workbench as Workbench
