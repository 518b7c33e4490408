"""The studies of the papers, as data: path, depth profile, process, robot, sensor, targets.

- ``milling-steps``: MRR paper sec. IV / chapter sec. 4.4, end milling of an aluminium block,
  depth 1 -> 2 -> 3 mm, Fr = 250 N, command speed 30 mm/s, lab fit F = 23 d^0.9 f^0.5.
- ``deburr-burrs``: MRR paper fig. 9 / chapter fig. 13, grinding two burrs off a cast-steel
  bar in one straight pass, spindle limit ~300 N, command speed 100 mm/s.
- ``lund-df``: Lund paper sec. 3, milling with step and ramp changes of the material-removal
  parameter Df, Kf = 50 N/mm, Fr = 20 N, start-up feed 6 mm/s.
- ``learned-path``: the product's own: depth along a (learned) path from a stock mesh against
  the nominal part, deburred like ``deburr-burrs``. Without a learned path, a synthetic block
  edge with burr bumps stands in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal, get_args

import numpy as np

from ..cell import CONTROL_PERIOD_S
from .controllers.base import FEED_REF_M_S, ControlDesign
from .depth_profiles import (
    Burr,
    PathProfile,
    burr_depth_profile,
    path_depth_profile,
    random_burrs,
    segment_bounds,
    step_depth_profile,
    synthetic_burr_block,
)
from .errors import CmrrSettingsError, UnknownScenarioError
from .feed_dynamics import FeedDynamics
from .process import (
    FeedbackSignal,
    ForceSensorModel,
    LundForceModel,
    PowerLawForceModel,
    SpindleCurrentModel,
)

MM = 1e-3

ScenarioName = Literal["milling-steps", "deburr-burrs", "lund-df", "learned-path"]
SCENARIO_NAMES: tuple[str, ...] = get_args(ScenarioName)

# Deburring grinder on cast steel (not given in the paper; chosen so that the nominal pass at
# 100 mm/s cuts at ~90 N and the larger burr at full speed would exceed the 300 N spindle
# limit by ~20 %).
DEBURR_PROCESS = PowerLawForceModel(gain_N=16.0, depth_exponent=0.9, feed_exponent=0.5)
DEBURR_BURRS: tuple[Burr, ...] = (
    Burr(center_m=0.20, height_m=1.5 * MM, width_m=30.0 * MM),
    Burr(center_m=0.38, height_m=2.0 * MM, width_m=40.0 * MM),
)


@dataclass(frozen=True)
class Segment:
    """A stretch of the path reported on its own (e.g. one depth of the step test)."""

    label: str
    start_m: float
    end_m: float


@dataclass(frozen=True, eq=False)
class Scenario:
    """Everything a study needs besides the controller.

    Attributes:
        name: scenario name.
        description: one line for reports.
        depth_profile: depth of cut [m] along the path; its last position is the path length.
        process: the true cutting process.
        nominal_process: the process model the engineer designs with (the lab fit).
        design_depth_m: the depth at which ``nominal_process`` gives the design gain Kf.
        command_speed_m_s: Vr, the programmed speed [m/s].
        reference_force_N: Fr [N].
        min_speed_ratio: delta of eq. (13).
        force_limit_N: a hard limit (spindle power) to report against, if any [N].
        feedback: "force" (F/T sensor) or "spindle_current".
        feed_dynamics: the robot, eq. (1).
        sensor: force sensor noise and low-pass filter.
        spindle: spindle current model.
        dt_s: control period [s].
        control_delay_steps: samples between a measurement and the command it produces.
        segments: stretches reported separately.
        conservative_feed_m_s: the constant feed practice would choose without CMRR, if given.
        max_time_s: simulated time limit [s]; None derives one from the path and delta.
        default_controller: the controller the paper used for this experiment.
    """

    name: str
    description: str
    depth_profile: PathProfile
    process: PowerLawForceModel | LundForceModel
    nominal_process: PowerLawForceModel | LundForceModel
    design_depth_m: float
    command_speed_m_s: float
    reference_force_N: float
    min_speed_ratio: float = 0.1
    force_limit_N: float | None = None
    feedback: FeedbackSignal = "force"
    feed_dynamics: FeedDynamics = field(default_factory=FeedDynamics)
    sensor: ForceSensorModel = field(default_factory=ForceSensorModel)
    spindle: SpindleCurrentModel = field(default_factory=SpindleCurrentModel)
    dt_s: float = CONTROL_PERIOD_S
    control_delay_steps: int = 1
    segments: tuple[Segment, ...] = ()
    conservative_feed_m_s: float | None = None
    max_time_s: float | None = None
    default_controller: str = "adaptive-pi"

    def __post_init__(self) -> None:
        if not self.command_speed_m_s > 0.0 or not self.reference_force_N > 0.0:
            raise CmrrSettingsError("command speed and reference force must be positive")
        if not 0.0 < self.min_speed_ratio < 1.0:
            raise CmrrSettingsError("minimum speed ratio must be in (0, 1)")
        if self.feedback not in ("force", "spindle_current"):
            raise CmrrSettingsError(f"feedback must be force or spindle_current: {self.feedback}")
        if self.control_delay_steps < 0:
            raise CmrrSettingsError("control delay must not be negative")
        if self.path_length_m <= 0.0:
            raise CmrrSettingsError("the path must have a positive length")

    @property
    def path_length_m(self) -> float:
        """Length of the cut [m]."""
        return float(self.depth_profile.positions_m[-1])

    @property
    def time_limit_s(self) -> float:
        """Simulated time after which a study gives up [s]."""
        if self.max_time_s is not None:
            return self.max_time_s
        slowest = self.min_speed_ratio * self.command_speed_m_s
        return 1.5 * self.path_length_m / slowest + 2.0

    @property
    def limit_force_N(self) -> float:
        """The force a constant feed must not exceed: the hard limit, else the reference."""
        return self.force_limit_N if self.force_limit_N is not None else self.reference_force_N

    def safe_constant_feed_m_s(self) -> float:
        """Greatest constant feed [m/s] whose steady force stays at or under ``limit_force_N``
        everywhere on the path (the conservative feed of the MRR paper, sec. III), <= Vr."""
        depths = self.depth_profile.values
        feeds = [self.process.feed_for_force(self.limit_force_N, float(d)) for d in depths]
        return min(self.command_speed_m_s, min(feeds))

    def reference_reachable(self, depth_m: np.ndarray) -> np.ndarray:
        """True where the full-speed steady force exceeds Fr, i.e. where CMRR must act."""
        vr = self.command_speed_m_s
        force = [self.process.steady_force(float(d), vr) for d in np.atleast_1d(depth_m)]
        return np.array(force) >= self.reference_force_N

    def control_design(self) -> ControlDesign:
        """The design data a controller gets: the engineer's model, not the true process."""
        nominal = self.nominal_process
        kwargs: dict[str, Any] = {}
        if isinstance(nominal, PowerLawForceModel):
            kwargs["nominal_force_gain_N"] = nominal.force_gain_N(self.design_depth_m)
            kwargs["nominal_feed_exponent"] = nominal.feed_exponent
        else:
            df = nominal.removal_parameter(self.design_depth_m)
            kwargs["interaction_stiffness_N_m"] = nominal.stiffness_N_m
            kwargs["initial_removal_N_s_m"] = df
            # A linear process is beta = 1 with Kf = Df (force per mm/s).
            kwargs["nominal_force_gain_N"] = df * FEED_REF_M_S
            kwargs["nominal_feed_exponent"] = 1.0
        return ControlDesign(
            dt_s=self.dt_s,
            command_speed_m_s=self.command_speed_m_s,
            reference_force_N=self.reference_force_N,
            min_speed_ratio=self.min_speed_ratio,
            feed_dynamics=self.feed_dynamics,
            measurement_filter=self.sensor.make_filter(self.dt_s),
            control_delay_steps=self.control_delay_steps,
            **kwargs,
        )


def milling_steps(
    *,
    depths_mm: Sequence[float] = (1.0, 2.0, 3.0),
    segment_length_mm: float = 90.0,
    reference_force_N: float = 250.0,
    command_speed_mm_s: float = 30.0,
    **overrides: Any,
) -> Scenario:
    """End milling, depth 1 -> 2 -> 3 mm, Fr = 250 N, Vr = 30 mm/s (figs. 11-12 of the chapter).

    The gains of a fixed PI are designed for the 1 mm depth (``design_depth_m``).
    """
    depths = [d * MM for d in depths_mm]
    seg = segment_length_mm * MM
    profile = step_depth_profile(depths, seg)
    segments = tuple(
        Segment(f"{d:g} mm", a, b)
        for d, (a, b) in zip(depths_mm, segment_bounds(depths, seg), strict=True)
    )
    process = PowerLawForceModel()
    base = Scenario(
        name="milling-steps",
        description=(
            f"end milling, depth {' -> '.join(f'{d:g}' for d in depths_mm)} mm, "
            f"Fr = {reference_force_N:g} N, Vr = {command_speed_mm_s:g} mm/s"
        ),
        depth_profile=profile,
        process=process,
        nominal_process=process,
        design_depth_m=depths[0],
        command_speed_m_s=command_speed_mm_s * MM,
        reference_force_N=reference_force_N,
        min_speed_ratio=0.1,
        segments=segments,
        default_controller="adaptive-pi",
    )
    return replace(base, **overrides)


def deburr_burrs(
    *,
    burrs: Sequence[Burr] | None = None,
    length_mm: float = 600.0,
    base_depth_mm: float = 0.5,
    command_speed_mm_s: float = 100.0,
    reference_force_N: float = 200.0,
    force_limit_N: float = 300.0,
    **overrides: Any,
) -> Scenario:
    """Deburring two burrs in one straight grinding pass, spindle limit 300 N (chapter fig. 13).

    The reference force of the speed change is set below the spindle limit; the paper ran the
    command speed at 100 mm/s with two-stage switching (0.5, 1.0) where a constant feed would
    be set to a conservative 30-40 mm/s.
    """
    burrs = DEBURR_BURRS if burrs is None else tuple(burrs)
    length = length_mm * MM
    profile = burr_depth_profile(burrs, length, base_depth_m=base_depth_mm * MM)
    segments = tuple(
        Segment(f"burr {i + 1}", b.center_m - 0.5 * b.width_m, b.center_m + 0.5 * b.width_m)
        for i, b in enumerate(burrs)
    )
    base = Scenario(
        name="deburr-burrs",
        description=(
            f"deburring {len(burrs)} burrs, Vr = {command_speed_mm_s:g} mm/s, "
            f"Fr = {reference_force_N:g} N, spindle limit {force_limit_N:g} N"
        ),
        depth_profile=profile,
        process=DEBURR_PROCESS,
        nominal_process=DEBURR_PROCESS,
        design_depth_m=base_depth_mm * MM,
        command_speed_m_s=command_speed_mm_s * MM,
        reference_force_N=reference_force_N,
        min_speed_ratio=0.1,
        force_limit_N=force_limit_N,
        segments=segments,
        conservative_feed_m_s=35.0 * MM,
        default_controller="two-stage",
    )
    return replace(base, **overrides)


def lund_df(
    *,
    stiffness_N_mm: float = 50.0,
    reference_force_N: float = 20.0,
    command_speed_mm_s: float = 40.0,
    **overrides: Any,
) -> Scenario:
    """Lund milling simulation: Df = 1 -> 2 (step) -> 1 (step) -> ramp 2 -> 0.5 N s/mm.

    Kf = 50 N/mm, Fr = 20 N, initial Df estimate 1 N s/mm; the adaptive LQ starts at 6 mm/s
    (speed ratio 0.15 of 40 mm/s) until its Df estimate has converged. Df is modelled as
    proportional to the depth of cut (1 mm <-> 1 N s/mm), so the profile is a depth profile.
    """
    s = np.array([0.0, 60.0, 61.0, 120.0, 121.0, 180.0, 181.0, 200.0, 330.0]) * MM
    d = np.array([1.0, 1.0, 2.0, 2.0, 1.0, 1.0, 2.0, 2.0, 0.5]) * MM
    process = LundForceModel(stiffness_N_m=stiffness_N_mm * 1e3, removal_N_s_m=1.0e3)
    segments = (
        Segment("Df 1", 0.0, 60 * MM),
        Segment("Df 2 (step)", 61 * MM, 120 * MM),
        Segment("Df 1 (step)", 121 * MM, 180 * MM),
        Segment("Df ramp 2 -> 0.5", 200 * MM, 330 * MM),
    )
    base = Scenario(
        name="lund-df",
        description=(
            f"Lund milling, Kf = {stiffness_N_mm:g} N/mm, Df steps and ramp, "
            f"Fr = {reference_force_N:g} N"
        ),
        depth_profile=PathProfile(s, d),
        process=process,
        nominal_process=process,
        design_depth_m=1.0 * MM,
        command_speed_m_s=command_speed_mm_s * MM,
        reference_force_N=reference_force_N,
        min_speed_ratio=0.05,
        sensor=ForceSensorModel(noise_std_N=0.3),
        segments=segments,
        default_controller="adaptive-lq",
    )
    return replace(base, **overrides)


def learned_path(
    *,
    path_points_m: np.ndarray | None = None,
    nominal_mesh: object | None = None,
    stock_mesh: object | None = None,
    tool_axis: np.ndarray | Sequence[float] = (0.0, 0.0, 1.0),
    burr_count: int = 3,
    seed: int = 0,
    command_speed_mm_s: float = 100.0,
    reference_force_N: float = 200.0,
    force_limit_N: float = 300.0,
    **overrides: Any,
) -> Scenario:
    """Deburring along a learned path, depth from the stock mesh against the nominal part.

    Without a path and meshes, a synthetic 200 mm block edge with 0.5 mm allowance and
    ``burr_count`` burrs of random size and place (from ``seed``) stands in.
    """
    given = (path_points_m is not None, nominal_mesh is not None, stock_mesh is not None)
    if any(given) and not all(given):
        raise CmrrSettingsError("learned-path needs the path and both meshes, or none of them")
    if path_points_m is None:
        rng = np.random.default_rng(seed)
        burrs = random_burrs(
            rng, burr_count, 0.2, height_range_m=(1.0 * MM, 2.0 * MM), margin_m=20.0 * MM
        )
        nominal_mesh, stock_mesh, path_points_m, tool_axis = synthetic_burr_block(burrs)
    profile = path_depth_profile(path_points_m, nominal_mesh, stock_mesh, tool_axis)
    base = deburr_burrs(
        command_speed_mm_s=command_speed_mm_s,
        reference_force_N=reference_force_N,
        force_limit_N=force_limit_N,
    )
    return replace(
        base,
        name="learned-path",
        description=f"deburring along a learned path ({profile.length_m * 1e3:.0f} mm) from meshes",
        depth_profile=profile,
        segments=(),
        **overrides,
    )


SCENARIO_BUILDERS = {
    "milling-steps": milling_steps,
    "deburr-burrs": deburr_burrs,
    "lund-df": lund_df,
    "learned-path": learned_path,
}


def build_scenario(name: str, **overrides: Any) -> Scenario:
    """The named scenario with keyword overrides (builder keywords or ``Scenario`` fields)."""
    try:
        builder = SCENARIO_BUILDERS[name]
    except KeyError:
        raise UnknownScenarioError(
            f"unknown CMRR scenario {name!r}; choose one of {', '.join(SCENARIO_NAMES)}"
        ) from None
    try:
        return builder(**overrides)
    except TypeError as exc:
        raise CmrrSettingsError(f"scenario {name}: {exc}") from None
