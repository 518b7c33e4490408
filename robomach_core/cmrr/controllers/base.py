"""What every CMRR controller shares: the design data it may use, its input and its output.

A controller is an immutable object (settings plus constants derived from the design) with
``initial_state()`` and ``step(state, measurement) -> (state, output)``; all that changes during
a cut lives in the returned state, so a study can be replayed or run in parallel.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

from ..errors import CmrrSettingsError
from ..feed_dynamics import FeedDynamics
from ..process import LowPassFilter

# The power law's feed unit: Kf is the force at 1 mm/s (eq. (6) uses f in mm/s).
FEED_REF_M_S = 1e-3


@dataclass(frozen=True, eq=False)
class ControlDesign:
    """The numbers a process engineer knows before the cut, and the controller's sample time.

    Attributes:
        dt_s: control period [s] (0.004 on the simulated cell).
        command_speed_m_s: Vr, the programmed (greatest) feed [m/s].
        reference_force_N: Fr, the force to hold [N].
        min_speed_ratio: delta of eq. (13), the lowest speed_ratio a controller may command.
        nominal_force_gain_N: Kf = K d^alpha at the design depth, the force at 1 mm/s [N].
        nominal_feed_exponent: beta of eq. (8).
        feed_dynamics: eq. (1), the identified robot model (used by the LQ design).
        measurement_filter: the low-pass filter already applied to the force signal, so a
            controller can filter the feed the same way before estimating (None: unfiltered).
        interaction_stiffness_N_m: Kf of the Lund model (tool-workpiece-robot stiffness).
        initial_removal_N_s_m: the Lund model's initial guess of Df [N s/m].
        control_delay_steps: samples between a measurement and the robot acting on the command
            it produced (the controller's own latency; the LQ design models it).
    """

    dt_s: float
    command_speed_m_s: float
    reference_force_N: float
    min_speed_ratio: float = 0.1
    nominal_force_gain_N: float = 23.0
    nominal_feed_exponent: float = 0.5
    feed_dynamics: FeedDynamics = field(default_factory=FeedDynamics)
    measurement_filter: LowPassFilter | None = None
    interaction_stiffness_N_m: float = 50.0e3
    initial_removal_N_s_m: float = 1.0e3
    control_delay_steps: int = 1

    def __post_init__(self) -> None:
        if not self.dt_s > 0.0:
            raise CmrrSettingsError("control period must be positive")
        if not self.command_speed_m_s > 0.0:
            raise CmrrSettingsError("command speed must be positive")
        if not self.reference_force_N > 0.0:
            raise CmrrSettingsError("reference force must be positive")
        if not 0.0 < self.min_speed_ratio < 1.0:
            raise CmrrSettingsError(
                f"minimum speed ratio must be in (0, 1), got {self.min_speed_ratio}"
            )
        if not self.nominal_force_gain_N > 0.0 or not self.nominal_feed_exponent > 0.0:
            raise CmrrSettingsError("nominal process gain and feed exponent must be positive")


@dataclass(frozen=True)
class Measurement:
    """One control sample: the (filtered) force feedback and the robot's actual feed."""

    force_N: float
    feed_m_s: float


@dataclass(frozen=True)
class ControlOutput:
    """The controller's command for the next sample.

    Attributes:
        speed_ratio: fraction of the programmed speed, in [delta, 1] (0 only when stopped).
        engaged: the control law is in effect (False during a start-up phase or after a stop).
        stop: the failure-protection rule stopped the robot (latched).
        estimates: named on-line estimates for plotting (units in the names).
    """

    speed_ratio: float
    engaged: bool = True
    stop: bool = False
    estimates: dict[str, float] = field(default_factory=dict)


class Controller(Protocol):
    """A CMRR feed controller: ``step`` maps (state, measurement) to (state, output)."""

    name: str
    estimate_names: tuple[str, ...]

    @property
    def initial_speed_ratio(self) -> float:
        """The speed ratio in effect before the first command."""
        ...

    def initial_state(self) -> Any:
        """State at the start of the cut."""
        ...

    def step(self, state: Any, measurement: Measurement) -> tuple[Any, ControlOutput]:
        """One control period."""
        ...

    def describe(self) -> dict[str, float | str]:
        """Resolved parameters (gains after design) for reports, units in the keys."""
        ...


def saturate(u: float, low: float, high: float = 1.0) -> float:
    """sat(u) of eq. (13): clip the speed ratio to [delta, 1]."""
    return high if u >= high else (low if u <= low else u)
