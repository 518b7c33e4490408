"""Every number at the REST boundary comes from ``robomach_core.limits`` (issue 19, R3, R11):
the post-processing tolerance is 0.01-5 mm as the CLI says (the API took (0, 10]); a push is
at most 200 N, 20 N*m and 10 s (it took 1e308 N and 60 s); and a diagonal push moves no faster
than the documented 50 mm/s (the per-axis clip let it reach 86.6 mm/s). In process."""

from __future__ import annotations

import re

import numpy as np
import pytest

from robomach_core import limits

PUSH = "/api/leadthrough/push"


@pytest.mark.parametrize("tolerance_mm", [0.001, 0.0099, 5.01, 10.0])
def test_post_processing_tolerances_outside_limits_are_refused(client, tolerance_mm):
    for field in ("tolerance_mm", "arc_tolerance_mm"):
        r = client.post("/api/postprocess", json={field: tolerance_mm})
        assert r.status_code == 422, r.text
        assert field in r.json()["detail"]


def test_the_schema_advertises_the_limits_ranges(client):
    schema = client.get("/openapi.json").json()["components"]["schemas"]
    tol = schema["PostprocessUpdate"]["properties"]["tolerance_mm"]["anyOf"][0]
    assert (tol["minimum"], tol["maximum"]) == (limits.TOLERANCE_MM.min, limits.TOLERANCE_MM.max)
    push = schema["PushCreate"]["properties"]
    assert push["duration_s"]["maximum"] == limits.PUSH_DURATION_S.max
    assert push["force_N"]["items"]["maximum"] == limits.PUSH_FORCE_N.max
    assert push["torque_Nm"]["items"]["maximum"] == limits.PUSH_TORQUE_NM.max


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"force_N": [1e308, 0, 0], "duration_s": 0.1}, "force_N"),
        ({"force_N": [10, 0, 0], "duration_s": 60}, "duration_s"),
        ({"force_N": [10, 0, 0], "duration_s": 10.5}, "duration_s"),
        ({"force_N": [150, 150, 0], "duration_s": 0.1}, r"push force magnitude \[N\] must be"),
        ({"force_N": [0, 0, 0], "torque_Nm": [15, 15, 0], "duration_s": 0.1}, "torque magnitude"),
        ({"force_N": [0, 0, 0], "torque_Nm": [25, 0, 0], "duration_s": 0.1}, "torque_Nm"),
    ],
)
def test_pushes_outside_the_limits_are_refused(client, body, needle):
    r = client.post(PUSH, json=body)
    assert r.status_code == 422, r.text
    assert re.search(needle, r.json()["detail"]), r.json()["detail"]


def test_a_diagonal_push_is_no_faster_than_a_straight_one(client):
    client.post("/api/leadthrough/home")
    client.put("/api/leadthrough/compliance", json={"axes": ["x", "y", "z"], "frame": "base"})
    speeds = []
    for force in ([190.0, 0.0, 0.0], [-109.0, -109.0, 109.0]):  # both well past the limit
        p0 = np.array(client.get("/api/state").json()["tcp"]["position_mm"])
        r = client.post(PUSH, json={"force_N": force, "duration_s": 0.4})
        assert r.status_code == 200, r.text
        p1 = np.array(r.json()["tcp"]["position_mm"])
        speeds.append(np.linalg.norm(p1 - p0) / 0.4)
    straight, diagonal = speeds
    assert straight == pytest.approx(50.0, abs=3.0)  # mm/s, after a few ms of acceleration
    assert diagonal <= 50.0 + 1e-6, f"{diagonal:.1f} mm/s"
    assert diagonal == pytest.approx(straight, abs=2.0)
