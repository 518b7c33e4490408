"""Robot stiffness, deformation compensation and iterative learning control (issue 5).

Joint-stiffness model (linear and non-linear), its identification from CMM measurements,
gravity compensation of the F/T sensor, online and offline deformation compensation.
"""

from .compensation import OnlineCompensationParams as OnlineCompensationParams
from .compensation import OnlineCompensationState as OnlineCompensationState
from .compensation import compensate_targets as compensate_targets
from .compensation import compensate_targets_and_joints as compensate_targets_and_joints
from .compensation import online_compensation_step as online_compensation_step
from .errors import ConvergenceError as ConvergenceError
from .errors import IdentificationError as IdentificationError
from .errors import SettingsFileError as SettingsFileError
from .errors import UnknownStudyError as UnknownStudyError
from .gravity import ToolGravity as ToolGravity
from .gravity import calibration_joints as calibration_joints
from .gravity import compensate_gravity as compensate_gravity
from .gravity import identify_tool_gravity as identify_tool_gravity
from .gravity import simulate_sensor_readings as simulate_sensor_readings
from .gravity import wrench_at_tcp_in_base as wrench_at_tcp_in_base
from .gravity import wrench_in_tool_frame as wrench_in_tool_frame
from .identification import StiffnessIdentification as StiffnessIdentification
from .identification import StiffnessMeasurements as StiffnessMeasurements
from .identification import identify_joint_stiffness as identify_joint_stiffness
from .identification import prediction_errors as prediction_errors
from .identification import sample_workspace_joints as sample_workspace_joints
from .identification import simulate_stiffness_measurements as simulate_stiffness_measurements
from .identification import sphere_tip_transform as sphere_tip_transform
from .model import LoadedEquilibrium as LoadedEquilibrium
from .model import cartesian_compliance as cartesian_compliance
from .model import equilibrium_at_pose as equilibrium_at_pose
from .model import linear_deflection as linear_deflection
from .model import loaded_cartesian_compliance as loaded_cartesian_compliance
from .model import loaded_equilibrium as loaded_equilibrium
