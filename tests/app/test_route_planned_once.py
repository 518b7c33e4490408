"""The check of the guide points plans their route once, a refused one too.

The workbench's rules panel, its wall preview and GET /api/path-learning/check read one route
per set of guide points and settings (``Learning._checked_route``), and ``project.guide_check``
hands the route it planned to the findings. A refused route was planned again to say why:
twice in ``guide_check``, three times for one check in the session, and once more for the
preview. The refusal is now handed over like a route. Counted with the real planner wrapped
(``plan_route`` in the two modules that call it).
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from app.session import Session
from robomach_core import project as core
from robomach_core.learning import checks
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.project import _stages


@pytest.fixture
def plans(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """One entry per call of the real ``plan_route``."""
    calls: list[int] = []
    for module in (checks, _stages):
        planner = module.plan_route

        def counted(*args, _planner=planner, **kwargs):
            calls.append(1)
            return _planner(*args, **kwargs)

        monkeypatch.setattr(module, "plan_route", counted)
    return calls


def test_a_refused_route_is_planned_once_and_said_first(plans: list[int]) -> None:
    session = Session(real_time=False)
    try:
        first = session.robot.record()
        T = first.T_base_tcp.copy()
        T[2, 3] += 0.008  # straight above it: a route with one height at one place is refused
        view = session.view()
        project = replace(view.project, guide_points=(first, replace(first, T_base_tcp=T)))
        findings, route = core.guide_check(project, view.cell, PathLearningSettings())
        assert route is None
        assert (findings[0].rule, findings[0].severity) == ("route", "refusal")
        assert "one above the other" in findings[0].message
        assert len(plans) == 1, f"the refused route was planned {len(plans)} times"
    finally:
        session.close()


def test_the_session_checks_and_preview_share_one_refused_plan(plans: list[int]) -> None:
    session = Session(real_time=False)
    try:
        session.record_guide_point()
        session.commit(
            lambda p: core.with_guide_point_added(p, _above(p.guide_points[0])), "guides"
        )
        first = session.learning.guide_findings()
        again = session.learning.guide_findings()
        points, line = session.learning.taught_wall_preview()
        assert first == again and first[0].severity == "refusal"
        assert points == [] and "one above the other" in line
        assert len(plans) == 1, f"the refused route was planned {len(plans)} times"
    finally:
        session.close()


def _above(point):
    T = point.T_base_tcp.copy()
    T[2, 3] += 0.008
    return replace(point, T_base_tcp=T)
