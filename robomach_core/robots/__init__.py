"""Robot arm definitions built from published kinematics (example-robot-data has no ABB or
KUKA arm), the user's own arms (``robots.custom``) and the bounds on a robot file before
pinocchio parses it (``urdf_check``)."""

from .abb import ABB_ARMS as ABB_ARMS
from .abb import IRB2400 as IRB2400
from .abb import IRB4400 as IRB4400
from .abb import IRB6640 as IRB6640
from .abb import ArmSpec as ArmSpec
from .abb import arm_spec as arm_spec
from .abb import urdf_path as urdf_path
from .abb import urdf_text as urdf_text
from .builtin import ARM_FAMILIES as ARM_FAMILIES
from .builtin import GENERATED_ARMS as GENERATED_ARMS
from .builtin import JointCoupling as JointCoupling
from .builtin import controller_axes_deg as controller_axes_deg
from .builtin import joint_couplings as joint_couplings
from .kuka import KR270 as KR270
from .kuka import KUKA_ARMS as KUKA_ARMS
from .kuka import KukaArmSpec as KukaArmSpec
from .urdf_check import open_zip as open_zip
