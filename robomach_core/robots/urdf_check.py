"""Bounds on a robot file before pinocchio parses it, and the zip that carries it.

PROBLEM   pinocchio's URDF parser recurses along the kinematic tree: the IRB 4400 with 5,000
          fixed links chained on (715 KB) overflowed its stack and killed the server (issue 19,
          R2; 3,500 parsed, 4,000 crashed). A robot zip of 1 MB held a 1 GiB mesh that was read
          into memory, written to the robot cache and read again at every restart (R4).
STRATEGY  Bound the text (size, XML nesting, element count) while it is read as a stream, then
          the tree it declares (links, joints, depth from the root, every link reached); all far
          above real arms (the largest URDF of example-robot-data, TIAGo dual: 211 KB, 130 links,
          depth under 20) and far below what the parser survives. A zip is judged by its
          central directory before anything is extracted: how many entries, then the declared
          sizes of the one URDF and of the mesh files it references, summed once per reference
          (the scene loads a file again for each ``<mesh>`` that names it: a 31 KB URDF naming
          one 25 MB mesh from 120 links took a server from 3.1 to 6.2 GB, issue 32); the files
          the URDF does not reference are never read. Every mesh reference must name a file of
          the upload (``reference_parts``: no absolute path, ``file://``, other scheme or
          ``..``; it scene loaded any mesh file of the server's disk) of a type the scene reads
          without following references of its own further than the sanitised copy
          (``MESH_REFERENCE_SUFFIXES``); the scene resolves references with
          ``resolve_reference``, which cannot leave the upload's members. Finally the pinocchio
          model is built once in an isolated process (``isolation``, task ``urdf``) so that a
          crash left unforeseen here refuses the file instead of killing the caller.
SOLUTION  ``check_urdf_text(text, filename)``, ``read_robot_zip(filename, data) -> (text,
          files)``, ``read_package_meshes`` (a bare URDF's example-robot-data meshes),
          ``resolve_reference`` and ``check_urdf_native(text, filename)``, called by
          ``robots.custom``.
"""

from __future__ import annotations

import io
import math
import posixpath
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Iterable
from pathlib import Path

from ..errors import RobomachError

MAX_URDF_BYTES = 2_000_000
MAX_XML_NESTING = 32  # a URDF nests 4-6 deep (robot/link/visual/geometry/mesh)
MAX_XML_ELEMENTS = 50_000
MAX_URDF_LINKS = 500
MAX_URDF_JOINTS = 500
MAX_URDF_DEPTH = 100  # joints from the root to the deepest link
MAX_ZIP_ENTRIES = 10_000
MAX_ROBOT_MESH_FILES = 200
MAX_ROBOT_UNPACKED_BYTES = 100_000_000  # the URDF and the mesh files it references, declared
MAX_ROBOT_MESH_BYTES = 50_000_000  # one mesh file, as the workpiece reader's limit
# Attributes of URDF elements that hold numbers (origins, axes, limits, shapes, inertia).
NUMERIC_ATTRIBUTES = frozenset(
    {"xyz", "rpy", "scale", "size", "radius", "length", "lower", "upper", "effort", "velocity",
     "value", "ixx", "ixy", "ixz", "iyy", "iyz", "izz", "damping", "friction", "rising",
     "falling", "soft_lower_limit", "soft_upper_limit", "k_position", "k_velocity",
     "multiplier", "offset", "rgba"}
)  # fmt: skip
MAX_ROBOT_REFERENCED_TRIANGLES = 2_000_000  # summed over the <mesh> references: each loads
# Mesh types the scene (trimesh, through yourdfpy) reads; their own references to other files
# (an OBJ's mtllib, a COLLADA file's images) are dropped from the copy the scene reads.
MESH_REFERENCE_SUFFIXES = (".stl", ".obj", ".ply", ".dae")
EXAMPLE_ROBOT_DATA_PREFIX = "package://example-robot-data/robots/"
NATIVE_CHECK_MEMORY_BYTES = 1 << 30
NATIVE_CHECK_TIMEOUT_S = 60.0


class UrdfBoundsError(RobomachError, ValueError):
    """A robot file exceeds a bound on its size, its tree or its archive."""


def check_urdf_text(
    text: str, filename: str = "robot.urdf", error: type[RobomachError] = UrdfBoundsError
) -> None:
    """``UrdfBoundsError`` when the URDF is too large, nests too deep, or declares a tree of too
    many links or joints or too deep for the parser; a file that is not XML passes (the
    chain check names that fault)."""
    size = len(text.encode("utf-8", "surrogatepass"))
    if size > MAX_URDF_BYTES:
        raise error(
            f"{filename}: the URDF is {size / 1e6:.1f} MB, more than {MAX_URDF_BYTES / 1e6:g} MB"
        )
    try:
        _check_urdf_text(text, filename)
    except UrdfBoundsError as exc:
        if error is UrdfBoundsError:
            raise
        raise error(str(exc)) from None


def _check_urdf_text(text: str, filename: str) -> None:
    parser: ET.XMLPullParser[ET.Element] = ET.XMLPullParser(events=("start", "end"))
    depth, elements = 0, 0
    owner = "robot"
    links: list[str] = []
    edges: list[tuple[str, str]] = []
    try:
        for start in range(0, len(text), 1 << 16):
            parser.feed(text[start : start + (1 << 16)])
            # typeshed's event union has a 1-tuple; "start" and "end" come as (event, element).
            for event, element in parser.read_events():  # type: ignore[misc]
                assert isinstance(element, ET.Element)  # only "start" and "end" were asked for
                if event == "end":
                    depth -= 1
                    if depth == 1 and element.tag == "joint":
                        parent, child = element.find("parent"), element.find("child")
                        if parent is not None and child is not None:
                            edges.append((str(parent.get("link")), str(child.get("link"))))
                    continue
                depth += 1
                elements += 1
                if depth > MAX_XML_NESTING:
                    raise UrdfBoundsError(
                        f"{filename}: XML elements nest more than {MAX_XML_NESTING} deep"
                    )
                if elements > MAX_XML_ELEMENTS:
                    raise UrdfBoundsError(f"{filename}: more than {MAX_XML_ELEMENTS} XML elements")
                if depth == 2:
                    owner = f"{element.tag} {element.get('name')!r}"
                    if element.tag == "link":
                        links.append(str(element.get("name")))
                _check_numbers(element, owner if depth >= 2 else "robot", filename)
        parser.close()
    except ET.ParseError:
        return  # validate_urdf reports it as "not valid XML"
    if len(links) > MAX_URDF_LINKS:
        raise UrdfBoundsError(
            f"{filename}: {len(links)} links, more than {MAX_URDF_LINKS}; a 6-axis arm needs ~10"
        )
    if len(edges) > MAX_URDF_JOINTS:
        raise UrdfBoundsError(f"{filename}: {len(edges)} joints, more than {MAX_URDF_JOINTS}")
    _check_tree(links, edges, filename)


def _check_numbers(element: ET.Element, owner: str, filename: str) -> None:
    """``UrdfBoundsError`` when a numeric attribute (``NUMERIC_ATTRIBUTES``) holds a number
    that is not finite: an infinite visual origin was accepted and flooded the log with the
    viewer's warnings at every frame (issue 32). Text that is not a number is left to the
    parsers' own messages."""
    for attribute in NUMERIC_ATTRIBUTES.intersection(element.attrib):
        text = element.attrib[attribute]
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            continue
        if not all(math.isfinite(v) for v in values):
            raise UrdfBoundsError(
                f"{filename}: {owner}: <{element.tag} {attribute}={text[:80]!r}> is not a "
                "finite number"
            )


def _check_tree(links: list[str], edges: list[tuple[str, str]], filename: str) -> None:
    """Depth from the root (iterative: no recursion here either) and every link reached."""
    children: dict[str, list[str]] = {}
    child_links = set()
    for parent, child in edges:
        children.setdefault(parent, []).append(child)
        child_links.add(child)
    roots = [name for name in links if name not in child_links]
    if len(roots) != 1:
        return  # validate_urdf names the fault (no root, several roots)
    depth_of = {roots[0]: 0}
    stack = [roots[0]]
    while stack:
        link = stack.pop()
        for child in children.get(link, ()):
            if child in depth_of:
                raise UrdfBoundsError(f"{filename}: link {child!r} has two parents (a loop)")
            depth_of[child] = depth_of[link] + 1
            if depth_of[child] > MAX_URDF_DEPTH:
                raise UrdfBoundsError(
                    f"{filename}: the kinematic tree is more than {MAX_URDF_DEPTH} joints deep"
                )
            stack.append(child)
    unreached = [name for name in links if name not in depth_of]
    if unreached:
        shown = ", ".join(repr(n) for n in unreached[:3])
        raise UrdfBoundsError(
            f"{filename}: {len(unreached)} links are not connected to the root {roots[0]!r} "
            f"({shown}{', ...' if len(unreached) > 3 else ''})"
        )


def mesh_references(text: str) -> list[str]:
    """The ``filename`` of every ``<mesh>`` of the URDF, as written, in order (a file named by
    several ``<mesh>`` elements is listed each time: each is loaded)."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return []
    return [str(m.get("filename")) for m in root.iter("mesh") if m.get("filename") is not None]


def _parts(path: str) -> tuple[str, ...]:
    """Path components without a ``package://name/`` or ``file://`` prefix, ``.`` or ``..``."""
    if path.startswith("package://"):
        path = path[len("package://") :].split("/", 1)[-1]
    elif path.startswith("file://"):
        path = path[len("file://") :]
    norm = posixpath.normpath(path.replace("\\", "/"))
    return tuple(p for p in norm.split("/") if p not in ("", ".", ".."))


def reference_problem(reference: str) -> str | None:
    """Why a ``<mesh filename>`` cannot name a file of an upload, or None when it can: a
    relative path or ``package://<package>/<path>`` without ``..``, of a mesh type the scene
    reads (``MESH_REFERENCE_SUFFIXES``)."""
    ref = reference.strip()
    if not ref:
        return "is empty"
    if any(ord(ch) < 32 for ch in ref):
        return "holds control characters"
    if ref.startswith("file:"):
        return "is a file:// URL (a file of the server's disk, not of the upload)"
    scheme = ref.split("://", 1)[0] if "://" in ref else ""
    if scheme and scheme != "package":
        return f"is a {scheme}:// URL, not a file of the upload"
    rest = ref[len("package://") :] if scheme == "package" else ref
    if scheme == "package" and "/" not in rest.strip("/"):
        return "names a package but no file in it"
    path = rest.replace("\\", "/")
    if scheme == "package":
        path = path.split("/", 1)[1]
    if path.startswith("/") or (len(path) > 1 and path[1] == ":"):
        return "is an absolute path (a file of the server's disk, not of the upload)"
    if ".." in rest.replace("\\", "/").split("/"):  # the package's name counts too
        return "climbs out of its folder (..)"
    suffix = posixpath.splitext(path)[1].lower()
    if suffix not in MESH_REFERENCE_SUFFIXES:
        return (
            f"is a {suffix or 'suffix-less'} file; meshes must be "
            f"{', '.join(s.upper().lstrip('.') for s in MESH_REFERENCE_SUFFIXES)}"
        )
    return None


def check_references(
    references: list[str], filename: str, error: type[RobomachError] = UrdfBoundsError
) -> None:
    """``error`` naming the first reference that cannot name a file of the upload."""
    for ref in dict.fromkeys(references):
        problem = reference_problem(ref)
        if problem is not None:
            raise error(f"{filename}: the mesh reference {ref[:200]!r} {problem}")


def resolve_reference(reference: str, members: Iterable[str]) -> str | None:
    """The member of an upload a mesh reference names (``is_referenced``; the member sharing
    the longest tail with it when several do), or None: a reference ``reference_problem``
    refuses never resolves, whatever the members."""
    if reference_problem(reference) is not None:
        return None
    theirs = _parts(reference)
    best, best_k = None, 0
    for member in members:
        mine = _parts(member)
        if not mine or ".." in member.replace("\\", "/").split("/") or member.startswith("/"):
            continue
        k = min(len(mine), len(theirs))
        if not (k and mine[-k:] == theirs[-k:] and (k >= 2 or len(mine) == len(theirs) == 1)):
            continue
        shared = next((i for i in range(1, k + 1) if mine[-i] != theirs[-i]), k + 1) - 1
        if shared > best_k:
            best, best_k = member, shared
    return best


def is_referenced(member: str, references: list[str]) -> bool:
    """True when the zip member is the file one of the references names: the shorter of the
    two paths is the tail of the longer (``package://arm/meshes/a.stl`` is ``meshes/a.stl``
    and ``arm/meshes/a.stl``; a base name alone is not enough)."""
    mine = _parts(member)
    for ref in references:
        theirs = _parts(ref)
        k = min(len(mine), len(theirs))
        if k and mine[-k:] == theirs[-k:] and (k >= 2 or len(mine) == len(theirs) == 1):
            return True
    return False


def _check_reference_cost(
    references: list[str],
    sizes: dict[str, int],
    resolved: dict[str, str],
    text_bytes: int,
    filename: str,
    error: type[RobomachError],
) -> None:
    """The bytes the scene reads: the URDF and, for every reference, its file again."""
    total = text_bytes + sum(sizes[resolved[ref]] for ref in references)
    if total > MAX_ROBOT_UNPACKED_BYTES:
        raise error(
            f"{filename}: the URDF's {len(references)} mesh references load "
            f"{total / 1e6:.1f} MB (a file is loaded again for each reference to it), more "
            f"than {MAX_ROBOT_UNPACKED_BYTES / 1e6:g} MB"
        )


def _entry_count(data: bytes) -> int | None:
    """Entries the zip's end record declares (read before zipfile lists them all)."""
    # zipfile's private end-record reader and index: not in typeshed's stubs.
    end = zipfile._EndRecData(io.BytesIO(data))  # type: ignore[attr-defined]  # noqa: SLF001
    return None if end is None else int(end[zipfile._ECD_ENTRIES_TOTAL])  # type: ignore[attr-defined]  # noqa: SLF001


def open_zip(
    data: bytes,
    filename: str,
    error: type[RobomachError],
    *,
    unreadable: str = "not a readable zip file",
) -> zipfile.ZipFile:
    """The archive of ``data`` once its end record declares at most ``MAX_ZIP_ENTRIES``
    entries (zipfile would list millions of entries in memory first); ``error`` saying
    ``unreadable`` when it is not a zip."""
    try:
        count = _entry_count(data)
        if count is not None and count > MAX_ZIP_ENTRIES:
            raise error(
                f"{filename}: the zip declares {count} entries, more than {MAX_ZIP_ENTRIES}"
            )
        return zipfile.ZipFile(io.BytesIO(data))
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError) as exc:
        if isinstance(exc, RobomachError):
            raise
        raise error(f"{filename}: {unreadable}") from None


def read_robot_zip(
    filename: str, data: bytes, error: type[RobomachError] = UrdfBoundsError
) -> tuple[str, dict[str, bytes]]:
    """The URDF text of a robot zip and the mesh files it references (path -> bytes).

    Nothing is extracted before the declared sizes of the URDF and of the referenced files
    are summed against ``MAX_ROBOT_UNPACKED_BYTES``; reading stops at each declared size (a
    member that holds more fails its CRC and the zip is refused).

    Raises:
        error: not a zip, not exactly one .urdf, too many entries or referenced files, or more
            bytes declared than allowed.
    """
    archive = open_zip(data, filename, error)
    try:
        infos = [i for i in archive.infolist() if not i.is_dir()]
        urdfs = [i for i in infos if i.filename.lower().endswith(".urdf")]
        if len(urdfs) != 1:
            raise error(
                f"{filename}: the zip holds {len(urdfs)} .urdf files; it must hold exactly one"
            )
        urdf = urdfs[0]
        if urdf.file_size > MAX_URDF_BYTES:
            raise error(
                f"{filename}: {urdf.filename} declares {urdf.file_size / 1e6:.1f} MB, more than "
                f"{MAX_URDF_BYTES / 1e6:g} MB"
            )
        try:
            text = archive.read(urdf).decode("utf-8")
        except UnicodeDecodeError:
            raise error(f"{urdf.filename}: not UTF-8 text") from None
        references = mesh_references(text)
        check_references(references, filename, error)
        members = {i.filename: i for i in infos if i is not urdf}
        resolved = {}
        for ref in dict.fromkeys(references):
            member = resolve_reference(ref, members)
            if member is None:
                raise error(
                    f"{filename}: the mesh reference {ref[:200]!r} names no file of the zip; "
                    "put the meshes the URDF names in the zip beside it"
                )
            resolved[ref] = member
        wanted = [members[m] for m in dict.fromkeys(resolved.values())]
        if len(wanted) > MAX_ROBOT_MESH_FILES:
            raise error(
                f"{filename}: the URDF references {len(wanted)} files of the zip, more than "
                f"{MAX_ROBOT_MESH_FILES}"
            )
        for info in wanted:
            if info.file_size > MAX_ROBOT_MESH_BYTES:
                raise error(
                    f"{filename}: {info.filename} declares {info.file_size / 1e6:.1f} MB, more "
                    f"than {MAX_ROBOT_MESH_BYTES / 1e6:g} MB for one mesh"
                )
        sizes = {i.filename: i.file_size for i in wanted}
        _check_reference_cost(references, sizes, resolved, urdf.file_size, filename, error)
        files = {i.filename: archive.read(i) for i in wanted}
    except (zipfile.BadZipFile, OSError, EOFError, ValueError, NotImplementedError) as exc:
        if isinstance(exc, RobomachError):
            raise
        raise error(f"{filename}: a file in the zip is damaged ({exc})") from None
    finally:
        archive.close()
    _check_meshes(files, [resolved[ref] for ref in references], filename, error)
    return text, files


def read_package_meshes(
    text: str, filename: str, error: type[RobomachError] = UrdfBoundsError
) -> dict[str, bytes]:
    """The mesh files a bare URDF (no zip) references, by member path: only files of the
    installed example-robot-data (``package://example-robot-data/...``: a UR copied out of
    it names its meshes so), read from inside its robots folder, bounded like a zip's; any
    other reference is refused with ``error`` naming it (a .urdf brings no file of its own)."""
    from .registry import robots_directory

    references = mesh_references(text)
    check_references(references, filename, error)
    root = robots_directory().resolve()
    paths: dict[str, Path] = {}
    for ref in dict.fromkeys(references):
        path = None
        if ref.startswith(EXAMPLE_ROBOT_DATA_PREFIX):
            candidate = (root / ref[len(EXAMPLE_ROBOT_DATA_PREFIX) :]).resolve()
            if root in candidate.parents and candidate.is_file():
                path = candidate
        if path is None:
            raise error(
                f"{filename}: the mesh reference {ref[:200]!r} names no file of the upload; a "
                ".urdf brings no meshes: upload a .zip of the URDF and the meshes it names"
            )
        paths[ref] = path
    members = {ref: f"example-robot-data/robots/{p.relative_to(root).as_posix()}"
               for ref, p in paths.items()}  # fmt: skip
    sizes = {members[ref]: p.stat().st_size for ref, p in paths.items()}
    for member, size in sizes.items():
        if size > MAX_ROBOT_MESH_BYTES:
            raise error(f"{filename}: {member} is {size / 1e6:.1f} MB, more than one mesh may be")
    size_text = len(text.encode("utf-8", "surrogatepass"))
    _check_reference_cost(references, sizes, members, size_text, filename, error)
    files = {members[ref]: p.read_bytes() for ref, p in paths.items()}
    _check_meshes(files, [members[ref] for ref in references], filename, error)
    return files


def _check_meshes(
    files: dict[str, bytes],
    referenced: list[str],
    filename: str,
    error: type[RobomachError],
) -> None:
    """Mesh files the viewer will parse: STL/OBJ/PLY within the workpiece reader's triangles
    each, and within ``MAX_ROBOT_REFERENCED_TRIANGLES`` summed over the references (each is
    loaded)."""
    from ..part import MAX_MESH_TRIANGLES, count_mesh_triangles

    triangles: dict[str, int] = {}
    for path, data in files.items():
        kind = posixpath.splitext(path)[1].lower()
        if kind in (".stl", ".obj", ".ply"):
            count, complete = count_mesh_triangles(data, kind, stop_above=MAX_MESH_TRIANGLES)
            if count > MAX_MESH_TRIANGLES:
                raise error(
                    f"{filename}: {path} holds {'at least ' if not complete else ''}{count} "
                    f"triangles, more than {MAX_MESH_TRIANGLES}"
                )
            triangles[path] = count
    total = sum(triangles.get(member, 0) for member in referenced)
    if total > MAX_ROBOT_REFERENCED_TRIANGLES:
        raise error(
            f"{filename}: the URDF's mesh references load {total} triangles (a file again for "
            f"each reference to it), more than {MAX_ROBOT_REFERENCED_TRIANGLES}"
        )


def check_urdf_native(
    text: str, filename: str = "robot.urdf", error: type[RobomachError] = UrdfBoundsError
) -> dict:
    """Build the pinocchio model of ``text`` once in an isolated process: a crash, a memory
    blow-up or a hang there becomes ``error``; a model pinocchio refuses with an exception
    passes (the caller's own build reports it). Returns the child's answer (``nq``,
    ``njoints``, ``nframes``; empty when pinocchio refused)."""
    from ..isolation import IsolatedError, run_isolated

    try:
        return run_isolated(
            "urdf",
            {"text": text},
            memory_bytes=NATIVE_CHECK_MEMORY_BYTES,
            timeout_s=NATIVE_CHECK_TIMEOUT_S,
        )
    except IsolatedError as exc:
        if exc.kind == "error":
            return {}
        raise error(f"{filename}: pinocchio cannot build this model ({exc})") from None
