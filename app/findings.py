"""How every page shows the check's findings: one line per rule, its other points named.

The check before a run (``robomach_core.learning.guide_point_warnings``) finds one thing per
guide point; the same rule broken at 14 points read as 14 lines. Every page (the workbench, the
pendant, the terminal) shows one line per rule: the first point's message, "(the same at G2,
G3)", marked by its severity, refusals first.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from robomach_core.learning import GuideWarning

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
