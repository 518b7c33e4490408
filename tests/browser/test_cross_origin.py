"""A page from another origin tries to change the workbench through the user's browser and
fails (issue 10, item 6): the issue's attack was a page on another port of 127.0.0.1 that
recorded a guide point and replaced the workpiece by a multipart ``fetch``.

Both requests are "simple" (no preflight), so the browser sends them and only hides the
answers from the page: only the server can refuse them.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import httpx
import pytest
from playwright.sync_api import Page, Response

from tests.browser.conftest import Served

pytestmark = pytest.mark.slow

ATTACK_PAGE = b"""<!doctype html>
<html><body><p>cat pictures</p>
<script>
const STL = "solid x\\nfacet normal 0 0 1\\nouter loop\\nvertex 0 0 0\\nvertex 90 0 0\\n" +
  "vertex 0 90 0\\nendloop\\nendfacet\\nendsolid x\\n";
window.attack = async (api) => {
  const point = await fetch(api + "/api/guide-points", {method: "POST", mode: "no-cors"});
  const form = new FormData();
  form.append("file", new Blob([STL], {type: "application/octet-stream"}), "part.stl");
  const upload = await fetch(api + "/api/cell/workpiece",
    {method: "POST", mode: "no-cors", body: form});
  return [point.type, upload.type];
};
</script></body></html>
"""


class _AttackPage(BaseHTTPRequestHandler):
    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        self.send_response(200)
        self.send_header("Content-Type", "text/html; charset=utf-8")
        self.send_header("Content-Length", str(len(ATTACK_PAGE)))
        self.end_headers()
        self.wfile.write(ATTACK_PAGE)

    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture
def attacker() -> Iterator[str]:
    """The attack page on another port of 127.0.0.1."""
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), _AttackPage)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/"
    httpd.shutdown()
    httpd.server_close()
    thread.join(5)


def test_a_page_of_another_origin_cannot_change_the_workbench(
    page: Page, served: Served, api: httpx.Client, attacker: str
) -> None:
    for _ in range(2):
        assert api.post("/api/guide-points").status_code == 201
    before_points = api.get("/api/guide-points").json()
    before_cell = api.get("/api/cell").json()

    page.goto(attacker)
    statuses: dict[str, int] = {}

    def seen(response: Response) -> None:  # the browser sees the status the page may not
        if "/api/" in response.url:
            statuses[response.url.split("/api/", 1)[-1]] = response.status

    page.on("response", seen)
    kinds = page.evaluate("(api) => window.attack(api)", served.base_url)
    assert kinds == ["opaque", "opaque"]  # the browser sent both, as the page did
    page.wait_for_timeout(200)
    assert statuses == {"guide-points": 403, "cell/workpiece": 403}, statuses

    assert api.get("/api/guide-points").json() == before_points
    assert api.get("/api/cell").json() == before_cell
