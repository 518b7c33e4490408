"""The check's findings (``GuideWarning``: a point, its rule, the message and a severity).

The check before a run (``checks.guide_point_warnings``) finds one thing per guide point; how
the pages show them, one line per rule with its other points named, is the app's
(``app.findings``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

GuideRule = Literal[
    "wall_side",
    "route",
    "heavy_contact",
    "touching_without_push",
    "far_from_wall",
    "in_material",
    "nearer_other_wall",
    "against_setting",
    "on_floor",
    "leg_through_part",
    "too_close",
    "wrist_turn",
    "joint_limit",
    "singularity",
    "reach",
    "clearance",
    "tolerance",
]
Severity = Literal["refusal", "warning", "info"]


@dataclass(frozen=True)
class GuideWarning:
    """One finding about the guide points.

    Attributes:
        point: 1-based guide point number (as the GUIs list them); 0 for the whole route.
        rule: Which rule (``GuideRule``).
        message: What is wrong and what to do, for the operator.
        severity: "refusal" (learning will not start), "warning" or "info".
    """

    point: int
    rule: GuideRule
    message: str
    severity: Severity = "warning"
