"""Issue 11 core pieces: work-object frames, user URDFs, guide-point rules, mesh score."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robomach_core.cell import TOOL_DOWN, GuidePoint, Robot
from robomach_core.cell.robot import robot_urdf_path
from robomach_core.errors import InvalidInputError
from robomach_core.export.languages import default_arm as default_robot
from robomach_core.learning.checks import guide_point_warnings
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.part import builtin_workpiece
from robomach_core.project import wobj_transform
from robomach_core.robots.custom import RobotFileError, register_urdf, validate_urdf
from robomach_core.scoring import score_mesh, score_path
from robomach_core.transforms import make_transform, rotation_about


def test_wobj_forms():
    T4 = wobj_transform([800, 160, 0, 30])
    T6 = wobj_transform([800, 160, 0, 0, 0, 30])
    np.testing.assert_allclose(T4, T6, atol=1e-12)
    T = wobj_transform([0, 0, 0, 90, 0, 90])  # about x, then about the base z
    np.testing.assert_allclose(
        T[:3, :3], rotation_about("z", np.pi / 2) @ rotation_about("x", np.pi / 2), atol=1e-12
    )
    with pytest.raises(InvalidInputError):
        wobj_transform([1, 2, 3, 4, 5])


def test_default_robot_follows_the_language():
    assert default_robot("rapid") == "irb4400"
    assert default_robot("auto") == default_robot("urscript") == "ur10"


def test_a_ur_urdf_from_example_robot_data_registers_and_matches_the_builtin():
    data = robot_urdf_path("ur5").read_bytes()
    chain = validate_urdf(data.decode())
    assert len(chain.joints) == 6 and chain.has_flange
    name = register_urdf("ur5_copy.urdf", data)
    mine, builtin = Robot(name), Robot("ur5")
    q = np.array([0.1, -1.2, 1.4, -1.5, -1.4, 0.3])
    np.testing.assert_allclose(mine.fk(q), builtin.fk(q), atol=1e-12)
    assert np.all(mine.home_rad >= mine.lower_rad) and np.all(mine.home_rad <= mine.upper_rad)


def test_a_branching_urdf_is_named():
    text = (
        '<robot name="y"><link name="a"/><link name="b"/><link name="c"/>'
        '<joint name="j1" type="revolute"><parent link="a"/><child link="b"/>'
        '<limit lower="-1" upper="1"/></joint>'
        '<joint name="j2" type="revolute"><parent link="a"/><child link="c"/>'
        '<limit lower="-1" upper="1"/></joint></robot>'
    )
    with pytest.raises(RobotFileError, match="branches"):
        validate_urdf(text)


def test_a_urdf_missing_a_link_or_joint_name_is_named_at_every_place():
    """Every link without a name, every joint end without a link and every arm joint without a
    name of the UR5's file gets its own error (a nameless last link whose joint named no child
    once passed, the chain ending in a None link; each alone was called a second root)."""
    import xml.etree.ElementTree as ET

    text = robot_urdf_path("ur5").read_text()
    root = ET.fromstring(text)
    cases = [
        (f"link {i}", ("link", i, None, "name"), "without a name")
        for i in range(len(root.findall("link")))
    ]
    for i, joint in enumerate(root.findall("joint")):
        for end in ("parent", "child"):
            cases.append((f"joint {i} {end}", ("joint", i, end, "link"), "lacks a <parent>"))
        if joint.get("type") == "revolute":
            cases.append((f"joint {i}", ("joint", i, None, "name"), "has no name"))
    assert len(cases) > 20
    for label, (tag, i, sub, attribute), message in cases:
        broken = ET.fromstring(text)
        element = broken.findall(tag)[i]
        element = element if sub is None else element.find(sub)
        del element.attrib[attribute]
        try:
            validate_urdf(ET.tostring(broken, encoding="unicode"))
        except RobotFileError as exc:
            assert message in str(exc), f"{label} without its {attribute}: {exc}"
        else:
            pytest.fail(f"{label} without its {attribute} passed")


def _guide(p, force=(0.0, 0.0, 0.0)) -> GuidePoint:
    return GuidePoint(
        make_transform(TOOL_DOWN, np.array(p, float)), np.zeros(6), 0.0, np.array(force)
    )


def test_guide_rules_flag_heavy_contact_a_touch_and_an_untold_wall_side():
    settings = PathLearningSettings(closed=False)
    # material on the right of travel: along +x, the wall at -y pushes the tool towards +y.
    wall_push = (0.0, 6.0, 0.0)
    guides = [_guide([0.0, 0.0, 0.0], wall_push), _guide([0.05, 0.0, 0.0], wall_push)]
    assert guide_point_warnings(guides, settings) == ()
    free = [_guide([0.0, 0.0, 0.0]), _guide([0.05, 0.0, 0.0], (0.0, 1.2, 0.0))]
    found = guide_point_warnings(free, settings)
    assert [(w.rule, w.severity) for w in found] == [
        ("wall_side", "refusal"),
        ("touching_without_push", "info"),
    ]
    assert "set the wall side" in found[0].message
    assert guide_point_warnings(free, replace(settings, wall_side="right")) == ()
    heavy = [_guide([0, 0, 0], (0, 40.0, 0)), _guide([0.05, 0, 0], wall_push)]
    assert [w.rule for w in guide_point_warnings(heavy, settings)] == ["heavy_contact"]


def test_mesh_score_agrees_with_the_true_wall_score():
    wp = builtin_workpiece("water_pump")
    from robomach_core.teaching import guide_plan  # noqa: F401 (the wall's frame)

    T = wp.T_base_wobj
    path = wp.wall.offset(0.001).sample(0.004)[:60]
    z = wp.wall_z_m[1] - 0.003
    pts = np.c_[path, np.full(len(path), z)] @ T[:3, :3].T + T[:3, 3]
    truth = score_path(wp, 0.001, pts)
    mesh = score_mesh(wp, 0.001, pts)
    assert mesh.max_m == pytest.approx(truth.max_m, abs=5e-5)
    assert mesh.rms_m == pytest.approx(truth.rms_m, abs=5e-5)


def test_the_ur5_learns_the_pump_where_it_is_placed_for_it():
    """At the UR10's placement (0.8 m) the UR5 met its elbow singularity before the first
    guide point; its own placement (0.525 m) is within its reach."""
    from robomach_core.pipeline import run_demo
    from robomach_core.project import CellSettings, Project

    ur5 = Project(cell=CellSettings(robot="ur5"))
    result = run_demo(ur5, PathLearningSettings(speed_m_s=0.010))
    assert result.recording.completed, result.recording.stop_reason
    assert result.score.max_m < 0.25e-3
    assert result.reachability.reachable == result.reachability.total
