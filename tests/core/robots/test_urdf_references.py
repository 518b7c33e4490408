"""A robot upload's mesh references name files of the upload only (issue 32, point 1).

A ``<mesh filename>`` with an absolute path or ``file://`` passed the upload check and the
scene loaded it from the server's disk once per link: a 31 KB URDF naming a 25 MB mesh from
120 links took a server from 3.1 to 6.2 GB. Now every reference must name a member of the zip
(or, in a bare URDF, a mesh of the installed example-robot-data), its file counted once per
reference, and the scene's resolver cannot leave the arm's folder.
"""

from __future__ import annotations

import io
import random
import zipfile
from pathlib import Path

import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.robots import abb, registry
from robomach_core.robots.custom import RobotFileError, mesh_path, register_urdf
from robomach_core.robots.registry import sanitised_mesh
from robomach_core.robots.urdf_check import (
    MAX_ROBOT_UNPACKED_BYTES,
    check_urdf_text,
    reference_problem,
    resolve_reference,
)


def arm_with_meshes(refs: list[str]) -> str:
    """The IRB 4400 with one visual mesh per reference, spread over its links."""
    text = abb.urdf_text(abb.ABB_ARMS["irb4400"])
    links = [f"link_{i}" for i in range(1, 7)]
    for i, ref in enumerate(refs):
        link = links[i % len(links)]
        visual = f'<visual><geometry><mesh filename="{ref}"/></geometry></visual>'
        text = text.replace(f'<link name="{link}">', f'<link name="{link}">{visual}', 1)
    return text


def zipped(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return buf.getvalue()


def sphere_stl(subdivisions: int = 3) -> bytes:
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.05).export(
        file_type="stl"
    )


@pytest.mark.parametrize(
    ("ref", "needle"),
    [
        ("/etc/robomach/big.stl", "is an absolute path"),
        ("file:///tmp/big.stl", "is a file:// URL"),
        ("package://arm/../../../../etc/x.stl", r"climbs out of its folder"),
        ("../outside.stl", r"climbs out of its folder"),
        ("https://example.com/a.stl", "is a https:// URL"),
        ("package://arm/meshes/a.glb", "is a .glb file"),
        ("package://arm/meshes/missing.stl", "names no file of the zip"),
        ("C:/meshes/a.stl", "is an absolute path"),
    ],
)
def test_a_zip_whose_mesh_reference_leaves_the_upload_is_refused_naming_it(
    ref: str, needle: str
) -> None:
    data = zipped(
        {"arm/robot.urdf": arm_with_meshes([ref]).encode(), "arm/meshes/a.stl": sphere_stl()}
    )
    with pytest.raises(RobotFileError, match=needle) as refused:
        register_urdf("arm.zip", data)
    assert ref[:40] in str(refused.value)


def test_a_bare_urdf_brings_no_meshes_but_example_robot_data_s(tmp_path: Path) -> None:
    stl = tmp_path / "big.stl"
    stl.write_bytes(sphere_stl())
    with pytest.raises(RobotFileError, match="names no file of the upload"):
        register_urdf("arm.urdf", arm_with_meshes(["package://arm/meshes/a.stl"]).encode())
    with pytest.raises(RobotFileError, match="is an absolute path"):
        register_urdf("arm.urdf", arm_with_meshes([str(stl)]).encode())
    # A UR5 copied out of example-robot-data names that package's meshes: they come along.
    ur5 = (registry.robots_directory() / "ur_description/urdf/ur5_robot.urdf").read_bytes()
    name = register_urdf("my_ur5.urdf", ur5)
    members = dict(registry.arm(name).meshes)
    assert members
    assert all(m.startswith("example-robot-data/robots/ur_description/") for m in members)


def test_a_mesh_counts_once_per_reference_to_it() -> None:
    stl = sphere_stl(4)  # 5120 triangles, 256 KB
    per_reference = len(stl)
    fits = MAX_ROBOT_UNPACKED_BYTES // per_reference - 10
    refs = ["package://arm/meshes/a.stl"]
    ok = zipped({"arm/robot.urdf": arm_with_meshes(refs * fits).encode(), "arm/meshes/a.stl": stl})
    register_urdf("ok.zip", ok)
    too_many = zipped(
        {"arm/robot.urdf": arm_with_meshes(refs * (fits + 20)).encode(), "arm/meshes/a.stl": stl}
    )
    with pytest.raises(RobotFileError, match=rf"{fits + 20} mesh references load .* more than 100"):
        register_urdf("many.zip", too_many)


def test_the_scene_reads_an_uploads_meshes_from_its_own_folder_only() -> None:
    stl = sphere_stl()
    data = zipped(
        {"arm/robot.urdf": arm_with_meshes(["package://arm/meshes/a.stl"]).encode(),
         "arm/meshes/a.stl": stl, "arm/meshes/unreferenced.stl": stl}
    )  # fmt: skip
    record = registry.arm(register_urdf("scene.zip", data))
    folder = record.urdf_path().parent.resolve()
    found = Path(mesh_path(record, "package://arm/meshes/a.stl"))
    assert found.parent.parent.parent == folder and found.read_bytes() == stl
    for other in ("package://arm/meshes/unreferenced.stl", "/etc/passwd", "file:///etc/passwd",
                  "package://arm/../../../../etc/passwd", str(found)):  # fmt: skip
        assert mesh_path(record, other) == ""
    from app.gui.arm import load_urdf

    urdf = load_urdf(record.name)  # yourdfpy through the resolver: the mesh is drawn
    assert urdf.scene is not None and len(urdf.scene.geometry) >= 1


PIECES = ["..", ".", "", "etc", "passwd", "arm", "meshes", "a.stl", "b.obj", "/", "C:", "~"]


@given(
    st.lists(st.sampled_from(PIECES), min_size=1, max_size=8),
    st.sampled_from(["", "package://", "package://arm/", "file://", "/", "\\\\", "http://"]),
    st.integers(0, 2**32 - 1),
)
@settings(max_examples=300, deadline=None)
def test_no_reference_resolves_outside_the_upload_s_members(
    pieces: list[str], prefix: str, seed: int
) -> None:
    members = ["arm/meshes/a.stl", "arm/meshes/b.obj", "meshes/a.stl", "a.stl"]
    rng = random.Random(seed)
    ref = prefix + rng.choice(["/", "\\"]).join(pieces)
    member = resolve_reference(ref, members)
    if member is not None:
        assert member in members and reference_problem(ref) is None
        assert ".." not in ref.replace("\\", "/").split("/")
        assert not ref.startswith(("/", "file:", "\\"))
        assert "://" not in ref.replace("package://", "")


def test_a_mesh_s_own_references_to_other_files_are_dropped() -> None:
    obj = b"mtllib /etc/passwd\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    clean = sanitised_mesh("a.obj", obj)
    assert b"mtllib" not in clean and b"usemtl" not in clean and b"f 1 2 3" in clean
    dae = (b"<library_images><image id='t'><init_from>/etc/passwd</init_from></image>"
           b"<image id='u'><init_from><ref>file:///x/y.png</ref></init_from></image>"
           b"</library_images><init_from>t</init_from>")  # fmt: skip
    clean = sanitised_mesh("a.dae", dae)
    assert b"/etc/passwd" not in clean and b"file://" not in clean
    assert b"<init_from>t</init_from>" in clean  # an image id an effect points at stays


@pytest.mark.parametrize(
    "bad",
    ['<origin xyz="inf 0 0" rpy="0 0 0"/>', '<origin xyz="0 0 0" rpy="0 nan 0"/>',
     '<origin xyz="1e999 0 0"/>'],
)  # fmt: skip
def test_a_non_finite_number_is_refused_naming_its_element(bad: str) -> None:
    text = abb.urdf_text(abb.ABB_ARMS["irb4400"]).replace(
        '<link name="link_2">', f'<link name="link_2"><visual>{bad}<geometry>'
        '<box size="0.1 0.1 0.1"/></geometry></visual>', 1
    )  # fmt: skip
    with pytest.raises(RobotFileError, match=r"link 'link_2': <origin .* is not a finite number"):
        check_urdf_text(text, "arm.urdf", RobotFileError)
    with pytest.raises(RobotFileError, match="not a finite number"):
        register_urdf("arm.urdf", text.encode())
