"""Projects: list, create, open, rename, delete; each holds its own work."""

from __future__ import annotations

import uuid

import pytest

from tests.api.server_process import Api

P = "/api/projects"


def _name() -> str:
    return f"p-{uuid.uuid4().hex[:8]}"


def test_create_open_rename_delete(api: Api) -> None:
    first = api.ok("GET", f"{P}/current")
    a = api.ok("POST", P, 201, json={"name": _name()})
    assert a["is_open"] and api.ok("GET", f"{P}/current")["id"] == a["id"]
    api.ok("POST", "/api/guide-points", 201)
    b = api.ok("POST", P, 201, json={"name": _name()})
    assert api.ok("GET", "/api/guide-points") == []  # a new project starts empty
    listed = {p["id"]: p for p in api.ok("GET", P)}
    assert {first["id"], a["id"], b["id"]} <= set(listed)
    assert listed[b["id"]]["is_open"] and not listed[a["id"]]["is_open"]

    opened = api.ok("POST", f"{P}/{a['id']}/open")
    assert opened["is_open"] and len(api.ok("GET", "/api/guide-points")) == 1

    new_name = _name()
    renamed = api.ok("PATCH", f"{P}/{a['id']}", json={"name": f"  {new_name}  "})
    assert renamed["name"] == new_name

    api.ok("DELETE", f"{P}/{b['id']}", 204)
    assert b["id"] not in {p["id"] for p in api.ok("GET", P)}
    # Deleting the open project opens another one.
    api.ok("DELETE", f"{P}/{a['id']}", 204)
    current = api.ok("GET", f"{P}/current")
    assert current["id"] != a["id"] and current["is_open"]


def test_duplicate_names_conflict(api: Api) -> None:
    name = _name()
    a = api.ok("POST", P, 201, json={"name": name})
    r = api.post(P, json={"name": name})
    assert r.status_code == 409 and "already exists" in r.json()["detail"]
    b = api.ok("POST", P, 201, json={"name": _name()})
    r = api.patch(f"{P}/{b['id']}", json={"name": name})
    assert r.status_code == 409
    assert api.ok("PATCH", f"{P}/{a['id']}", json={"name": name})["name"] == name


@pytest.mark.parametrize(
    ("method", "path", "body", "status"),
    [
        ("POST", P, {"name": ""}, 422),
        ("POST", P, {"name": "   "}, 422),
        ("POST", P, {"name": "x" * 81}, 422),
        ("POST", P, {"name": "tab\there"}, 422),
        ("POST", P, {}, 422),
        ("POST", f"{P}/999999/open", None, 404),
        ("POST", f"{P}/abc/open", None, 422),
        ("POST", f"{P}/{10**30}/open", None, 422),
        ("POST", f"{P}/0/open", None, 422),
        ("PATCH", f"{P}/999999", {"name": "x"}, 404),
        ("DELETE", f"{P}/999999", None, 404),
    ],
)
def test_project_errors(api: Api, method: str, path: str, body: dict | None, status: int) -> None:
    r = api.http.request(method, path, json=body)
    assert r.status_code == status and r.json()["detail"], r.text
