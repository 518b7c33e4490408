"""Robot stiffness, deformation compensation and iterative learning control (issue 5).

Joint-stiffness model (linear and non-linear), its identification from CMM measurements,
gravity compensation of the F/T sensor, online and offline deformation compensation, milling
simulations, iterative learning control, settings JSON and the study runners.
"""

from ..cell import ToolGravity as ToolGravity
from ..cell import compensate_gravity as compensate_gravity
from ..cell import wrench_at_tcp_in_base as wrench_at_tcp_in_base
from ..cell import wrench_in_tool_frame as wrench_in_tool_frame
from .compensation import OnlineCompensationParams as OnlineCompensationParams
from .compensation import OnlineCompensationState as OnlineCompensationState
from .compensation import compensate_targets as compensate_targets
from .compensation import compensate_targets_and_joints as compensate_targets_and_joints
from .compensation import online_compensation_step as online_compensation_step
from .errors import ConvergenceError as ConvergenceError
from .errors import IdentificationError as IdentificationError
from .errors import SettingsFileError as SettingsFileError
from .errors import UnknownStudyError as UnknownStudyError
from .export import compensated_rapid_program as compensated_rapid_program
from .gravity import calibration_joints as calibration_joints
from .gravity import identify_tool_gravity as identify_tool_gravity
from .gravity import simulate_sensor_readings as simulate_sensor_readings
from .identification import StiffnessIdentification as StiffnessIdentification
from .identification import StiffnessMeasurements as StiffnessMeasurements
from .identification import identify_joint_stiffness as identify_joint_stiffness
from .identification import prediction_errors as prediction_errors
from .identification import sample_workspace_joints as sample_workspace_joints
from .identification import simulate_stiffness_measurements as simulate_stiffness_measurements
from .identification import sphere_tip_transform as sphere_tip_transform
from .ilc import IlcResult as IlcResult
from .ilc import IlcSystem as IlcSystem
from .ilc import ilc_update as ilc_update
from .ilc import milling_process_gain as milling_process_gain
from .ilc import run_ilc as run_ilc
from .ilc import simulate_ilc_run as simulate_ilc_run
from .ilc import square_path as square_path
from .milling import CHAPTER_END_MILLING as CHAPTER_END_MILLING
from .milling import LUND_FACE_MILLING as LUND_FACE_MILLING
from .milling import MillingRun as MillingRun
from .milling import MillingScenario as MillingScenario
from .milling import simulate_milling as simulate_milling
from .model import LoadedEquilibrium as LoadedEquilibrium
from .model import cartesian_compliance as cartesian_compliance
from .model import equilibrium_at_pose as equilibrium_at_pose
from .model import linear_deflection as linear_deflection
from .model import loaded_cartesian_compliance as loaded_cartesian_compliance
from .model import loaded_equilibrium as loaded_equilibrium
from .modes import COMPENSATIONS as COMPENSATIONS
from .modes import OFFLINE_MODELS as OFFLINE_MODELS
from .modes import Compensation as Compensation
from .modes import OfflineModel as OfflineModel
from .modes import read_compensation as read_compensation
from .settings import CompensationSettings as CompensationSettings
from .settings import load_settings as load_settings
from .settings import save_settings as save_settings
from .studies import StudyOptions as StudyOptions
from .studies import StudyResult as StudyResult
from .studies import run_gravity_study as run_gravity_study
from .studies import run_identification_study as run_identification_study
from .studies import run_ilc_study as run_ilc_study
from .studies import run_milling_study as run_milling_study
from .studies import run_studies as run_studies
