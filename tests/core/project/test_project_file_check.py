"""A ``project.npz`` is checked before it is read and before it is believed (issue 19, R4, R6,
R7): a bomb of zeros is refused from its ``.npy`` header, recording arrays that disagree in
length or type are refused at import (they used to be accepted and fail every export), and
numbers far outside their ranges (positions x1e300, a work-object at 1e308 mm) are refused
at once instead of running for half a minute."""

from __future__ import annotations

import io
import json
import tracemalloc
import zipfile

import numpy as np
import pytest

from robomach_core.project import ProjectFileError, project_file_bytes, project_from_file_bytes
from tests.core.project.test_project import learned_block_project


@pytest.fixture(scope="module")
def good_bytes() -> bytes:
    return small_project_bytes()


def small_project_bytes() -> bytes:
    """A project file of two guide points and a 400-sample recording on the block."""
    return project_file_bytes(learned_block_project())


def arrays_of(data: bytes) -> dict[str, np.ndarray]:
    with np.load(io.BytesIO(data), allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def npz(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def changed(data: bytes, **arrays: np.ndarray) -> bytes:
    return npz({**arrays_of(data), **arrays})


def with_document(data: bytes, edit) -> bytes:
    arrays = arrays_of(data)
    doc = json.loads(arrays["document"].tobytes())
    edit(doc)
    arrays["document"] = np.frombuffer(json.dumps(doc).encode(), dtype=np.uint8)
    return npz(arrays)


def test_a_good_file_round_trips(good_bytes: bytes):
    project = project_from_file_bytes(good_bytes)
    assert len(project.learned.recording) == 400 and len(project.guide_points) == 2


@pytest.mark.parametrize(
    ("edit", "needle"),
    [
        (lambda a: {"rec_force_normal_N": a["rec_force_normal_N"][:-7]},
         r"differ in length \(force_normal_N has 393 samples, the others 400\)"),
        (lambda a: {"rec_in_contact": a["rec_in_contact"].astype(float)},
         "'rec_in_contact' has type float64"),
        (lambda a: {"rec_segment": a["rec_segment"].astype(float)}, "'rec_segment' has type"),
        (lambda a: {"rec_position_m": a["rec_position_m"][:, :2]}, r"shape \(400, 2\)"),
        (lambda a: {"rec_position_m": a["rec_position_m"] * 1e300}, "more than 10 m"),
        (lambda a: {"rec_yp": np.full_like(a["rec_yp"], np.nan)}, "'rec_yp' holds NaN"),
        (lambda a: {"rec_quaternion_wxyz": a["rec_quaternion_wxyz"] * 2}, "not of unit length"),
        (lambda a: {"guide_joints_rad": a["guide_joints_rad"][:1]}, "1 guide points, the doc"),
        (lambda a: {"rec_time_s": a["rec_time_s"][::-1].copy()}, "goes backwards"),
        (lambda a: {"rec_segment": a["rec_segment"] + 7}, "segments run 7-7"),
        (lambda a: {"document": np.frombuffer(b"[1, 2]", np.uint8)}, "not a robomach project"),
    ],
    ids=["length", "bool-type", "int-type", "shape", "x1e300", "nan", "quaternion", "guides",
         "time", "segment", "document"],
)  # fmt: skip
def test_inconsistent_arrays_are_refused_naming_the_array(good_bytes: bytes, edit, needle: str):
    data = changed(good_bytes, **edit(arrays_of(good_bytes)))
    with pytest.raises(ProjectFileError, match=needle):
        project_from_file_bytes(data, "p.npz")


@pytest.mark.parametrize(
    ("edit", "needle"),
    [
        (lambda d: d["cell"].update(wobj_mm_deg=[1e308, 0, 0]), "work-object x must be"),
        (lambda d: d["cell"].update(wobj_mm_deg=[800, 0, 0, 1e9]), "work-object rz must be"),
        (lambda d: d["cell"].update(tool_radius_m=1e6), "tool radius"),
        (lambda d: d["cell"].update(seed=-1), "seed"),
        (lambda d: d.update(guide_times_s=["x", 1]), "not a finite number"),
        (lambda d: d["post_settings"].update(tolerance_m=1e-9), "tolerance"),
    ],
    ids=["wobj-1e308", "wobj-rz", "radius", "seed", "times", "tolerance"],
)
def test_numbers_outside_their_ranges_are_refused_at_once(good_bytes: bytes, edit, needle):
    data = with_document(good_bytes, edit)
    with pytest.raises(ProjectFileError, match=needle):
        project_from_file_bytes(data, "p.npz")


def _bomb(data: bytes, member: str, nbytes: int) -> bytes:
    """``data`` with one more member: a float64 .npy of ``nbytes`` of zeros, streamed."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (nbytes // 8,)}
    )
    out = io.BytesIO(data)
    with zipfile.ZipFile(out, "a", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        with z.open(member, "w", force_zip64=True) as f:
            f.write(header.getvalue())  # magic and header
            block = bytes(1 << 20)
            for _ in range(nbytes >> 20):
                f.write(block)
    return out.getvalue()


@pytest.fixture(scope="module")
def bomb_parts(good_bytes: bytes) -> dict[str, bytes]:
    arrays = arrays_of(good_bytes)
    without_time = npz({k: v for k, v in arrays.items() if k != "rec_time_s"})
    return {
        "recording": _bomb(without_time, "rec_time_s.npy", 512 << 20),
        "unknown": _bomb(good_bytes, "holiday_video.npy", 512 << 20),
    }


def test_a_zeros_bomb_is_refused_from_its_header_in_bounded_memory(bomb_parts):
    data = bomb_parts["recording"]
    assert len(data) < 5_000_000
    tracemalloc.start()
    try:
        with pytest.raises(ProjectFileError, match="'rec_time_s' has 67108864 rows, more than"):
            project_from_file_bytes(data, "bomb.npz")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 50e6, f"{peak / 1e6:.0f} MB"


def test_members_robomach_does_not_write_are_never_read(bomb_parts):
    tracemalloc.start()
    try:
        project = project_from_file_bytes(bomb_parts["unknown"], "extra.npz")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(project.learned.recording) == 400
    assert peak < 100e6, f"{peak / 1e6:.0f} MB"


@pytest.mark.parametrize("model", ["linear", "nonlinear"])
def test_a_project_saved_with_the_old_compensation_spelling_loads_by_the_rule(
    good_bytes: bytes, model: str
):
    """Issue 30: a project.npz written before the one vocabulary holds a version-1 compensation
    document (``"mode": "offline_<model>"``); it loads as offline with that model, and is
    saved back in the one vocabulary (nothing dropped, nothing silently changed)."""
    from robomach_core.cell.joint_compliance import TRUE_JOINT_STIFFNESS_NM_RAD

    def old_compensation(doc: dict) -> None:
        doc["compensation"] = {
            "format": "robomach.compensation",
            "version": 1,
            "robot": "ur10",
            "mode": f"offline_{model}",
            "joint_stiffness_Nm_rad": list(TRUE_JOINT_STIFFNESS_NM_RAD["ur10"]),
            "force_filter_cutoff_hz": 30.0,
        }

    project = project_from_file_bytes(with_document(good_bytes, old_compensation))
    assert (project.compensation.mode, project.compensation.offline_model) == ("offline", model)
    again = project_from_file_bytes(project_file_bytes(project))
    assert again.compensation == project.compensation
    doc = json.loads(arrays_of(project_file_bytes(project))["document"].tobytes())
    assert (doc["compensation"]["mode"], doc["compensation"]["offline_model"]) == (
        "offline",
        model,
    )
