"""The check's findings as every page shows them (``app/findings.py``): one line per rule,
refusals first, every other point of the rule named once. Findings drawn fresh each run
(hypothesis prints the failing example)."""

from __future__ import annotations

from typing import get_args

from hypothesis import given
from hypothesis import strategies as st

from app.findings import SEVERITY_ORDER, grouped_findings
from robomach_core.learning import GuideWarning
from robomach_core.learning.findings import GuideRule, Severity

RULES = get_args(GuideRule)[:5]
findings = st.lists(
    st.builds(
        GuideWarning,
        point=st.integers(0, 14),
        rule=st.sampled_from(RULES),
        message=st.text("abc ", min_size=1, max_size=8),
        severity=st.sampled_from(get_args(Severity)),
    ),
    max_size=20,
)


@given(findings)
def test_one_line_per_rule_refusals_first_every_point_named(found: list[GuideWarning]) -> None:
    groups = grouped_findings(found)
    assert sorted(g.rule for g in groups) == sorted({f.rule for f in found})
    ranks = [SEVERITY_ORDER[g.severity] for g in groups]
    assert ranks == sorted(ranks)
    for g in groups:
        same_rule = [f for f in found if f.rule == g.rule]
        assert g.first == same_rule[0]
        assert g.also_at == tuple(f.point for f in same_rule[1:] if f.point)
        if g.also_at:
            assert g.text().endswith(f"(the same at {', '.join(f'G{k}' for k in g.also_at)})")
        else:
            assert g.text() == g.first.message
