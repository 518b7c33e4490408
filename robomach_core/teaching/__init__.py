"""Teaching: how the guide points and the work object come from the operator.

The scripted operator leads the robot to each point by pushes (``operator``: the example
lead-through, a CSV's points, a proposal's points, entered on a part off its CAD); the
supervised motion beside the wall takes the tool to a point taught by a click (``motion``);
touching three or more features of the real part registers its mesh to it before teaching
(``registration`` fits the work object, ``calibration`` plans and runs the guarded touches,
``face_touches`` picks them on a clicked face). The points they record go to path learning
(``robomach_core.learning``); the lead-through controller they push is the cell's
(``robomach_core.cell``).
"""

from .calibration import TOUCH_FORCE_N as TOUCH_FORCE_N
from .calibration import PlannedTouch as PlannedTouch
from .calibration import TouchPlan as TouchPlan
from .calibration import plan_touches as plan_touches
from .calibration import scripted_touches as scripted_touches
from .calibration import touch_at as touch_at
from .face_touches import UP_COS as UP_COS
from .face_touches import face_touch_points as face_touch_points
from .face_touches import touches_for_face as touches_for_face
from .motion import Arrival as Arrival
from .motion import go_to_point as go_to_point
from .motion import move_by as move_by
from .motion import turn_to as turn_to
from .operator import GuideIntent as GuideIntent
from .operator import guide_intents as guide_intents
from .operator import guide_plan as guide_plan
from .operator import intents_from_csv as intents_from_csv
from .operator import robust_intents as robust_intents
from .operator import scripted_leadthrough as scripted_leadthrough
from .registration import MIN_TOUCHES as MIN_TOUCHES
from .registration import CalibrationError as CalibrationError
from .registration import Touch as Touch
from .registration import WobjFit as WobjFit
from .registration import WobjRegistration as WobjRegistration
from .registration import fit_wobj as fit_wobj
from .registration import mm_deg_from_transform as mm_deg_from_transform
from .registration import registered_workpiece as registered_workpiece

__all__ = [
    "MIN_TOUCHES",
    "TOUCH_FORCE_N",
    "UP_COS",
    "Arrival",
    "CalibrationError",
    "GuideIntent",
    "PlannedTouch",
    "Touch",
    "TouchPlan",
    "WobjFit",
    "WobjRegistration",
    "face_touch_points",
    "fit_wobj",
    "go_to_point",
    "guide_intents",
    "guide_plan",
    "intents_from_csv",
    "mm_deg_from_transform",
    "move_by",
    "plan_touches",
    "registered_workpiece",
    "robust_intents",
    "scripted_leadthrough",
    "touch_at",
    "touches_for_face",
    "turn_to",
]
