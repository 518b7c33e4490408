"""Robot arm definitions built from published kinematics (example-robot-data has no ABB arm)."""

from .abb import ABB_ARMS as ABB_ARMS
from .abb import IRB4400 as IRB4400
from .abb import IRB6640 as IRB6640
from .abb import ArmSpec as ArmSpec
from .abb import arm_spec as arm_spec
from .abb import controller_axes_deg as controller_axes_deg
from .abb import urdf_path as urdf_path
from .abb import urdf_text as urdf_text
