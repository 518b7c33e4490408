"""Program export: ABB RAPID modules and a checker for them."""

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
