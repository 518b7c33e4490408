"""The machining tool: spindle body, cutter and TCP, mounted on the F/T sensor at the flange."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np

from ..errors import InvalidInputError
from ..limits import TOOL_RADIUS_MM
from ..transforms import make_transform

CutterShape = Literal["ball", "cylinder"]

TOOL_RADIUS_RANGE_M = (TOOL_RADIUS_MM.min * 1e-3, TOOL_RADIUS_MM.max * 1e-3)
# The tool pointing straight down, its x along -y of the base (the built-in parts' work pose).
TOOL_DOWN = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class Tool:
    """A spindle with a cutter.

    Attributes:
        name: Identifier used in exports (tooldata name).
        tcp_offset_m: (3,) TCP position in the flange (sensor) frame; the tool axis is flange +Z.
        mass_kg: Mass of spindle + cutter, carried by the F/T sensor.
        com_m: (3,) centre of mass in the flange frame.
        shape: ``"ball"`` (sphere centred at the TCP) or ``"cylinder"`` (tip at the TCP, body
            along -Z of the tool towards the flange).
        radius_m: Cutter radius.
        flute_length_m: Length of the cutting part (cylinder only).
    """

    name: str = "tSpindle"
    tcp_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.18)
    mass_kg: float = 2.5
    com_m: tuple[float, float, float] = (0.0, 0.0, 0.07)
    shape: CutterShape = "ball"
    radius_m: float = TOOL_RADIUS_MM.default_value() * 1e-3
    flute_length_m: float = 0.010
    _checked: bool = field(default=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        lo, hi = TOOL_RADIUS_RANGE_M
        if not (lo <= self.radius_m <= hi):
            raise InvalidInputError(
                f"tool radius {self.radius_m * 1e3:g} mm is outside {lo * 1e3:g}-{hi * 1e3:g} mm"
            )
        if self.shape not in ("ball", "cylinder"):
            raise InvalidInputError(
                f"cutter shape must be 'ball' or 'cylinder', not {self.shape!r}"
            )
        if not (0.0 < self.mass_kg < 50.0):
            raise InvalidInputError(f"tool mass {self.mass_kg} kg is outside (0, 50) kg")
        if not (0.0 < self.flute_length_m < 0.2):
            raise InvalidInputError("flute length must be in (0, 200) mm")
        if not np.all(np.isfinite(self.tcp_offset_m)) or not np.all(np.isfinite(self.com_m)):
            raise InvalidInputError("tool TCP offset and centre of mass must be finite")

    @cached_property
    def T_flange_tcp(self) -> np.ndarray:
        """4x4 pose of the TCP in the flange frame (same orientation as the flange)."""
        return make_transform(np.eye(3), np.asarray(self.tcp_offset_m, dtype=float))
