"""Compliance selection, pushes and jogs, and their error cases."""

from __future__ import annotations

import numpy as np
import pytest

from tests.api.server_process import Api

PUSH = "/api/leadthrough/push"
JOG = "/api/leadthrough/jog"
COMPLIANCE = "/api/leadthrough/compliance"


def test_compliance_round_trip(api: Api) -> None:
    assert api.ok("GET", COMPLIANCE) == {"axes": ["x", "y", "z"], "frame": "base"}
    body = {"axes": ["rz", "x", "z"], "frame": "tool"}
    assert api.ok("PUT", COMPLIANCE, json=body) == {"axes": ["x", "z", "rz"], "frame": "tool"}
    assert api.ok("GET", COMPLIANCE)["frame"] == "tool"
    assert api.ok("PUT", COMPLIANCE, json={"axes": [], "frame": "base"})["axes"] == []


@pytest.mark.parametrize(
    "body",
    [
        {"axes": ["x", "w"], "frame": "base"},
        {"axes": ["x"], "frame": "world"},
        {"axes": "x", "frame": "base"},
        {"axes": ["x"]},
        {"axes": ["x"], "frame": "base", "extra": 1},
    ],
)
def test_compliance_rejects_bad_bodies(api: Api, body: dict) -> None:
    r = api.put(COMPLIANCE, json=body)
    assert r.status_code == 422 and r.json()["detail"]


def test_push_moves_along_the_force(api: Api) -> None:
    p0 = api.position_mm()
    # 10 N against 500 N*s/m damping: 20 mm/s, so ~20 mm in 1 s.
    state = api.ok("POST", PUSH, json={"force_N": [10, 0, 0], "duration_s": 1.0})
    d = np.array(state["tcp"]["position_mm"]) - p0
    assert 17.0 < d[0] < 21.0 and abs(d[1]) < 1.0 and abs(d[2]) < 1.0
    assert state["time_s"] > 1.0


def test_push_only_moves_compliant_axes(api: Api) -> None:
    api.ok("PUT", COMPLIANCE, json={"axes": ["z"], "frame": "base"})
    p0 = api.position_mm()
    state = api.ok("POST", PUSH, json={"force_N": [10, 10, 5], "duration_s": 0.5})
    d = np.array(state["tcp"]["position_mm"]) - p0
    assert abs(d[0]) < 0.5 and abs(d[1]) < 0.5 and d[2] > 3.0


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ('{"force_N": [10, 0', "not valid JSON"),
        ('{"force_N": [10, 0], "duration_s": 1}', "force_N"),
        ('{"force_N": [10, 0, 0, 0], "duration_s": 1}', "force_N"),
        ('{"force_N": ["a", 0, 0], "duration_s": 1}', "force_N"),
        ('{"force_N": [10, 0, 0], "duration_s": "long"}', "duration_s"),
        ('{"force_N": [10, 0, 0], "duration_s": 61}', "duration_s"),
        ('{"force_N": [10, 0, 0], "duration_s": -1}', "duration_s"),
        ('{"force_N": [NaN, 0, 0], "duration_s": 1}', "force_N"),
        ('{"force_N": [Infinity, 0, 0], "duration_s": 1}', "force_N"),
        ('{"force_N": [1, 0, 0], "torque_Nm": [1], "duration_s": 1}', "torque_Nm"),
        ('{"duration_s": 1}', "force_N"),
        ("", "JSON body"),
        ("[]", "valid dictionary"),
    ],
)
def test_push_rejects_bad_bodies(api: Api, content: str, needle: str) -> None:
    r = api.post(PUSH, content=content, headers={"content-type": "application/json"})
    assert r.status_code == 422, r.text
    assert needle in r.json()["detail"], r.json()


def test_jog_translates_and_rotates_in_the_tool_frame(api: Api) -> None:
    s0 = api.ok("GET", "/api/state")
    s1 = api.ok("POST", JOG, json={"axis": "z", "step": 5})
    d = np.array(s1["tcp"]["position_mm"]) - np.array(s0["tcp"]["position_mm"])
    # The tool points down at home: +z of the tool is -z of the base.
    assert abs(d[2] + 5.0) < 0.3 and np.linalg.norm(d[:2]) < 0.3
    s2 = api.ok("POST", JOG, json={"axis": "rz", "step": 10})
    q1, q2 = np.array(s1["tcp"]["quaternion_wxyz"]), np.array(s2["tcp"]["quaternion_wxyz"])
    angle = np.degrees(2 * np.arccos(min(1.0, abs(float(q1 @ q2)))))
    assert abs(angle - 10.0) < 0.5


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"axis": "q", "step": 1}, "axis"),
        ({"axis": "x", "step": 300}, "200 mm"),
        ({"axis": "rx", "step": 60}, "45 degrees"),
        ({"axis": "x"}, "step"),
        ({"axis": "x", "step": "far"}, "step"),
    ],
)
def test_jog_rejects_bad_bodies(api: Api, body: dict, needle: str) -> None:
    r = api.post(JOG, json=body)
    assert r.status_code == 422 and needle in r.json()["detail"], r.text


def test_home_resets_the_pose(api: Api) -> None:
    home = api.position_mm()
    api.ok("POST", PUSH, json={"force_N": [0, 10, 0], "duration_s": 0.5})
    state = api.ok("POST", "/api/leadthrough/home")
    assert np.allclose(state["tcp"]["position_mm"], home, atol=0.5)
