"""Mamdani fuzzy PD feed control with staged speed ratios (MRR paper sec. III-D, chapter 4.3.4).

PROBLEM: in deburring at up to 200 mm/s the burr size changes abruptly; a PI limited to a
stable loop gain reacts too late, and a derivative term on the noisy force is impractical.
STRATEGY: three inputs, fuzzified with triangular memberships: the force error e = F - Fr, the
filtered change of the error de/dt, and the previous speed ratio. Three rule groups: force
limit (speed up or slow down on e, like a classical controller), force trend (react to a steep
rise of the force before the error is large: the tool entering a large burr), and failure
protection (at the lowest stage with the force still far too high: stop the robot). Min for
AND, max for aggregation, centroid defuzzification give the change of speed ratio.
SOLUTION: the change is integrated and the output is quantized to stages (five, 0.2 ... 1.0,
by default) with hysteresis, so the feed does not change continuously (tool wear, surface) and
never drops below the lowest stage (rubbing instead of cutting). A stage up is taken only if
the force predicted there, F (u_next / u)^beta with the nominal beta, stays under the
reference; without this guard a staged output hunts between two stages whenever the reference
lies between their forces. Two-stage switching (0.5 / 1.0) is the special case with two stages.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np

from ..errors import CmrrSettingsError
from .base import ControlDesign, ControlOutput, Measurement

# Linguistic terms. Error and output: negative big .. positive big; trend: falling, steady,
# rising; previous speed ratio: at the lowest stage, middle, at full speed.
ERROR_TERMS = ("NB", "NS", "ZE", "PS", "PB")
TREND_TERMS = ("N", "Z", "P")
RATIO_TERMS = ("LOW", "MID", "HIGH")
OUTPUT_TERMS = ("NB", "NS", "ZE", "PS", "PB")
STOP = "STOP"

# (error, trend, previous ratio) -> output; None means "any". e = F - Fr: a positive error is
# too much force and slows down. Together the first two groups are a full PD table over
# (e, de/dt), as in Li & Gatland's rule bases:
#
#            de/dt:  N    Z    P
#       e = NB      PB   PB   NS
#           NS      PS   PS   NB
#           ZE      PS   ZE   NB
#           PS      ZE   NS   NB
#           PB      NS   NB   NB
FORCE_LIMIT_RULES: tuple[tuple[str | None, str | None, str | None, str], ...] = (
    ("NB", "Z", None, "PB"),
    ("NS", "Z", None, "PS"),
    ("ZE", "Z", None, "ZE"),
    ("PS", "Z", None, "NS"),
    ("PB", "Z", None, "NB"),
)
FORCE_TREND_RULES: tuple[tuple[str | None, str | None, str | None, str], ...] = (
    ("NB", "P", None, "NS"),  # far below but rising fast: a burr is coming, prepare
    ("NS", "P", None, "NB"),  # rising fast towards the reference: slow down now
    ("ZE", "P", None, "NB"),
    ("PS", "P", None, "NB"),
    ("PB", "P", None, "NB"),
    ("NB", "N", None, "PB"),  # falling: leaving the burr, speed up
    ("NS", "N", None, "PS"),  # falling but still near: our own slow-down also looks like this
    ("ZE", "N", None, "PS"),
    ("PS", "N", None, "ZE"),  # above but falling fast: do not slow down further
    ("PB", "N", None, "NS"),
)
PROTECTION_RULES: tuple[tuple[str | None, str | None, str | None, str], ...] = (
    ("PB", None, "LOW", STOP),  # lowest stage and the force still far too high
)
RULE_BASE = FORCE_LIMIT_RULES + FORCE_TREND_RULES + PROTECTION_RULES

# Output universe of discourse for centroid defuzzification.
OUTPUT_UNIVERSE = np.linspace(-1.0, 1.0, 81)
FIVE_STAGES = (0.2, 0.4, 0.6, 0.8, 1.0)


def triangular_memberships(x: float, centers: np.ndarray) -> np.ndarray:
    """Grades of evenly spaced triangles at ``centers``; the outer ones are shoulders."""
    xc = min(max(x, float(centers[0])), float(centers[-1]))
    width = float(centers[1] - centers[0])
    return np.maximum(0.0, 1.0 - np.abs(xc - centers) / width)


def _output_sets() -> np.ndarray:
    centers = np.linspace(-1.0, 1.0, len(OUTPUT_TERMS))
    width = centers[1] - centers[0]
    return np.maximum(0.0, 1.0 - np.abs(OUTPUT_UNIVERSE[None, :] - centers[:, None]) / width)


OUTPUT_SETS = _output_sets()


@dataclass(frozen=True)
class FuzzySettings:
    """Mamdani fuzzy PD with staged output.

    Attributes:
        stages: allowed speed ratios, increasing, the last 1.0 (five 0.2 ... 1.0 by default).
        error_span_N: |F - Fr| at which the error is "big"; None: ``error_span_fraction`` Fr.
        trend_span_N_s: |dF/dt| at which the trend is fully "rising"/"falling"; None: 5 Fr/s.
        trend_filter_s: time constant of the first-order filter on the change of error [s].
        max_rate_per_s: change of the internal speed ratio per second at full output.
        hysteresis: fraction of a stage gap the internal ratio must pass the midpoint by before
            the output stage changes.
        stop_strength: firing strength of the protection rule that stops the robot.
        stop_hold_s: how long the protection rule must fire before the stop [s].
        initial_speed_ratio: the stage at the start of the cut.
        error_span_fraction: the default error span as a fraction of Fr.
        switch_settle_s: after the output stage changes, the trend input is held at zero
            this long [s]: the force change the controller's own switch causes (eq. 1's feed
            response, the force lag, the filter) is not a burr coming. 0 (the papers' rule
            base as it is): the trend rules answer the switch, and a force near the reference
            makes the stages hunt, a switch every few tenths of a millimetre.
        stage_up_margin: a stage up is taken only if the force predicted there stays this
            fraction under the reference (0, the rule as it was: just under it; then the
            sensor's noise alone decides whether a cut whose force at the next stage would be
            about the reference goes up, and a short stretch at the next stage comes and goes).
    """

    kind: Literal["fuzzy"] = field(default="fuzzy", init=False)
    stages: tuple[float, ...] = FIVE_STAGES
    error_span_N: float | None = None
    trend_span_N_s: float | None = None
    trend_filter_s: float = 0.01
    max_rate_per_s: float = 8.0
    hysteresis: float = 0.1
    stop_strength: float = 0.5
    stop_hold_s: float = 0.2
    initial_speed_ratio: float = 1.0
    error_span_fraction: float = 0.3
    switch_settle_s: float = 0.0
    stage_up_margin: float = 0.0

    def __post_init__(self) -> None:
        stages = tuple(float(s) for s in self.stages)
        object.__setattr__(self, "stages", stages)
        if len(stages) < 2 or any(b <= a for a, b in zip(stages, stages[1:], strict=False)):
            raise CmrrSettingsError("fuzzy stages must be two or more increasing speed ratios")
        if not 0.0 < stages[0] or stages[-1] != 1.0:
            raise CmrrSettingsError("fuzzy stages must lie in (0, 1] and end at 1.0")
        if self.initial_speed_ratio not in stages:
            raise CmrrSettingsError("the initial speed ratio must be one of the stages")
        for name in ("error_span_N", "trend_span_N_s"):
            value = getattr(self, name)
            if value is not None and not value > 0.0:
                raise CmrrSettingsError(f"{name} must be positive")
        if not 0.0 < self.error_span_fraction <= 2.0:
            raise CmrrSettingsError("error span fraction must be in (0, 2]")
        if not self.max_rate_per_s > 0.0 or not self.trend_filter_s > 0.0:
            raise CmrrSettingsError("rate and trend filter time must be positive")
        if not 0.0 <= self.hysteresis < 0.5:
            raise CmrrSettingsError("stage hysteresis must be in [0, 0.5)")
        if not 0.0 < self.stop_strength <= 1.0 or self.stop_hold_s < 0.0:
            raise CmrrSettingsError("stop strength must be in (0, 1], hold time >= 0")
        if not 0.0 <= self.switch_settle_s <= 10.0:
            raise CmrrSettingsError("switch settle time must be within 0-10 s")
        if not 0.0 <= self.stage_up_margin < 1.0:
            raise CmrrSettingsError("stage-up margin must be in [0, 1)")


@dataclass(frozen=True)
class TwoStageSettings:
    """Two-stage switching: the fuzzy controller with only a low and the full speed.

    The paper's deburring result used (0.5, 1.0) at a 100 mm/s command speed. A much
    faster internal rate than the five-stage default (one switch halves the speed, and it must
    land within the burr's force rise) and a wider error span (the switch is prepared while
    the force is still well below the reference).
    """

    kind: Literal["two-stage"] = field(default="two-stage", init=False)
    low_speed_ratio: float = 0.5
    error_span_N: float | None = None
    trend_span_N_s: float | None = None
    trend_filter_s: float = 0.01
    max_rate_per_s: float = 40.0
    hysteresis: float = 0.1
    stop_strength: float = 0.5
    stop_hold_s: float = 0.2
    error_span_fraction: float = 0.5
    switch_settle_s: float = 0.0
    stage_up_margin: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 < self.low_speed_ratio < 1.0:
            raise CmrrSettingsError("two-stage low speed ratio must be in (0, 1)")
        self.to_fuzzy()  # validates the rest

    def to_fuzzy(self) -> FuzzySettings:
        """The equivalent fuzzy settings with stages (low, 1.0)."""
        return FuzzySettings(
            stages=(self.low_speed_ratio, 1.0),
            error_span_N=self.error_span_N,
            error_span_fraction=self.error_span_fraction,
            trend_span_N_s=self.trend_span_N_s,
            trend_filter_s=self.trend_filter_s,
            max_rate_per_s=self.max_rate_per_s,
            hysteresis=self.hysteresis,
            stop_strength=self.stop_strength,
            stop_hold_s=self.stop_hold_s,
            switch_settle_s=self.switch_settle_s,
            stage_up_margin=self.stage_up_margin,
        )


@dataclass(frozen=True)
class FuzzyState:
    """Internal (continuous) ratio, output stage index, filtered trend, previous error, time
    at high force at the lowest stage, stopped, time since the last stage change."""

    internal_ratio: float
    stage: int
    trend_N_s: float
    previous_error_N: float
    protection_time_s: float
    stopped: bool
    since_switch_s: float = math.inf


@dataclass(frozen=True)
class FuzzyController:
    """Mamdani fuzzy PD on (e, de/dt, previous speed ratio) -> change of speed ratio, staged."""

    settings: FuzzySettings | TwoStageSettings
    design: ControlDesign
    estimate_names: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return self.settings.kind

    @cached_property
    def fuzzy(self) -> FuzzySettings:
        s = self.settings
        return s.to_fuzzy() if isinstance(s, TwoStageSettings) else s

    @cached_property
    def spans(self) -> tuple[float, float]:
        """(error span [N], trend span [N/s]) after defaults."""
        fr = self.design.reference_force_N
        f = self.fuzzy
        return (f.error_span_N or f.error_span_fraction * fr, f.trend_span_N_s or 5.0 * fr)

    @cached_property
    def _rules(self) -> list[tuple[int | None, int | None, int | None, int]]:
        def idx(terms: tuple[str, ...], term: str | None) -> int | None:
            return None if term is None else terms.index(term)

        out = []
        for e, de, u, o in RULE_BASE:
            out_index = -1 if o == STOP else OUTPUT_TERMS.index(o)
            out.append((idx(ERROR_TERMS, e), idx(TREND_TERMS, de), idx(RATIO_TERMS, u), out_index))
        return out

    @property
    def initial_speed_ratio(self) -> float:
        return self.fuzzy.initial_speed_ratio

    def initial_state(self) -> FuzzyState:
        f = self.fuzzy
        stage = f.stages.index(f.initial_speed_ratio)
        fr = self.design.reference_force_N
        return FuzzyState(f.initial_speed_ratio, stage, 0.0, -fr, 0.0, False, math.inf)

    def infer(self, error_N: float, trend_N_s: float, previous_ratio: float) -> tuple[float, float]:
        """Mamdani inference: (change of speed ratio in [-1, 1], protection-rule strength)."""
        e_span, de_span = self.spans
        stages = self.fuzzy.stages
        mu_e = triangular_memberships(error_N / e_span, np.linspace(-1.0, 1.0, 5))
        mu_de = triangular_memberships(trend_N_s / de_span, np.linspace(-1.0, 1.0, 3))
        lo, hi = stages[0], stages[-1]
        mu_u = triangular_memberships(previous_ratio, np.array([lo, 0.5 * (lo + hi), hi]))
        strength = np.zeros(len(OUTPUT_TERMS))
        stop = 0.0
        for e, de, u, o in self._rules:
            w = 1.0
            if e is not None:
                w = min(w, mu_e[e])
            if de is not None:
                w = min(w, mu_de[de])
            if u is not None:
                w = min(w, mu_u[u])
            if o < 0:
                stop = max(stop, w)
            elif w > strength[o]:
                strength[o] = w
        aggregate = np.max(np.minimum(strength[:, None], OUTPUT_SETS), axis=0)
        area = float(aggregate.sum())
        change = float(aggregate @ OUTPUT_UNIVERSE) / area if area > 0.0 else 0.0
        return change, stop

    def step(self, state: FuzzyState, measurement: Measurement) -> tuple[FuzzyState, ControlOutput]:
        f, d = self.fuzzy, self.design
        if state.stopped:
            return state, ControlOutput(0.0, engaged=False, stop=True)
        error = measurement.force_N - d.reference_force_N
        a = math.exp(-d.dt_s / f.trend_filter_s)
        raw_trend = (error - state.previous_error_N) / d.dt_s
        trend = a * state.trend_N_s + (1.0 - a) * raw_trend
        since = state.since_switch_s + d.dt_s
        if since < f.switch_settle_s:
            trend = 0.0  # the controller's own switch, settling (``switch_settle_s``)
        previous_ratio = f.stages[state.stage]
        change, stop_strength = self.infer(error, trend, previous_ratio)

        protection = state.protection_time_s + d.dt_s if stop_strength >= f.stop_strength else 0.0
        if stop_strength >= f.stop_strength and protection >= f.stop_hold_s:
            stopped = FuzzyState(
                state.internal_ratio, state.stage, trend, error, protection, True, since
            )
            return stopped, ControlOutput(0.0, engaged=False, stop=True)

        stages = f.stages
        internal = state.internal_ratio + change * f.max_rate_per_s * d.dt_s
        internal = min(max(internal, stages[0]), stages[-1])
        force_now = max(measurement.force_N, 0.0)
        internal, stage = _next_stage(
            stages, state.stage, internal, force_now, d, f.hysteresis, f.stage_up_margin
        )
        if stage != state.stage:
            since = 0.0
        new_state = FuzzyState(internal, stage, trend, error, protection, False, since)
        return new_state, ControlOutput(stages[stage])

    def describe(self) -> dict[str, float | str]:
        e_span, de_span = self.spans
        return {
            "stages": ", ".join(f"{s:g}" for s in self.fuzzy.stages),
            "error_span_N": e_span,
            "trend_span_N_s": de_span,
            "max_rate_per_s": self.fuzzy.max_rate_per_s,
            "rules": len(RULE_BASE),
        }


def _next_stage(
    stages: tuple[float, ...],
    stage: int,
    internal: float,
    force_now_N: float,
    design,
    hysteresis: float,
    up_margin: float = 0.0,
) -> tuple[float, int]:
    """The stage the internal ratio selects, with hysteresis: up while the force the next stage
    would cause (F * (r_next / r)^beta, the process model) stays below the reference less
    ``up_margin`` of it (else the internal ratio is held at the switch level), down past the
    lower switch level. Returns
    (internal ratio, stage)."""
    beta = design.nominal_feed_exponent
    while stage + 1 < len(stages) and internal > _switch_level(stages, stage, +1, hysteresis):
        predicted = force_now_N * (stages[stage + 1] / stages[stage]) ** beta
        if predicted >= design.reference_force_N * (1.0 - up_margin):
            internal = _switch_level(stages, stage, +1, hysteresis)
            break
        stage += 1
    while stage > 0 and internal < _switch_level(stages, stage, -1, hysteresis):
        stage -= 1
    return internal, stage


def _switch_level(
    stages: tuple[float, ...], stage: int, direction: int, hysteresis: float
) -> float:
    """Internal ratio beyond which the output moves one stage up (+1) or down (-1)."""
    other = stage + direction
    mid = 0.5 * (stages[stage] + stages[other])
    return mid + direction * hysteresis * abs(stages[other] - stages[stage])
