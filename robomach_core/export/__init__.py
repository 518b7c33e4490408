"""Program export: the registry of program languages (``languages``), ABB RAPID modules,
URScript programs and KUKA KRL pairs, and the project's checkers for RAPID and KRL."""

from .krl_check import KrlProgramInfo as KrlProgramInfo
from .krl_check import KrlSyntaxError as KrlSyntaxError
from .krl_check import check_krl_program as check_krl_program
from .languages import ProgramContext as ProgramContext
from .languages import ProgramLanguage as ProgramLanguage
from .languages import language as language
from .languages import languages_for as languages_for
from .languages import register_language as register_language
from .rapid import ForceControlSettings as ForceControlSettings
from .rapid import RapidProgram as RapidProgram
from .rapid import RapidTarget as RapidTarget
from .rapid import RapidTool as RapidTool
from .rapid import RapidWorkObject as RapidWorkObject
from .rapid import SpeedChangeSettings as SpeedChangeSettings
from .rapid import confdata_from_joints as confdata_from_joints
from .rapid import rapid_identifier as rapid_identifier
from .rapid import rapid_module as rapid_module
from .rapid import rapid_quaternion as rapid_quaternion
from .rapid import write_rapid_module as write_rapid_module
from .rapid_check import RapidModuleInfo as RapidModuleInfo
from .rapid_check import RapidSyntaxError as RapidSyntaxError
from .rapid_check import check_rapid_module as check_rapid_module
