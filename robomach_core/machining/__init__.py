"""The learned program meets the cut: stock, the simulated machining run, and comparisons.

Build a stock (``builtin_stock``, ``stock_from_profile``, ``stock_from_mesh``), cut it with
``run_machining(robot, targets, wall_normals_m, stock, settings)`` and compare feed controllers
and compensation modes with ``compare_configurations``.
"""

from .compare import Comparison as Comparison
from .compare import compare_configurations as compare_configurations
from .compare import format_table as format_table
from .compare import table_notes as table_notes
from .compare import write_run_csv as write_run_csv
from .errors import MachiningSettingsError as MachiningSettingsError
from .errors import SampleLimitError as SampleLimitError
from .errors import StockError as StockError
from .path import targets_along_wall as targets_along_wall
from .path import wall_normals_for_workpiece as wall_normals_for_workpiece
from .path import wall_normals_from_path as wall_normals_from_path
from .plots import plot_runs as plot_runs
from .run import FinishedWall as FinishedWall
from .run import MachiningRun as MachiningRun
from .run import MachiningTrace as MachiningTrace
from .run import identify_stiffness as identify_stiffness
from .run import run_machining as run_machining
from .run import stiffness_model as stiffness_model
from .settings import MACHINING_CONTROLLERS as MACHINING_CONTROLLERS
from .settings import STAGE_PLANS as STAGE_PLANS
from .settings import MachiningSettings as MachiningSettings
from .settings import settings_to_dict as settings_to_dict
from .stock import Burr as Burr
from .stock import Stock as Stock
from .stock import builtin_stock as builtin_stock
from .stock import stock_from_mesh as stock_from_mesh
from .stock import stock_from_profile as stock_from_profile
