"""Robot files are bounded before pinocchio parses them, and robot zips before extraction
(issue 19, R2 and R4).

R2: the IRB 4400 with 5,000 fixed links chained on (715 KB) overflowed pinocchio's parser
stack and killed the server. R4: a 1 MB robot zip holding a 1 GiB mesh was read into memory,
written to the robot cache and read again at every restart.
"""

from __future__ import annotations

import io
import tracemalloc
import zipfile

import pytest

from robomach_core.robots import abb, registry
from robomach_core.robots.custom import RobotFileError, register_urdf
from robomach_core.robots.urdf_check import (
    MAX_URDF_DEPTH,
    UrdfBoundsError,
    check_urdf_native,
    check_urdf_text,
    is_referenced,
    read_robot_zip,
)


def irb4400_text() -> str:
    return abb.urdf_text(abb.ABB_ARMS["irb4400"])


def with_fixed_links(text: str, n: int, *, chained: bool = True, mesh: str | None = None) -> str:
    """``text`` with ``n`` fixed links hung on tool0, one after the other or side by side."""
    extra, parent = [], "tool0"
    for i in range(n):
        visual = f'<visual><geometry><mesh filename="{mesh}"/></geometry></visual>' if mesh else ""
        extra.append(
            f'<link name="x{i}">{visual}</link><joint name="jx{i}" type="fixed">'
            f'<parent link="{parent}"/><child link="x{i}"/>'
            '<origin xyz="0 0 0.001" rpy="0 0 0"/></joint>'
        )
        parent = f"x{i}" if chained else parent
    return text.replace("</robot>", "".join(extra) + "</robot>")


def test_the_issue_s_5000_link_urdf_is_refused_before_pinocchio():
    text = with_fixed_links(irb4400_text(), 5000)
    assert 650_000 < len(text) < 800_000
    with pytest.raises(RobotFileError, match="5008 links, more than 500"):
        register_urdf("deep.urdf", text.encode())


def test_the_isolated_build_refuses_what_crashes_pinocchio():
    """Past the bounds, pinocchio itself overflows its stack: in the child, not here."""
    with pytest.raises(UrdfBoundsError, match="pinocchio cannot build this model.*SIG"):
        check_urdf_native(with_fixed_links(irb4400_text(), 5000), "deep.urdf")
    assert check_urdf_native(irb4400_text())["nq"] == 6


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (with_fixed_links(irb4400_text(), MAX_URDF_DEPTH + 5), "more than 100 joints deep"),
        (with_fixed_links(irb4400_text(), 600, chained=False), "608 links, more than 500"),
        ("<robot>" + "<a>" * 40 + "</a>" * 40 + "</robot>", "nest more than 32 deep"),
        ('<robot name="x">' + "<link name='l'/>" * 2 + " " * 2_100_000 + "</robot>", "2.1 MB"),
        (
            '<robot name="x"><link name="a"/><link name="b"/><link name="c"/>'
            '<joint name="j" type="fixed"><parent link="b"/><child link="c"/></joint>'
            '<joint name="k" type="fixed"><parent link="c"/><child link="b"/></joint></robot>',
            "not connected to the root 'a'",
        ),
    ],
    ids=["deep", "wide", "nested-xml", "huge", "loop"],
)
def test_bounds_name_what_is_exceeded(text: str, needle: str):
    with pytest.raises(UrdfBoundsError, match=needle):
        check_urdf_text(text, "arm.urdf")


def test_real_urdfs_pass_the_bounds():
    from robomach_core.cell.robot import robot_urdf_path

    for name in ("ur5", "ur10"):
        check_urdf_text(robot_urdf_path(name).read_text(), f"{name}.urdf")
    check_urdf_text(with_fixed_links(irb4400_text(), 50), "irb.urdf")


def test_references_match_by_path_tail_not_by_base_name():
    refs = ["package://arm/meshes/visual/base.stl", "../meshes/link1.stl", "file:///opt/a/b.stl"]
    assert is_referenced("arm/meshes/visual/base.stl", refs)
    assert is_referenced("meshes/visual/base.stl", refs)
    assert is_referenced("meshes/link1.stl", refs)
    assert is_referenced("a/b.stl", refs)
    assert not is_referenced("x/a/b.stl", refs)  # three parts each: they must agree
    assert not is_referenced("other/base.stl", refs)
    assert not is_referenced("meshes/collision/base.stl", refs)
    assert not is_referenced("junk.bin", refs)


def _zip(members: dict[str, bytes | int]) -> bytes:
    """A zip of named members; an int is that many zero bytes, streamed (a bomb)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        for name, content in members.items():
            if isinstance(content, int):
                with z.open(name, "w", force_zip64=True) as f:
                    block = bytes(1 << 20)
                    for _ in range(content >> 20):
                        f.write(block)
            else:
                z.writestr(name, content)
    return buf.getvalue()


MESH = "package://arm/meshes/base.stl"


@pytest.fixture(scope="module")
def bomb_zip() -> bytes:
    """A robot zip of ~0.3 MB: the URDF, a referenced 300 MB mesh of zeros."""
    text = with_fixed_links(irb4400_text(), 1, mesh=MESH)
    return _zip({"arm/robot.urdf": text.encode(), "arm/meshes/base.stl": 300 << 20})


def test_a_zip_bomb_is_refused_from_its_declared_sizes_before_extraction(bomb_zip: bytes):
    assert len(bomb_zip) < 2_000_000
    tracemalloc.start()
    try:
        with pytest.raises(RobotFileError, match="declares 314.6 MB, more than 50 MB"):
            register_urdf("arm.zip", bomb_zip)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 50e6, f"{peak / 1e6:.0f} MB"


def test_files_the_urdf_does_not_reference_are_never_read():
    text = with_fixed_links(irb4400_text(), 1, mesh=MESH)
    stl = trimesh_box_stl()
    data = _zip({"arm/robot.urdf": text.encode(), "arm/meshes/base.stl": stl,
                 "arm/junk/video.bin": 200 << 20})  # fmt: skip
    tracemalloc.start()
    try:
        name = register_urdf("arm.zip", data)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 50e6, f"{peak / 1e6:.0f} MB"
    assert dict(registry.arm(name).meshes) == {"arm/meshes/base.stl": stl}


def test_a_zip_declaring_too_many_entries_is_refused_before_listing():
    data = _zip({f"f{i}": b"" for i in range(10_001)})
    with pytest.raises(UrdfBoundsError, match="declares 10001 entries"):
        read_robot_zip("many.zip", data)


def test_a_referenced_mesh_over_the_triangle_limit_is_refused():
    text = with_fixed_links(irb4400_text(), 1, mesh=MESH)
    n = 600_000
    stl = bytes(80) + n.to_bytes(4, "little") + bytes(50 * n)
    with pytest.raises(UrdfBoundsError, match="600000 triangles"):
        read_robot_zip(
            "arm.zip", _zip({"arm/robot.urdf": text.encode(), "arm/meshes/base.stl": stl})
        )


def trimesh_box_stl() -> bytes:
    import trimesh

    return trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(file_type="stl")
