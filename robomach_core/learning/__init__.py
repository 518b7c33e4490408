"""Path learning (chapter section 3.2), one model: the route planned from the guide points
(``plan_route``: the side, the height, the walk on the mesh), the law that follows the wall by
force (``learn_path``) and the checks before and after. The guide-point planner that proposes
points on a mesh is teaching's (``teaching.pointing``); its thresholds are in the one table.
docs/learning_model.md states the model and every threshold (``thresholds``)."""

from .checks import TaughtWallCheck as TaughtWallCheck
from .checks import guide_point_warnings as guide_point_warnings
from .checks import taught_wall_check as taught_wall_check
from .findings import GuideWarning as GuideWarning
from .route import LearningRoute as LearningRoute
from .route import WallSideDecision as WallSideDecision
from .route import plan_route as plan_route
from .run import LearningStop as LearningStop
from .run import Recording as Recording
from .run import learn_path as learn_path
from .settings import WALL_SIDE_CHOICES as WALL_SIDE_CHOICES
from .settings import PathLearningSettings as PathLearningSettings
from .settings import WallSideSetting as WallSideSetting
