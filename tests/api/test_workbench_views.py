"""What the two pages need beside the pipeline (issue 31): a placement being tried, the
CAD-only program as a file, and what a cell change cleared."""

from __future__ import annotations

import numpy as np

from tests.api.server_process import Api

PREVIEW = "/api/cell/placement-preview"


def test_a_placement_is_tried_without_changing_the_cell(api: Api) -> None:
    placed = api.ok("GET", PREVIEW)
    assert placed["wobj_mm_deg"] is None
    assert np.allclose(placed["placed_wobj_mm_deg"], [800, 160, 0, 0, 0, 0])
    cell_before = api.ok("GET", "/api/cell")
    tried = [790.0, 150.0, 0.0, 0.0, 0.0, 25.0]
    answer = api.ok("PUT", PREVIEW, json={"wobj_mm_deg": tried})
    assert answer["wobj_mm_deg"] == tried
    assert api.ok("GET", "/api/cell") == cell_before  # nothing applied
    assert api.ok("GET", "/api/state")["busy"] is False
    r = api.put(PREVIEW, json={"wobj_mm_deg": [790.0, 150.0, 0.0, 0.0, 0.0, 400.0]})
    assert r.status_code == 422 and "rz" in r.json()["detail"], r.text
    r = api.put(PREVIEW, json={"wobj_mm_deg": [790.0, 150.0, 0.0]})
    assert r.status_code == 422, r.text
    api.ok("PUT", "/api/cell", json={"workpiece": "block"})  # a cell change drops it
    assert api.ok("GET", PREVIEW)["wobj_mm_deg"] is None
    api.ok("PUT", PREVIEW, json={"wobj_mm_deg": tried})
    assert api.ok("DELETE", PREVIEW)["wobj_mm_deg"] is None


def test_the_cad_only_program_downloads_in_the_arms_languages(api: Api) -> None:
    r = api.get("/api/export/cad-only/rapid")
    assert r.status_code == 409, r.text  # nothing post-processed yet
    api.learn()
    post = api.ok("POST", "/api/postprocess", json={})
    cad = post["cad_comparison"]
    assert cad is not None
    r = api.get("/api/export/cad-only/rapid")
    assert r.status_code == 200, r.text
    assert 'filename="cad_only_program.mod"' in r.headers["content-disposition"]
    assert "CAD-ONLY PROGRAM" in r.text
    assert f"{cad['cad_only']['max_deviation_mm']:.3f} mm" in r.text
    assert r.text.count("MoveL") >= cad["cad_only_targets"]
    r = api.get("/api/export/cad-only/urscript", params={"file": "program.script"})
    assert r.status_code == 200 and "movel" in r.text, r.text
    r = api.get("/api/export/cad-only/krl")
    assert r.status_code == 422 and "KRL" in r.json()["detail"], r.text


def test_the_pointing_settings_say_whether_anything_is_proposed(api: Api) -> None:
    assert api.ok("GET", "/api/guide-points/pointing")["proposal_points"] == 0
    proposal = api.ok("POST", "/api/guide-points/propose", json={"point_mm": [0.0, -65.0, 17.5]})
    pointing = api.ok("GET", "/api/guide-points/pointing")
    assert pointing["proposal_points"] == len(proposal["points"]) > 2
    api.ok("DELETE", "/api/guide-points/proposal", 204)
    assert api.ok("GET", "/api/guide-points/pointing")["proposal_points"] == 0
