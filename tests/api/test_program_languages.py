"""The registry of program languages: a language registered there alone shows in the CLI's
choices, the export route and the OpenAPI schema; arms, built-in or uploaded, are offered
their controller's languages only (in process, TestClient)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

import robomach_core.export.languages as registry
from app.cli import build_parser
from robomach_core import project as core
from robomach_core.export.krl_check import check_krl_program
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.part import builtin_workpiece
from tests.conftest import app_client
from tests.core.project.test_project import _guide, _recording

TOY = registry.ProgramLanguage(
    name="toy",
    title="Toy Script",
    suffixes=(".toy",),
    write=lambda context: (
        f"TOY {context.module_name}\n"
        + "".join(f"GO {p[0]:.4f} {p[1]:.4f} {p[2]:.4f}\n" for p in context.targets.position_m),
    ),
    families=("ur",),
)


def processed_project_file(folder: Path, robot: str = "ur10") -> Path:
    """A processed project (the synthetic straight pass of tests/core/project/test_project on the
    block, moved to where the block sits for ``robot``, its joints that arm's) as
    project.npz."""
    from robomach_core.cell import GuidePoint, Robot
    from robomach_core.part import default_T_base_wobj

    shift = default_T_base_wobj(robot)[:3, 3] - default_T_base_wobj("ur10")[:3, 3]
    recording = _recording()
    T0 = np.eye(4)
    T0[:3, :3] = np.diag([1.0, -1.0, -1.0])  # the tool down
    T0[:3, 3] = recording.position_m[0] + shift
    q0 = Robot(robot).ik(T0)
    recording = replace(
        recording,
        position_m=recording.position_m + shift,
        quaternion_wxyz=np.tile([0.0, 1.0, 0.0, 0.0], (len(recording), 1)),
        joints_rad=np.tile(q0, (len(recording), 1)),
    )
    guides = []
    for g in (_guide(0.76), _guide(0.84)):
        T = g.T_base_tcp.copy()
        T[:3, :3] = T0[:3, :3]
        T[:3, 3] += shift
        guides.append(GuidePoint(T, q0, g.time_s))
    workpiece = builtin_workpiece("block", robot=robot)
    project = core.Project(
        cell=core.CellSettings(robot=robot, workpiece="block"), guide_points=tuple(guides)
    )
    learned = core.LearnedPath(
        recording,
        np.tile([0.0, 1.0, 0.0, 0.0], (2, 1)),
        PathLearningSettings(closed=False),
        core.recording_inputs_key(project),
    )
    result = core.process(learned, project.post_settings, workpiece, project.cell.tool_radius_m)
    project = replace(project, learned=learned, processed=result)
    return core.save_project_file(project, folder / f"{robot}.npz")


@pytest.fixture(scope="module")
def project_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return processed_project_file(tmp_path_factory.mktemp("ur10"))


@pytest.fixture
def toy() -> Iterator[registry.ProgramLanguage]:
    registry.register_language(TOY)
    try:
        yield TOY
    finally:
        registry.unregister_language("toy")


@contextmanager
def _client(project_file: Path) -> Iterator[TestClient]:
    with app_client() as client:
        files = {"file": ("project.npz", project_file.read_bytes())}
        r = client.post("/api/projects/import", files=files, params={"name": "languages"})
        assert r.status_code == 201, r.text
        yield client


def _language_choices() -> list[str]:
    parser = build_parser()
    demo = next(
        action.choices["demo"]
        for action in parser._subparsers._group_actions  # noqa: SLF001 (argparse has no API)
    )
    return list(next(a for a in demo._actions if a.dest == "language").choices)  # noqa: SLF001


def test_a_language_registered_alone_is_in_the_cli_the_route_and_openapi(toy, project_file):
    assert "toy" in _language_choices()
    with _client(project_file) as client:
        schema = client.get("/openapi.json").json()
        route = schema["paths"]["/api/export/program/{language}"]["get"]
        (param,) = [p for p in route["parameters"] if p["name"] == "language"]
        ref = param["schema"]["$ref"].rsplit("/", 1)[-1]
        assert "toy" in schema["components"]["schemas"][ref]["enum"]
        offered = {lang["name"]: lang for lang in client.get("/api/export/languages").json()}
        assert offered["toy"]["offered"] and offered["toy"]["files"] == ["program.toy"]
        r = client.get("/api/export/program/toy")
        assert r.status_code == 200, r.text
        assert 'filename="program.toy"' in r.headers["content-disposition"]
        lines = r.text.splitlines()
        assert lines[0] == "TOY LearnedPath" and lines[1].startswith("GO ")
        saved = client.post("/api/exports", json={"name": "with-toy"}).json()
        assert "program.toy" in saved["files"]  # program_files writes every offered language


def test_without_registration_the_route_refuses_the_language(project_file):
    assert "toy" not in _language_choices()
    with _client(project_file) as client:
        r = client.get("/api/export/program/toy")
        assert r.status_code == 422
        assert "rapid" in r.json()["detail"] and "krl" in r.json()["detail"]
        schema = client.get("/openapi.json").json()
        names = {lang["name"] for lang in client.get("/api/export/languages").json()}
        assert names == {"rapid", "urscript", "krl"}
        assert "/api/export/program/{language}" in schema["paths"]


def test_an_arm_is_served_only_its_controllers_languages(project_file):
    with _client(project_file) as client:
        offered = {x["name"] for x in client.get("/api/export/languages").json() if x["offered"]}
        assert offered == {"rapid", "urscript"}  # the UR10: URScript, and RAPID beside it
        assert client.get("/api/export/program/urscript").text.startswith("def learned_path():")
        r = client.get("/api/export/program/krl")
        assert r.status_code == 422 and "does not run KUKA KRL" in r.json()["detail"]
        assert client.put("/api/cell", json={"robot": "irb4400"}).status_code == 200
        offered = {x["name"] for x in client.get("/api/export/languages").json() if x["offered"]}
        assert offered == {"rapid"}  # an IRB 4400 is no longer offered program.script
        for path in ("/api/export/program/urscript", "/api/export/urscript"):
            r = client.get(path)
            assert r.status_code == 422 and "does not run UR URScript" in r.json()["detail"]
        assert client.put("/api/cell", json={"robot": "kr270"}).status_code == 200
        offered = {x["name"] for x in client.get("/api/export/languages").json() if x["offered"]}
        assert offered == {"krl"}


def test_a_kuka_program_downloads_as_a_zip_or_one_file(tmp_path):
    """On the KR 270 (the block placed for it) the pair comes as a zip, or file by file; the
    project's KRL checker accepts it. Force control is refused: KRL has no variant here."""
    import io
    import zipfile

    with _client(processed_project_file(tmp_path, "kr270")) as client:
        offered = {x["name"] for x in client.get("/api/export/languages").json() if x["offered"]}
        assert offered == {"krl"}
        assert client.get("/api/export/rapid").status_code == 422
        r = client.get("/api/export/program/krl")
        assert r.status_code == 200, r.text
        assert r.headers["content-type"] == "application/zip"
        archive = zipfile.ZipFile(io.BytesIO(r.content))
        assert sorted(archive.namelist()) == ["program.dat", "program.src"]
        src = client.get("/api/export/program/krl", params={"file": "program.src"}).text
        dat = client.get("/api/export/program/krl", params={"file": "program.dat"}).text
        assert archive.read("program.src").decode() == src
        info = check_krl_program(src, dat, stem="program")
        assert len(info.motions) >= 3
        r = client.get("/api/export/program/krl", params={"force_control": True})
        assert r.status_code == 422 and "no force-controlled variant" in r.json()["detail"]
        r = client.get("/api/export/program/krl", params={"file": "program.mod"})
        assert r.status_code == 422 and "program.src" in r.json()["detail"]


@pytest.fixture(scope="module")
def ur5_file(tmp_path_factory) -> Path:
    """ur5_robot.urdf copied out of example-robot-data, as a user would."""
    import shutil

    from robomach_core.cell import robots_directory

    source = robots_directory() / "ur_description/urdf/ur5_robot.urdf"
    return Path(shutil.copy(source, tmp_path_factory.mktemp("upload") / "my_ur5.urdf"))


def test_upload_over_the_api_offers_the_controllers_languages(ur5_file):
    data = ur5_file.read_bytes()
    with app_client() as client:
        r = client.post("/api/cell/robot", files={"file": (ur5_file.name, data)})
        assert r.status_code == 200, r.text
        assert re.match(r"urdf_my_ur5_[0-9a-f]{8}$", r.json()["robot"])
        offered = {x["name"] for x in client.get("/api/export/languages").json() if x["offered"]}
        assert "urscript" in offered and "krl" not in offered
        # nothing learned yet: refused for that reason, not for the language
        r = client.get("/api/export/program/urscript")
        assert r.status_code == 409, r.text
        r = client.post(
            "/api/cell/robot", files={"file": (ur5_file.name, data)}, params={"family": "kuka"}
        )
        assert r.status_code == 200 and r.json()["robot"].endswith("_kuka")
        offered = {x["name"] for x in client.get("/api/export/languages").json() if x["offered"]}
        assert offered == {"krl"}
        r = client.post(
            "/api/cell/robot", files={"file": (ur5_file.name, data)}, params={"family": "x"}
        )
        assert r.status_code == 422
