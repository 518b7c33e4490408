"""CMRR feed controllers: constant feed, fixed and self-tuning PI, Mamdani fuzzy, two-stage,
and the Lund adaptive LQ. ``make_controller(settings, design)`` builds one from its settings."""

from __future__ import annotations

from typing import Union, get_args

from ..errors import UnknownControllerError
from .adaptive_lq import AdaptiveLqController as AdaptiveLqController
from .adaptive_lq import AdaptiveLqSettings as AdaptiveLqSettings
from .base import ControlDesign as ControlDesign
from .base import Controller as Controller
from .base import ControlOutput as ControlOutput
from .base import Measurement as Measurement
from .constant import ConstantController as ConstantController
from .constant import ConstantSettings as ConstantSettings
from .fuzzy import RULE_BASE as RULE_BASE
from .fuzzy import FuzzyController as FuzzyController
from .fuzzy import FuzzySettings as FuzzySettings
from .fuzzy import TwoStageSettings as TwoStageSettings
from .pi import DESIGN_LOOP_GAIN as DESIGN_LOOP_GAIN
from .pi import PI_ZERO_RAD_S as PI_ZERO_RAD_S
from .pi import AdaptivePiController as AdaptivePiController
from .pi import AdaptivePiSettings as AdaptivePiSettings
from .pi import FixedPiController as FixedPiController
from .pi import FixedPiSettings as FixedPiSettings
from .pi import pi_gains as pi_gains
from .rls import PowerLawEstimator as PowerLawEstimator
from .rls import RlsState as RlsState
from .rls import rls_update as rls_update

ControllerSettings = Union[  # noqa: UP007 (a runtime alias; get_args reads it)
    ConstantSettings,
    FixedPiSettings,
    AdaptivePiSettings,
    FuzzySettings,
    TwoStageSettings,
    AdaptiveLqSettings,
]

SETTINGS_CLASSES: dict[str, type] = {
    cls.__dataclass_fields__["kind"].default: cls for cls in get_args(ControllerSettings)
}
CONTROLLER_CLASSES: dict[str, type] = {
    "constant": ConstantController,
    "fixed-pi": FixedPiController,
    "adaptive-pi": AdaptivePiController,
    "fuzzy": FuzzyController,
    "two-stage": FuzzyController,
    "adaptive-lq": AdaptiveLqController,
}
CONTROLLER_NAMES: tuple[str, ...] = tuple(SETTINGS_CLASSES)


def settings_for(name: str) -> ControllerSettings:
    """Default settings of the named controller."""
    try:
        return SETTINGS_CLASSES[name]()
    except KeyError:
        raise UnknownControllerError(
            f"unknown CMRR controller {name!r}; choose one of {', '.join(CONTROLLER_NAMES)}"
        ) from None


def make_controller(settings: ControllerSettings, design: ControlDesign) -> Controller:
    """The controller for these settings, designed for this cut."""
    return CONTROLLER_CLASSES[settings.kind](settings, design)
