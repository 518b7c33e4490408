"""Constant feed: the baseline a CMRR controller is compared against."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from ..errors import CmrrSettingsError
from .base import ControlDesign, ControlOutput, Measurement


@dataclass(frozen=True)
class ConstantSettings:
    """A fixed speed_ratio (1.0: the programmed speed, no force feedback)."""

    kind: Literal["constant"] = field(default="constant", init=False)
    speed_ratio: float = 1.0

    def __post_init__(self) -> None:
        if not 0.0 < self.speed_ratio <= 1.0:
            raise CmrrSettingsError(
                f"constant speed ratio must be in (0, 1], got {self.speed_ratio}"
            )


@dataclass(frozen=True)
class ConstantController:
    """speed_ratio(t) = const; ignores the force (conventional machining, MRR paper sec. III)."""

    settings: ConstantSettings
    design: ControlDesign
    name: str = "constant"
    estimate_names: tuple[str, ...] = ()

    @property
    def initial_speed_ratio(self) -> float:
        return self.settings.speed_ratio

    def initial_state(self) -> None:
        return None

    def step(self, state: None, measurement: Measurement) -> tuple[None, ControlOutput]:
        return None, ControlOutput(self.settings.speed_ratio)

    def describe(self) -> dict[str, float | str]:
        return {
            "speed_ratio": self.settings.speed_ratio,
            "feed_mm_s": 1e3 * self.settings.speed_ratio * self.design.command_speed_m_s,
        }
