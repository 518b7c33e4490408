"""Controlled material removal rate (CMRR): feed control that holds the cutting force at a
reference (chapter section 4, the MRR paper, and the Lund adaptive LQ).

Run a study with ``run_study(scenario, controller, progress=..., cancel=...)``; write what it
gives with ``write_study_outputs``; export the chosen controller with ``settings_to_dict`` and,
for the RAPID program, ``to_speed_change_settings``.
"""

from .analysis import closed_loop_poles as closed_loop_poles
from .analysis import critical_loop_gain as critical_loop_gain
from .analysis import damping_ratio as damping_ratio
from .analysis import dominant_pole_pair as dominant_pole_pair
from .controllers import CONTROLLER_NAMES as CONTROLLER_NAMES
from .controllers import AdaptiveLqSettings as AdaptiveLqSettings
from .controllers import AdaptivePiSettings as AdaptivePiSettings
from .controllers import ConstantSettings as ConstantSettings
from .controllers import ControlDesign as ControlDesign
from .controllers import ControllerSettings as ControllerSettings
from .controllers import FixedPiSettings as FixedPiSettings
from .controllers import FuzzySettings as FuzzySettings
from .controllers import Measurement as Measurement
from .controllers import PowerLawEstimator as PowerLawEstimator
from .controllers import TwoStageSettings as TwoStageSettings
from .controllers import make_controller as make_controller
from .controllers import settings_for as settings_for
from .depth_profiles import Burr as Burr
from .depth_profiles import PathProfile as PathProfile
from .depth_profiles import burr_depth_profile as burr_depth_profile
from .depth_profiles import depth_along_path as depth_along_path
from .depth_profiles import path_depth_profile as path_depth_profile
from .depth_profiles import random_burrs as random_burrs
from .depth_profiles import step_depth_profile as step_depth_profile
from .depth_profiles import synthetic_burr_block as synthetic_burr_block
from .errors import CmrrSettingsError as CmrrSettingsError
from .errors import MeshDepthError as MeshDepthError
from .errors import UnknownControllerError as UnknownControllerError
from .errors import UnknownScenarioError as UnknownScenarioError
from .feed_dynamics import FeedDynamics as FeedDynamics
from .process import ForceSensorModel as ForceSensorModel
from .process import LundForceModel as LundForceModel
from .process import PowerLawForceModel as PowerLawForceModel
from .process import SpindleCurrentModel as SpindleCurrentModel
from .report import comparison_table as comparison_table
from .report import write_study_outputs as write_study_outputs
from .scenarios import SCENARIO_NAMES as SCENARIO_NAMES
from .scenarios import Scenario as Scenario
from .scenarios import build_scenario as build_scenario
from .settings import CmrrSettings as CmrrSettings
from .settings import cmrr_settings_for as cmrr_settings_for
from .settings import load_settings as load_settings
from .settings import save_settings as save_settings
from .settings import settings_from_dict as settings_from_dict
from .settings import settings_to_dict as settings_to_dict
from .settings import to_speed_change_settings as to_speed_change_settings
from .simulation import StudyResult as StudyResult
from .simulation import StudyTrace as StudyTrace
from .simulation import compare_controllers as compare_controllers
from .simulation import run_study as run_study
