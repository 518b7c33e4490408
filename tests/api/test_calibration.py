"""The work object over REST: its placement in ``PUT /api/cell`` and its calibration by touch
(``/api/cell/calibration``), in process and over real HTTP on a ``robomach serve``."""

from __future__ import annotations

import numpy as np
import pytest

from tests.api.server_process import Api

CAL = "/api/cell/calibration"


@pytest.mark.parametrize(
    ("numbers", "wobj"),
    [
        ([790, 150, 0], [790, 150, 0, 0, 0, 0]),
        ([790, 150, 0, 25], [790, 150, 0, 0, 0, 25]),
        ([790, 150, 10, 1.5, -2, 25], [790, 150, 10, 1.5, -2, 25]),
    ],
)
def test_the_placement_is_set_shown_and_reset(api: Api, numbers, wobj):
    cell = api.ok("PUT", "/api/cell", json={"wobj_mm_deg": numbers})
    assert cell["wobj_mm_deg"] == pytest.approx(numbers)
    shown = cell["wobj"]
    assert [shown[k] for k in ("x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg")] == (
        pytest.approx(wobj, abs=1e-4)
    )
    assert api.ok("GET", "/api/cell")["wobj"] == shown
    # Another change keeps it; null goes back to the built-in placement.
    assert api.ok("PUT", "/api/cell", json={"tool_radius_mm": 2})["wobj_mm_deg"] == (
        pytest.approx(numbers)
    )
    reset = api.ok("PUT", "/api/cell", json={"wobj_mm_deg": None})
    assert reset["wobj_mm_deg"] is None and reset["wobj"]["x_mm"] == 800.0


@pytest.mark.parametrize(
    ("numbers", "said"),
    [
        ([790, 150], "wobj_mm_deg"),
        ([790, 150, 0, 0, 0], "x,y,z in mm"),
        ([790, 150, 0, 400], "work-object rz must be a number within -360 to 360 deg"),
        ([5000, 150, 0], "wobj_mm_deg"),
        ("790,150,0", "wobj_mm_deg"),
    ],
)
def test_a_bad_placement_is_refused_and_changes_nothing(api: Api, numbers, said):
    before = api.ok("GET", "/api/cell")
    r = api.put("/api/cell", json={"wobj_mm_deg": numbers})
    assert r.status_code == 422 and said in r.text, r.text
    assert api.ok("GET", "/api/cell") == before


def test_touches_by_hand_undo_and_refusals(api: Api):
    api.ok("POST", f"{CAL}/start", json={"force_N": 8})
    state = api.ok("POST", f"{CAL}/touches", json={"at_wobj_mm": [90, 60, 20]})
    (touch,) = state["touches"]
    assert touch["feature"] == "top" and touch["direction"] == pytest.approx([0, 0, -1])
    assert touch["force_N"] == pytest.approx(8, abs=1.5) and state["force_N"] == 8
    assert state["fit"] is None and "1 of at least 6" in state["fit_error"]
    # Upwards: nothing there within 5 mm (409, the robot stays where it searched).
    r = api.post(f"{CAL}/touches", json={"direction": [0, 0, 1], "max_travel_mm": 5})
    assert r.status_code == 409 and "no contact within 5.0 mm" in r.text
    r = api.post(f"{CAL}/accept")
    assert r.status_code == 422 and "1 of at least 6" in r.text
    assert api.ok("DELETE", f"{CAL}/touches/last")["touches"] == []
    assert api.delete(f"{CAL}/touches/last").status_code == 404
    assert api.post(f"{CAL}/touches", json={}).status_code == 422
    assert api.post(f"{CAL}/touches", json={"direction": [0, 0, 0]}).status_code == 422
    assert api.post(f"{CAL}/start", json={"force_N": 80}).status_code == 422


@pytest.mark.slow
def test_a_realistic_part_is_calibrated_over_http_and_proposals_then_stand_on_it(
    http_api: Api,
):
    api = http_api
    api.ok("PUT", "/api/cell", json={"realistic": True, "wobj_mm_deg": [790, 150, 0, 25]})
    plan = api.ok("GET", f"{CAL}/plan")
    assert len(plan["touches"]) == 9
    job = api.ok("POST", f"{CAL}/auto", 202, json={})
    assert api.wait_job(job["job_id"], timeout_s=300)["status"] == "done"
    state = api.ok("GET", CAL)
    fit = state["fit"]
    assert fit is not None, state["fit_error"]
    assert fit["method"].startswith("point-to-plane") and fit["redundancy"] == 3
    assert 1.0 < fit["turned_deg"] < 2.1 and fit["rms_mm"] < 0.5  # the preset's 1-2 deg
    assert all(t["residual_mm"] is not None for t in state["touches"])
    cell = api.ok("POST", f"{CAL}/accept")
    reg = cell["registration"]
    assert reg["touches"] == 9 and reg["wobj_mm_deg"] == pytest.approx(fit["wobj_mm_deg"], abs=1e-3)
    assert cell["wobj_mm_deg"] == [790, 150, 0, 25]  # the placement stays as set
    # Proposals now stand on the registered CAD (tests/core/teaching/test_registration.py
    # measures them against the real wall): the whole groove is proposed and every point is reached.
    wall_mm = [0.0, -65.0, 17.0]
    proposal = api.ok("POST", "/api/guide-points/propose", json={"point_mm": wall_mm})
    assert proposal["closed"] and proposal["wall_side"] == "right", proposal["notes"]
    assert len(proposal["points"]) >= 4 and {p["reach"] for p in proposal["points"]} == {"ok"}
    undone = api.ok("DELETE", CAL)
    assert undone["registration"] is None
    assert len(api.ok("GET", CAL)["touches"]) == 9
    np.testing.assert_allclose(
        [undone["wobj"][k] for k in ("x_mm", "y_mm", "rz_deg")], [790, 150, 25], atol=1e-6
    )
