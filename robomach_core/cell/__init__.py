"""The simulated cell and its controller: the robot, the tool on its F/T sensor, the contact with
the part, the arm's hidden compliance, the 4 ms clock, the supervisor of every motion and the
lead-through (admittance) mode a person teaches in.

``Cell`` (``simulator``) steps the whole cell one control period; ``Robot`` gives pinocchio
kinematics; ``LeadThrough`` turns pushes and jogs into motion and records ``GuidePoint``s;
``cell_supervisor`` stops a motion before a joint limit, a singularity, the edge of reach or a
collision. Lead-through sits here rather than in ``teaching`` because path learning follows the
wall in the same controller and keeps its guide points, and teaching sits above learning.
"""

from .clearance import ClearanceProbe as ClearanceProbe
from .clock import CONTROL_PERIOD_S as CONTROL_PERIOD_S
from .clock import zoh as zoh
from .clock import zoh_tf as zoh_tf
from .joint_compliance import JointCompliance as JointCompliance
from .joint_compliance import true_joint_compliance as true_joint_compliance
from .leadthrough import AXES as AXES
from .leadthrough import JOG_SPEED_M_S as JOG_SPEED_M_S
from .leadthrough import ComplianceFrame as ComplianceFrame
from .leadthrough import ComplianceSelection as ComplianceSelection
from .leadthrough import GuidePoint as GuidePoint
from .leadthrough import LeadThrough as LeadThrough
from .leadthrough import LeadThroughState as LeadThroughState
from .leadthrough import halted as halted
from .realtime import RealTimePacer as RealTimePacer
from .robot import HOME_JOINTS_RAD as HOME_JOINTS_RAD
from .robot import ROBOT_NAMES as ROBOT_NAMES
from .robot import ROBOT_URDFS as ROBOT_URDFS
from .robot import Robot as Robot
from .robot import program_language as program_language
from .robot import robots_directory as robots_directory
from .sensor import GRAVITY_M_S2 as GRAVITY_M_S2
from .sensor import ForceEstimator as ForceEstimator
from .sensor import ToolGravity as ToolGravity
from .sensor import compensate_gravity as compensate_gravity
from .sensor import contact_reading as contact_reading
from .sensor import gravity_reading as gravity_reading
from .sensor import wrench_at_tcp_in_base as wrench_at_tcp_in_base
from .sensor import wrench_in_tool_frame as wrench_in_tool_frame
from .simulator import Cell as Cell
from .simulator import CellConfig as CellConfig
from .simulator import CellState as CellState
from .supervision import SHANK_LENGTH_M as SHANK_LENGTH_M
from .supervision import SHANK_RADIUS_FRACTION as SHANK_RADIUS_FRACTION
from .supervision import SPINDLE_RADIUS_M as SPINDLE_RADIUS_M
from .supervision import Supervisor as Supervisor
from .supervision import cell_supervisor as cell_supervisor
from .supervision import forget_supervisor as forget_supervisor
from .tool import TOOL_DOWN as TOOL_DOWN
from .tool import TOOL_RADIUS_RANGE_M as TOOL_RADIUS_RANGE_M
from .tool import Tool as Tool

__all__ = [
    "AXES",
    "CONTROL_PERIOD_S",
    "GRAVITY_M_S2",
    "HOME_JOINTS_RAD",
    "ROBOT_NAMES",
    "ROBOT_URDFS",
    "TOOL_DOWN",
    "TOOL_RADIUS_RANGE_M",
    "Cell",
    "CellConfig",
    "CellState",
    "ClearanceProbe",
    "ComplianceFrame",
    "ComplianceSelection",
    "ForceEstimator",
    "GuidePoint",
    "JointCompliance",
    "JOG_SPEED_M_S",
    "LeadThrough",
    "LeadThroughState",
    "RealTimePacer",
    "Robot",
    "Supervisor",
    "Tool",
    "ToolGravity",
    "cell_supervisor",
    "forget_supervisor",
    "compensate_gravity",
    "contact_reading",
    "gravity_reading",
    "halted",
    "program_language",
    "robots_directory",
    "true_joint_compliance",
    "wrench_at_tcp_in_base",
    "wrench_in_tool_frame",
    "zoh",
    "zoh_tf",
]
