"""Supervision of every commanded motion: joint limits, singularities, reach and collisions.

See ``supervisor`` for the model; the compiled per-period arithmetic is in ``_kernels``.
"""

from .supervisor import SHANK_LENGTH_M as SHANK_LENGTH_M
from .supervisor import SHANK_RADIUS_FRACTION as SHANK_RADIUS_FRACTION
from .supervisor import SPINDLE_RADIUS_M as SPINDLE_RADIUS_M
from .supervisor import FixtureBox as FixtureBox
from .supervisor import Supervised as Supervised
from .supervisor import SupervisionCause as SupervisionCause
from .supervisor import SupervisionLimits as SupervisionLimits
from .supervisor import SupervisionStop as SupervisionStop
from .supervisor import Supervisor as Supervisor
from .supervisor import cell_supervisor as cell_supervisor
from .supervisor import forget_supervisor as forget_supervisor
from .supervisor import interpolate_pose as interpolate_pose
