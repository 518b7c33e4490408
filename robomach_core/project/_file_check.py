"""What a ``project.npz`` may hold, checked before it is read and before it is believed.

PROBLEM   A 7 MB project file holding a 2 GiB array of zeros made the server allocate 2 GB on
          import (issue 19, R4); a file whose recording arrays differed in length or type was
          imported (201) and then failed every export (R7); a work-object of 1e308 mm ran 27.7 s
          and 4.9 GB before it failed (R6).
STRATEGY  The archive is judged by its central directory and each array by its ``.npy``
          header (a few hundred bytes) before any array is read: only the members robomach
          writes are read, each with a dtype and a shape that its name allows, at most
          ``MAX_RECORDING_SAMPLES`` samples and ``MAX_GUIDE_POINTS`` guide points, so the bytes
          an import can allocate are bounded by the format itself (~260 MB for the longest
          recording, 50 MB per mesh). Once read, the arrays must agree: one length for every
          recording array, one count for the guide arrays and the document's guide times,
          finite values, positions within ``MAX_POSITION_M``, unit quaternions, segments
          within the path; and the document's numbers must be inside their ``limits`` ranges.
SOLUTION  ``read_project_arrays(data, name) -> dict`` and ``check_project(doc, arrays, name)``,
          called by ``project_from_file_bytes``; each refusal a ``ProjectFileError`` naming the
          array or setting and what is wrong with it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import limits
from ..errors import InvalidInputError
from ..robots import open_zip

MAX_RECORDING_SAMPLES = limits.RECORDING_SAMPLES_MAX
MAX_GUIDE_POINTS = limits.GUIDE_POINTS_MAX
MAX_DOCUMENT_BYTES = 1_000_000
MAX_MESH_FILE_BYTES = 50 * 1024 * 1024  # workpiece.MAX_MESH_BYTES
MAX_ROBOT_FILE_BYTES = 50 * 1024 * 1024  # robots.custom.MAX_ROBOT_FILE_BYTES
MAX_POSITION_M = 10.0  # every pose of the cell is within a few metres of the robot base
QUATERNION_NORM_TOLERANCE = 1e-3
N = "n"  # the recording's sample count in a shape
G = "g"  # the guide-point count
# name -> (dtype kinds allowed, shape with N/G placeholders)
ARRAYS: dict[str, tuple[str, tuple[Any, ...]]] = {
    "document": ("u", ("bytes",)),
    "mesh_bytes": ("u", ("bytes",)),
    "stock_mesh_bytes": ("u", ("bytes",)),
    "robot_urdf_bytes": ("u", ("bytes",)),
    "guide_T_base_tcp": ("f", (G, 4, 4)),
    "guide_joints_rad": ("f", (G, 6)),
    "guide_force_N": ("f", (G, 3)),
    "guide_quaternions_wxyz": ("f", ("q", 4)),
    "rec_time_s": ("f", (N,)),
    "rec_joints_rad": ("f", (N, 6)),
    "rec_position_m": ("f", (N, 3)),
    "rec_quaternion_wxyz": ("f", (N, 4)),
    "rec_wrench_sensor": ("f", (N, 6)),
    "rec_wrench_tool": ("f", (N, 6)),
    "rec_force_normal_N": ("f", (N,)),
    "rec_force_reference_N": ("f", (N,)),
    "rec_in_contact": ("b", (N,)),
    "rec_yp": ("f", (N, 3)),
    "rec_segment": ("iu", (N,)),
}
_BYTES_LIMIT = {
    "document": MAX_DOCUMENT_BYTES,
    "mesh_bytes": MAX_MESH_FILE_BYTES,
    "stock_mesh_bytes": MAX_MESH_FILE_BYTES,
    "robot_urdf_bytes": MAX_ROBOT_FILE_BYTES,
}
_COUNT_LIMIT = {N: MAX_RECORDING_SAMPLES, G: MAX_GUIDE_POINTS, "q": MAX_GUIDE_POINTS + 1}

RECORDING_FIELDS = (
    "time_s",
    "joints_rad",
    "position_m",
    "quaternion_wxyz",
    "wrench_sensor",
    "wrench_tool",
    "force_normal_N",
    "force_reference_N",
    "in_contact",
    "yp",
    "segment",
)


class ProjectFileError(InvalidInputError):
    """A project file is missing, unreadable, or written by an unknown version."""


def _error(message: str) -> InvalidInputError:
    return ProjectFileError(message)


def _check_header(key: str, shape: tuple[int, ...], dtype: np.dtype, name: str) -> int:
    """The bytes the array will take, once its header is one ``ARRAYS[key]`` allows."""
    kinds, layout = ARRAYS[key]
    if dtype.hasobject or dtype.kind not in kinds or dtype.itemsize > 8:
        raise _error(f"{name}: array {key!r} has type {dtype}, expected kind {kinds!r}")
    if len(shape) != len(layout):
        raise _error(f"{name}: array {key!r} has shape {shape}, expected {len(layout)} axes")
    for size, want in zip(shape, layout, strict=True):
        if want == "bytes":
            if size > _BYTES_LIMIT[key]:
                raise _error(
                    f"{name}: {key!r} holds {size / 1e6:.1f} MB, more than "
                    f"{_BYTES_LIMIT[key] / 1e6:g} MB"
                )
        elif isinstance(want, str):
            if size > _COUNT_LIMIT[want]:
                raise _error(
                    f"{name}: array {key!r} has {size} rows, more than {_COUNT_LIMIT[want]}"
                )
        elif size != want:
            raise _error(f"{name}: array {key!r} has shape {shape}, expected {layout}")
    return math.prod(shape) * dtype.itemsize


def read_project_arrays(data: bytes, name: str) -> dict[str, np.ndarray]:
    """The arrays robomach writes in a ``project.npz``, each checked by its header first.

    Members of other names are not read. The total is bounded by the format (``ARRAYS``).

    Raises:
        ProjectFileError: not a zip, too many entries, an array of a type or shape its name
            does not allow, or a damaged member.
    """
    archive = open_zip(
        data, name, ProjectFileError, unreadable="not a robomach project file (not a zip)"
    )
    arrays: dict[str, np.ndarray] = {}
    try:
        for info in archive.infolist():
            key = info.filename.removesuffix(".npy")
            if key not in ARRAYS or key in arrays:
                continue
            with archive.open(info) as fp:
                version = np.lib.format.read_magic(fp)
                if version == (1, 0):
                    shape, fortran, dtype = np.lib.format.read_array_header_1_0(fp)
                elif version == (2, 0):
                    shape, fortran, dtype = np.lib.format.read_array_header_2_0(fp)
                else:
                    raise _error(f"{name}: array {key!r} has .npy version {version}")
                nbytes = _check_header(key, tuple(shape), np.dtype(dtype), name)
                raw = fp.read(nbytes)
                if len(raw) != nbytes:
                    raise _error(f"{name}: array {key!r} is truncated")
            array = np.frombuffer(raw, dtype=dtype)
            arrays[key] = array.reshape(shape, order="F" if fortran else "C").copy()
    except ProjectFileError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged zip or .npy member
        raise _error(f"{name}: not a robomach project file ({exc.__class__.__name__})") from None
    finally:
        archive.close()
    if "document" not in arrays:
        raise _error(f"{name}: not a robomach project file (no document)")
    return arrays


def _finite(key: str, a: np.ndarray, name: str) -> None:
    if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
        raise _error(f"{name}: array {key!r} holds NaN or infinite values")


def check_project(doc: dict[str, Any], arrays: dict[str, np.ndarray], name: str) -> None:
    """``ProjectFileError`` unless the arrays agree with each other and with the document and
    every number is inside its range (module docstring)."""
    for key, a in arrays.items():
        _finite(key, a, name)
    _check_guides(doc, arrays, name)
    _check_recording(doc, arrays, name)
    _check_cell(doc, name)


def _check_guides(doc: dict[str, Any], arrays: dict[str, np.ndarray], name: str) -> None:
    times = doc.get("guide_times_s", [])
    if not isinstance(times, list) or len(times) > MAX_GUIDE_POINTS:
        raise _error(f"{name}: guide_times_s must be a list of at most {MAX_GUIDE_POINTS} times")
    if not all(isinstance(t, (int, float)) and math.isfinite(t) for t in times):
        raise _error(f"{name}: guide_times_s holds a value that is not a finite number")
    g = len(times)
    for key in ("guide_T_base_tcp", "guide_joints_rad", "guide_force_N"):
        rows = len(arrays[key]) if key in arrays else 0
        if rows != g:
            raise _error(
                f"{name}: array {key!r} has {rows} guide points, the document {g} guide times"
            )
    if g:
        T = arrays["guide_T_base_tcp"]
        if np.max(np.abs(T[:, :3, 3])) > MAX_POSITION_M:
            raise _error(f"{name}: a guide point lies more than {MAX_POSITION_M:g} m from the base")
        R = T[:, :3, :3]
        if not np.allclose(R @ R.transpose(0, 2, 1), np.eye(3), atol=1e-6) or not np.allclose(
            T[:, 3], [0, 0, 0, 1]
        ):
            raise _error(f"{name}: a guide point's pose is not a rigid transform")


def _check_recording(doc: dict[str, Any], arrays: dict[str, np.ndarray], name: str) -> None:
    present = [f for f in RECORDING_FIELDS if f"rec_{f}" in arrays]
    if doc.get("recording") is None:
        return
    missing = [f for f in RECORDING_FIELDS if f not in present]
    if missing or "guide_quaternions_wxyz" not in arrays:
        shown = ", ".join(missing) or "guide_quaternions_wxyz"
        raise _error(f"{name}: the recording lacks {shown}")
    lengths = {f: len(arrays[f"rec_{f}"]) for f in RECORDING_FIELDS}
    n = max(set(lengths.values()), key=list(lengths.values()).count)  # the most arrays' length
    odd = {f: k for f, k in lengths.items() if k != n}
    if odd:
        shown = ", ".join(f"{f} has {k}" for f, k in odd.items())
        raise _error(
            f"{name}: the recording's arrays differ in length ({shown} samples, the others {n})"
        )
    if n < 2:
        raise _error(f"{name}: the recording holds {n} samples; at least 2 are needed")
    if np.any(np.diff(arrays["rec_time_s"]) < 0):
        raise _error(f"{name}: the recording's time_s goes backwards")
    if np.max(np.abs(arrays["rec_position_m"])) > MAX_POSITION_M:
        raise _error(
            f"{name}: a recorded position lies more than {MAX_POSITION_M:g} m from the base"
        )
    for key in ("rec_quaternion_wxyz", "guide_quaternions_wxyz"):
        norms = np.linalg.norm(arrays[key], axis=1)
        if len(norms) and np.max(np.abs(norms - 1.0)) > QUATERNION_NORM_TOLERANCE:
            raise _error(f"{name}: array {key!r} holds quaternions that are not of unit length")
    segments = arrays["rec_segment"]
    paths = len(arrays["guide_quaternions_wxyz"])
    if len(segments) and (segments.min() < 0 or segments.max() > paths):
        raise _error(
            f"{name}: the recording's segments run {segments.min()}-{segments.max()}, beyond "
            f"the {paths} guide points it followed"
        )


def _check_cell(doc: dict[str, Any], name: str) -> None:
    cell = doc.get("cell")
    if not isinstance(cell, dict):
        raise _error(f"{name}: the document has no cell")
    try:
        radius = cell.get("tool_radius_m", 0.001)
        limits.TOOL_RADIUS_MM.check(
            radius * 1e3 if isinstance(radius, (int, float)) else radius, "tool radius [mm]"
        )
        limits.SEED.check(cell.get("seed", 0), "seed")
        wobj = cell.get("wobj_mm_deg")
        if wobj is not None:
            check_wobj(wobj)
        registration = cell.get("registration")
        if registration is not None:
            if not isinstance(registration, dict):
                raise InvalidInputError("the work-object registration is not a document")
            check_wobj(registration.get("wobj_mm_deg"))
    except InvalidInputError as exc:
        raise _error(f"{name}: {exc}") from None


def check_wobj(values: Any) -> list[float]:
    """The work-object frame (x, y, z [mm], optional rz, or rx, ry, rz [deg]) when each
    number is inside ``limits.WOBJ_POSITION_MM`` / ``WOBJ_ROTATION_DEG``."""
    if not isinstance(values, (list, tuple)) or len(values) not in (3, 4, 6):
        raise InvalidInputError(
            "the work object is x,y,z in mm with an optional rz, or rx,ry,rz, in degrees"
        )
    out = []
    for i, v in enumerate(values):
        rng = limits.WOBJ_POSITION_MM if i < 3 else limits.WOBJ_ROTATION_DEG
        axis = "xyz"[i] if i < 3 else ("rz" if len(values) == 4 else ("rx", "ry", "rz")[i - 3])
        out.append(rng.check(v, f"work-object {axis}"))
    return out
