"""The feed controllers designed for the cut they run on: what a process engineer sets from the
stock's deepest cut, the force limit and the arm.

PROBLEM   A controller's defaults are the papers' (two-stage 0.5 / 1.0 at 100 mm/s; the Lund
          LQ with 50 N/mm and Df = 1 N s/mm). On a casting whose allowance itself varies by
          a factor of ten, the paper's low stage cannot keep the limit on the thickest spot, so
          the two-stage controller's failure-protection rule stops the robot on a burr it was
          meant to handle; and an LQ designed for a 0.5 s force lag oscillates on a cut whose
          force follows the feed within milliseconds.
STRATEGY  Design each controller from what is known before the cut (the nominal process
          F = K d^alpha f^beta, eq. 5 of the MRR paper, at the stock's deepest cut; the force
          limit; the arm's stiffness along the wall normal), as the papers did for theirs:
          - two-stage (MRR paper sec. III-D, fig. 9: "two-stage switch control (0.5, 1.0) is
            sufficient to keep the system under spindle limit"): the low stage is the paper's
            0.5, lowered where needed so that the deepest cut at the low stage stays under the
            limit and under the force at which the protection rule starts to fire (with a 5 %
            margin), f_low = (F / (K d_max^alpha))^(1/beta) (inverse of eq. 5); the rule then
            fires only on a real failure (a force the design did not allow for), not on the
            burrs the low stage was chosen for;
          - adaptive LQ (Lund paper sec. 2.1 and 4): Kf is the interaction stiffness "of the
            workpiece, the tool and the robot" measured by a contact experiment, here the
            arm's stiffness along the wall normal, 1 / (n^T C u) averaged along the path
            (chapter eq. 19); the RLS starts from the prior Df0 = Fr / f_r, f_r the feed at
            which the nominal process at the deepest cut gives Fr (eq. 9's steady state
            F = Df v); and the constant start-up feed never exceeds the one that keeps the
            limit at the deepest cut, so the cut cannot pass the limit while Df converges;
            the LQ is re-solved when Df_hat has moved by 10 %;
          - the PI and fuzzy controllers keep the papers' designs (eqs. 12-15; five stages).
SOLUTION  ``designed_controller_settings`` returns the controller's settings for this cut; the
          run records them, and the exported FC SpeedChange block carries the same stages.
"""

from __future__ import annotations

import math
from dataclasses import replace

from ..cmrr.controllers import (
    AdaptiveLqSettings,
    ControllerSettings,
    FuzzySettings,
    TwoStageSettings,
    settings_for,
)
from .settings import MachiningSettings

MM = 1e-3
# The MRR paper's two-stage switching (0.5, 1.0).
PAPER_LOW_SPEED_RATIO = 0.5
# A low stage below this is a crawl, not a cut (the MRR paper's minimal feed): the design
# does not go lower, and a cut that needs it trips the protection rule.
LOWEST_DESIGN_RATIO = 0.05
# The two-stage design keeps the deepest cut this far under the protection rule's onset.
PROTECTION_MARGIN = 0.95
# The staged controllers hold their trend input this long after their own stage change
# (``FuzzySettings.switch_settle_s``): eq. (1)'s slow pole (15 ms), the force lag and the
# 20 Hz filter settle within it, and at the 10 mm/s speed cap it is at most 1 mm of path, a
# fraction of a burr's 4-8 mm.
SWITCH_SETTLE_S = 0.1
# ... and go a stage up only if the force predicted there stays 5 % under the reference
# (``FuzzySettings.stage_up_margin``): the sensor's noise no longer decides, and a stretch at
# the next stage does not come and go with it. Both make the stage switches of a cut
# repeatable, which offline compensation needs (two-stage: 58-65 % -> 74-81 % over 24 stocks).
STAGE_UP_MARGIN = 0.05
# The LQ is re-designed when Df_hat moves 10 % (the Lund paper re-solves "continuously"): a
# casting's Df spans a factor of ten, and a Riccati solution per 2 % step was 7 s of a 2 s cut.
LQ_RESOLVE_TOLERANCE = 0.1


def safe_speed_ratio(settings: MachiningSettings, max_depth_m: float, speed_m_s: float) -> float:
    """The speed ratio at which the nominal process at the deepest cut gives the force limit
    (inverse of eq. 5), capped at 1; 1 where there is nothing to cut."""
    if max_depth_m <= 0.0 or speed_m_s <= 0.0:
        return 1.0
    feed = settings.process.feed_for_force(settings.force_limit_N, max_depth_m)
    return min(1.0, feed / speed_m_s) if math.isfinite(feed) else 1.0


def designed_controller_settings(
    settings: MachiningSettings,
    *,
    max_depth_m: float,
    speed_m_s: float,
    interaction_stiffness_N_m: float | None = None,
) -> ControllerSettings | None:
    """The controller's settings for this cut (module docstring); the user's own
    ``settings.controller_settings`` win; None for the constant feed."""
    name = settings.controller
    if name == "constant":
        return None
    if settings.controller_settings is not None:
        return settings.controller_settings
    safe = safe_speed_ratio(settings, max_depth_m, speed_m_s)
    if name == "two-stage":
        # The deepest cut at the low stage stays under the limit and, with a margin, under
        # the force at which the protection rule (PB error at the low stage) starts to fire:
        # e / span >= 1 - (1 - stop strength) / 2 of the triangular PB set.
        paper = TwoStageSettings()
        span = paper.error_span_fraction * settings.reference_N
        onset = settings.reference_N + span * (1.0 - 0.5 * (1.0 - paper.stop_strength))
        target = min(settings.force_limit_N, PROTECTION_MARGIN * onset)
        ratio = safe_speed_ratio(replace(settings, force_limit_N=target), max_depth_m, speed_m_s)
        low = min(PAPER_LOW_SPEED_RATIO, max(ratio, LOWEST_DESIGN_RATIO))
        return TwoStageSettings(
            low_speed_ratio=round(low, 3),
            switch_settle_s=SWITCH_SETTLE_S,
            stage_up_margin=STAGE_UP_MARGIN,
        )
    if name == "adaptive-lq":
        defaults = AdaptiveLqSettings()
        process = settings.process
        kf_design = process.force_gain_N(max_depth_m) if max_depth_m > 0.0 else 0.0
        prior = None
        if kf_design > 0.0:
            try:
                feed_r_mm_s = (settings.reference_N / kf_design) ** (1.0 / process.feed_exponent)
            except OverflowError:  # a force that hardly grows with the feed (beta 0.01): no
                feed_r_mm_s = math.inf  # feed gives the reference, and there is no prior
            if math.isfinite(feed_r_mm_s) and feed_r_mm_s > 0.0:
                prior = settings.reference_N / feed_r_mm_s
        stiffness = None
        if interaction_stiffness_N_m is not None and interaction_stiffness_N_m > 0.0:
            # As a contact experiment gives it, to two digits (and the same design, and the same
            # cached Riccati solutions, for every rehearsal of a corrected program).
            stiffness = float(f"{interaction_stiffness_N_m * MM:.2g}")
        return AdaptiveLqSettings(
            resolve_tolerance=LQ_RESOLVE_TOLERANCE,
            startup_speed_ratio=min(defaults.startup_speed_ratio, max(safe, LOWEST_DESIGN_RATIO)),
            initial_removal_N_s_mm=prior if prior is not None and 1e-6 < prior < 1e9 else None,
            stiffness_N_mm=stiffness,
        )
    if name == "fuzzy":
        return FuzzySettings(switch_settle_s=SWITCH_SETTLE_S, stage_up_margin=STAGE_UP_MARGIN)
    return settings_for(name)
