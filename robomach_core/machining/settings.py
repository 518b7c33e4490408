"""Settings of a machining run: the process, the force limit, the feed control, compensation.

Every field is SI with its unit in the name; ``__post_init__`` checks the physical range and
names it in the message. The process defaults are the chapter's lab fit F = 23 d^0.9 f^0.5
(eq. 6, d in mm, f in mm/s) with the spindle lag tau_m of eq. (3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Literal, get_args

from ..cmrr.controllers import CONTROLLER_NAMES, ControllerSettings
from ..cmrr.process import DEFAULT_TAU_M_S, PowerLawForceModel
from ..limits import (
    CMM_NOISE_UM,
    CMRR_COMMAND_SPEED_MM_S,
    CMRR_MIN_SPEED_RATIO,
    CMRR_REFERENCE_FORCE_N,
    FORCE_FILTER_CUTOFF_HZ,
    MACHINING_AXIAL_ENGAGEMENT_MM,
    MACHINING_DEPTH_EXPONENT,
    MACHINING_FEED_EXPONENT,
    MACHINING_FEED_FORCE_RATIO,
    MACHINING_FORCE_LIMIT_N,
    MACHINING_PATH_ACCELERATION_M_S2,
    MACHINING_PROCESS_GAIN_N,
    MACHINING_SENSOR_NOISE_N,
    MACHINING_STATION_SPACING_MM,
    MACHINING_TARGET_SPACING_MM,
    MACHINING_TIME_CONSTANT_S,
    Range,
)
from ..stiffness.compensation import FORCE_FILTER_CUTOFF_HZ as ONLINE_CUTOFF_HZ
from ..stiffness.modes import COMPENSATIONS, Compensation
from .errors import MachiningSettingsError

MM = 1e-3
# Fr as a share of the force limit when not given: room for the overshoot on a burr's flank.
DEFAULT_REFERENCE_FRACTION = 0.7
# The deepest cut a design may assume [m] (a stock's allowance is at most 20 mm).
MAX_DESIGN_DEPTH_M = 0.02
# The machining run's feed controls are the CMRR controllers (defined with their settings).
MACHINING_CONTROLLERS: tuple[str, ...] = CONTROLLER_NAMES
ControllerName = Literal[MACHINING_CONTROLLERS]  # type: ignore[valid-type]
# How a staged controller (fuzzy, two-stage) picks its stage under offline compensation:
# switching online in the cell by the force, or planned offline as the program's speeds
# (``machining.schedule``).
Stages = Literal["online", "planned"]
STAGE_PLANS: tuple[Stages, ...] = get_args(Stages)

# Each scalar setting's range, from ``limits`` (one definition for the API, the GUIs and here),
# so an advertised value is never refused here or, through the CMRR settings the choice makes,
# under another field's name. Ranges given in mm, mm/s or um are checked in the field's SI unit.
_RANGES: dict[str, Range] = {
    "process_gain_N": MACHINING_PROCESS_GAIN_N,
    "depth_exponent": MACHINING_DEPTH_EXPONENT,
    "feed_exponent": MACHINING_FEED_EXPONENT,
    "process_time_constant_s": MACHINING_TIME_CONSTANT_S,
    "force_limit_N": MACHINING_FORCE_LIMIT_N,
    "command_speed_cap_m_s": CMRR_COMMAND_SPEED_MM_S,
    "path_acceleration_m_s2": MACHINING_PATH_ACCELERATION_M_S2,
    "min_speed_ratio": CMRR_MIN_SPEED_RATIO,
    "feed_force_ratio": MACHINING_FEED_FORCE_RATIO,
    "axial_engagement_m": MACHINING_AXIAL_ENGAGEMENT_MM,
    "sensor_noise_N": MACHINING_SENSOR_NOISE_N,
    "sensor_filter_cutoff_hz": FORCE_FILTER_CUTOFF_HZ,
    "online_filter_cutoff_hz": FORCE_FILTER_CUTOFF_HZ,
    "station_spacing_m": MACHINING_STATION_SPACING_MM,
    "offline_target_spacing_m": MACHINING_TARGET_SPACING_MM,
    "cmm_noise_m": CMM_NOISE_UM,
}
_SI_UNIT: dict[str, tuple[str, float]] = {
    "mm": ("m", 1e-3),
    "mm/s": ("m/s", 1e-3),
    "um": ("m", 1e-6),
}


def _check_range(name: str, value: object, limits_range: Range) -> None:
    """``value`` (in the field's SI unit) inside ``limits_range``, else an error naming the
    field and its range in that unit."""
    unit, scale = _SI_UNIT.get(limits_range.unit, (limits_range.unit, 1.0))
    lo, hi = limits_range.min * scale, limits_range.max * scale
    number = value if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan
    slack = 1e-12 * max(abs(lo), abs(hi))  # the unit change's rounding at the ends
    if not (math.isfinite(number) and lo - slack <= number <= hi + slack):
        raise MachiningSettingsError(
            f"{name} must be in [{lo:g}, {hi:g}] {unit}".rstrip() + f", got {value!r}"
        )


@dataclass(frozen=True)
class MachiningSettings:
    """One machining run's settings (SI units).

    Attributes:
        process_gain_N: K of eq. (5): the force at 1 mm depth and 1 mm/s [N].
        depth_exponent: alpha of eq. (5).
        feed_exponent: beta of eq. (5).
        process_time_constant_s: tau_m of eq. (3), the first-order lag of the force.
        force_limit_N: The force the cut must not exceed (spindle, tool); the deepest cut of
            the stock is the binding case of a constant feed.
        reference_force_N: Fr the CMRR controllers hold; None takes 0.7 of the limit, the
            margin a PI needs for its overshoot on a burr's flank (the feed cannot drop
            faster than eq. (1) lets it).
        command_speed_cap_m_s: Vr: no programmed speed is executed faster than this (the
            chapter's ~10 mm/s machining feed, section 3.4).
        path_acceleration_m_s2: The path planner's limit on speed changes between moves
            (the programmed speeds step from move to move; the robot ramps between them).
        controller: ``"constant"`` or a CMRR controller of ``robomach_core.cmrr``.
        controller_settings: Overrides of the controller's defaults (its ``kind`` must match).
        constant_feed_m_s: Feed of the ``constant`` controller; None takes the greatest
            constant feed that keeps the force limit at the deepest cut.
        design_depth_m: The deepest cut the program (its constant feed) and the controllers
            are designed for; None: the stock's. A sweep over castings sets the nominal
            stock's, so every casting is cut by the one program that is exported.
        min_speed_ratio: delta of eq. (13), the lowest speed ratio CMRR may command.
        compensation: ``"off"``, ``"offline"`` (targets corrected before the run) or
            ``"online"`` (joint reference corrected from the measured force): the one
            vocabulary of ``stiffness.modes``. The run plans an offline correction linearly
            from the force its rehearsals met (``machining.offline``).
        stages: Under offline compensation, how a staged controller (fuzzy, two-stage) picks
            its stage: ``"online"`` (it switches in the cell by the measured force, as without
            compensation) or ``"planned"`` (its cuts of the nominal wall fix the lowest stage
            per station, the program carries it as its speeds, and the cell runs no feed
            control: ``machining.schedule``). Other controllers and modes ignore it.
        feed_force_ratio: Feed (tangential) over normal component of the process force; the
            power law gives the magnitude, the normal component pushes the tool off the wall.
        axial_engagement_m: Height of the cut along the tool axis (for the MRR only).
        sensor_noise_N: White noise of the force sensor, one sigma.
        sensor_filter_cutoff_hz: Low-pass of the CMRR feedback (2nd-order Butterworth).
        online_filter_cutoff_hz: First-order low-pass of the online compensation's wrench.
        station_spacing_m: Spacing of the stations where the finished wall is evaluated.
        offline_target_spacing_m: Spacing of the corrected targets of offline compensation.
        identification_poses: Poses of the CMM campaign that identifies the stiffness.
        cmm_noise_m: CMM noise per axis and reading of that campaign.
        max_samples: A run that would record more samples than this is refused.
        seed: Seeds the sensor noise and the identification campaign.
    """

    process_gain_N: float = 23.0
    depth_exponent: float = 0.9
    feed_exponent: float = 0.5
    process_time_constant_s: float = DEFAULT_TAU_M_S
    force_limit_N: float = 150.0
    reference_force_N: float | None = None
    command_speed_cap_m_s: float = 0.010
    path_acceleration_m_s2: float = 0.05
    controller: ControllerName = "adaptive-pi"
    controller_settings: ControllerSettings | None = None
    constant_feed_m_s: float | None = None
    design_depth_m: float | None = None
    min_speed_ratio: float = 0.1
    compensation: Compensation = "off"
    stages: Stages = "online"
    feed_force_ratio: float = 0.5
    axial_engagement_m: float = 0.005
    sensor_noise_N: float = 2.0
    sensor_filter_cutoff_hz: float = 20.0
    online_filter_cutoff_hz: float = ONLINE_CUTOFF_HZ
    station_spacing_m: float = 0.1 * MM
    offline_target_spacing_m: float = 1.0 * MM
    identification_poses: int = 30
    cmm_noise_m: float = 20e-6
    max_samples: int = 2_000_000
    seed: int = 0

    def __post_init__(self) -> None:
        for name, limits_range in _RANGES.items():
            _check_range(name, getattr(self, name), limits_range)
        if self.controller not in MACHINING_CONTROLLERS:
            raise MachiningSettingsError(
                f"unknown controller {self.controller!r}; choose one of "
                f"{', '.join(MACHINING_CONTROLLERS)}"
            )
        if self.compensation not in COMPENSATIONS:
            raise MachiningSettingsError(
                f"unknown compensation {self.compensation!r}; choose one of "
                f"{', '.join(COMPENSATIONS)}"
            )
        if self.stages not in STAGE_PLANS:
            raise MachiningSettingsError(
                f"unknown stages {self.stages!r}; choose one of {', '.join(STAGE_PLANS)}"
            )
        if self.controller_settings is not None and self.controller_settings.kind != (
            self.controller
        ):
            raise MachiningSettingsError(
                f"controller settings are for {self.controller_settings.kind!r}, "
                f"the controller is {self.controller!r}"
            )
        ref = self.reference_force_N
        top = min(self.force_limit_N, CMRR_REFERENCE_FORCE_N.max)
        if ref is not None and not (
            isinstance(ref, (int, float))
            and math.isfinite(ref)
            and CMRR_REFERENCE_FORCE_N.min <= ref <= top
        ):
            raise MachiningSettingsError(
                f"reference_force_N must be within {CMRR_REFERENCE_FORCE_N.min:g}-{top:g} N "
                f"(at most the force limit), got {ref!r}"
            )
        cf = self.constant_feed_m_s
        if cf is not None and not (math.isfinite(cf) and 0.0 < cf <= self.command_speed_cap_m_s):
            raise MachiningSettingsError(
                f"constant_feed_m_s must be in (0, {self.command_speed_cap_m_s:g}] m/s "
                f"(the speed cap), got {cf!r}"
            )
        dd = self.design_depth_m
        if dd is not None and not (
            isinstance(dd, (int, float)) and math.isfinite(dd) and 0.0 <= dd <= MAX_DESIGN_DEPTH_M
        ):
            raise MachiningSettingsError(
                f"design_depth_m must be in [0, {MAX_DESIGN_DEPTH_M:g}] m, got {dd!r}"
            )
        if not (isinstance(self.identification_poses, int) and 8 <= self.identification_poses):
            raise MachiningSettingsError(
                f"identification_poses must be an integer >= 8, got {self.identification_poses!r}"
            )
        if not (isinstance(self.max_samples, int) and 1000 <= self.max_samples <= 50_000_000):
            raise MachiningSettingsError(
                f"max_samples must be an integer in [1000, 50000000], got {self.max_samples!r}"
            )

    @property
    def process(self) -> PowerLawForceModel:
        """The cutting process, eqs. (3)-(6)."""
        return PowerLawForceModel(
            gain_N=self.process_gain_N,
            depth_exponent=self.depth_exponent,
            feed_exponent=self.feed_exponent,
            time_constant_s=self.process_time_constant_s,
        )

    @property
    def reference_N(self) -> float:
        """Fr [N]: the given reference, else ``DEFAULT_REFERENCE_FRACTION`` of the limit."""
        if self.reference_force_N is not None:
            return self.reference_force_N
        return DEFAULT_REFERENCE_FRACTION * self.force_limit_N

    def safe_constant_feed_m_s(self, max_depth_m: float) -> float:
        """Greatest constant feed keeping the limit at the deepest cut, capped:
        f = (F_lim / (K d_max^alpha))^(1/beta), the inverse of eq. (5)."""
        return min(
            self.command_speed_cap_m_s, self.process.feed_for_force(self.force_limit_N, max_depth_m)
        )


def settings_to_dict(settings: MachiningSettings) -> dict[str, Any]:
    """JSON-ready dict of the scalar settings (controller settings by kind only)."""
    out: dict[str, Any] = {}
    for f in fields(settings):
        value = getattr(settings, f.name)
        out[f.name] = value.kind if f.name == "controller_settings" and value else value
    return out
