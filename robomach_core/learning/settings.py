"""The settings of a path-learning run, with the ranges a user may set."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

from ..errors import InvalidInputError
from ..limits import FLOOR_CLEARANCE_MM, LEARNING_FORCE_N, LEARNING_SPEED_MM_S

WallSideSetting = Literal["auto", "left", "right"]
WALL_SIDE_CHOICES: tuple[WallSideSetting, ...] = get_args(WallSideSetting)
FORCE_RANGE_N = (LEARNING_FORCE_N.min, LEARNING_FORCE_N.max)
SPEED_RANGE_M_S = (LEARNING_SPEED_MM_S.min * 1e-3, LEARNING_SPEED_MM_S.max * 1e-3)


@dataclass(frozen=True)
class PathLearningSettings:
    """Settings of a path-learning run (SI units).

    Attributes:
        force_N: Contact force reference normal to the edge (the chapter: 10-20 N; 10 N on
            the pump).
        speed_m_s: Learning speed along the wall (the chapter: 5 mm/s).
        closed: The contour returns from the last guide point to the first.
        wall_side: Side of the wall relative to the travel direction, looking along the tool
            axis into the part; "auto" decides from a clear wall push at the guide points or
            the part's mesh, and refuses otherwise (``route.resolve_wall_side``).
        force_limit_N: Protection rule: the run stops when the contact force exceeds this.
        floor_clearance_m: The cutter's least clearance above the floor: a guide point resting
            on it is lifted to it, and a floor the run meets lifts the tool to it.
        kp_m_s_N: Proportional gain of the force loop.
        ki_m_s2_N: Integral gain of the force loop.
        max_normal_speed_m_s: Speed limit of the force loop.
        search_speed_m_s: Speed towards the wall, and along it, while out of contact (searching
            for the wall), so the tool meets it gently instead of at full speed.
    """

    force_N: float = LEARNING_FORCE_N.default_value()
    speed_m_s: float = LEARNING_SPEED_MM_S.default_value() * 1e-3
    closed: bool = True
    wall_side: WallSideSetting = "auto"
    force_limit_N: float = 60.0
    floor_clearance_m: float = FLOOR_CLEARANCE_MM.default_value() * 1e-3
    kp_m_s_N: float = 1.5e-3
    ki_m_s2_N: float = 0.03
    max_normal_speed_m_s: float = 0.025
    search_speed_m_s: float = 0.005

    def __post_init__(self) -> None:
        lo, hi = FORCE_RANGE_N
        if not (lo <= self.force_N <= hi):
            raise InvalidInputError(f"contact force {self.force_N:g} N is outside {lo:g}-{hi:g} N")
        lo, hi = SPEED_RANGE_M_S
        if not (lo <= self.speed_m_s <= hi):
            raise InvalidInputError(
                f"learning speed {self.speed_m_s * 1e3:g} mm/s is outside "
                f"{lo * 1e3:g}-{hi * 1e3:g} mm/s"
            )
        if self.force_limit_N <= self.force_N:
            raise InvalidInputError("the force limit must be above the force reference")
        if self.wall_side not in WALL_SIDE_CHOICES:
            raise InvalidInputError(f"wall side must be one of {', '.join(WALL_SIDE_CHOICES)}")
        FLOOR_CLEARANCE_MM.check(self.floor_clearance_m * 1e3)
