"""The check's findings (``GuideWarning``: a point, its rule, the message and a severity) and
how every page shows them: one line per rule, its other points named.

The check before a run (``checks.guide_point_warnings``) finds one thing per guide point; the
same rule broken at 14 points read as 14 lines. Every page (the workbench, the pendant, the
terminal) shows one line per rule: the first point's message, "(the same at G2, G3)", marked
by its severity, refusals first.
"""

from __future__ import annotations

from collections.abc import Sequence
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


SEVERITY_ORDER = {"refusal": 0, "warning": 1, "info": 2}


@dataclass(frozen=True)
class FindingGroup:
    """One rule's findings: the first one and the other points where it holds.

    Attributes:
        first: The first finding of the rule (its message names its point).
        also_at: The other points (1-based) where the same rule holds.
    """

    first: GuideWarning
    also_at: tuple[int, ...] = ()

    @property
    def severity(self) -> str:
        return self.first.severity

    @property
    def rule(self) -> str:
        return self.first.rule

    def text(self) -> str:
        """The first message, then "(the same at G2, G3)" when the rule holds elsewhere."""
        if not self.also_at:
            return self.first.message
        return f"{self.first.message} (the same at {', '.join(f'G{k}' for k in self.also_at)})"


def grouped_findings(found: Sequence[GuideWarning]) -> list[FindingGroup]:
    """One group per rule, refusals first, then warnings, then notes (each in the order its
    rule was first found)."""
    groups: dict[str, list[GuideWarning]] = {}
    for finding in found:
        groups.setdefault(finding.rule, []).append(finding)
    out = [
        FindingGroup(group[0], tuple(f.point for f in group[1:] if f.point))
        for group in groups.values()
    ]
    return sorted(out, key=lambda g: SEVERITY_ORDER[g.severity])
