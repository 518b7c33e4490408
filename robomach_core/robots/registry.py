"""One record per arm: everything the workbench knows of an arm, by name, in one table.

PROBLEM   An arm is more than its URDF: the cell needs its home pose, its controller's family
          and program language, where the built-in part sits in front of it, the simulator's
          true joint stiffness and the radii of its links for supervision. Kept in five tables
          of four modules, an uploaded arm had to be written into each of them.
STRATEGY  A frozen ``Arm`` record per name. The built-in arms (UR from example-robot-data, ABB
          and KUKA built from published kinematics, ``robots.builtin``) are in the table from
          the start; an upload adds one record (``robots.custom.register_urdf``); asking for
          ``<upload>_<family>`` adds the same arm with that family's controller.
SOLUTION  ``arm(name) -> Arm``, ``register(arm)``, ``forget(name)``, ``BUILTIN_ARMS``.
"""

from __future__ import annotations

import importlib.metadata
import re
import threading
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import UnknownNameError
from . import builtin

# A home pose with the tool pointing down above the table in front of the robot (UR arms).
UR_HOME_JOINTS_RAD = (0.0, -1.7, 1.9, -1.77, -1.5708, 0.0)
DEFAULT_LINK_RADIUS_M = 0.06  # of an arm's links for supervision, when its record has none


@dataclass(frozen=True)
class Arm:
    """One arm.

    Attributes:
        name: The name ``Robot`` takes (lower case).
        family: Whose controller it has (``robots.builtin.ARM_FAMILIES``).
        home_rad: (6,) home joints: the tool down above the built-in part's placement, in the
            controller's axis zeros and directions.
        stiffness_Nm_rad: (6,) the simulator's true joint stiffness Kq (``joint_compliance``).
        part_position_m: Where the built-in part's work object sits for this arm, base frame;
            None: the UR10's (``workpiece.DEFAULT_T_BASE_WOBJ``).
        link_radii_m: Radii of the capsules of the upper arm, forearm and wrists 1-3 that
            supervision checks for collisions; None: ``DEFAULT_LINK_RADIUS_M`` each.
        urdf_file: Its URDF, relative to example-robot-data's robots folder (UR arms); None
            for the arms built here and the uploads.
        urdf_text: An upload's URDF (with a ``tool0`` flange); None for the built-in arms.
        meshes: The mesh files that came with an upload's zip (path -> bytes).
        source_file: An upload's file as the user gave it, (filename, bytes): what a project
            on this arm saves (``Project.robot_urdf``); None for the built-in arms.
    """

    name: str
    family: str
    home_rad: tuple[float, ...]
    stiffness_Nm_rad: tuple[float, ...]
    part_position_m: tuple[float, float, float] | None = None
    link_radii_m: tuple[float, ...] | None = None
    urdf_file: str | None = None
    urdf_text: str | None = None
    meshes: tuple[tuple[str, bytes], ...] = ()
    source_file: tuple[str, bytes] | None = None

    @property
    def language(self) -> str:
        """The program language its controller runs (``"rapid"``, ``"urscript"``, ``"krl"``)."""
        return builtin.FAMILY_LANGUAGE[self.family]

    @property
    def uploaded(self) -> bool:
        """True for a user's arm (``robots.custom``)."""
        return self.urdf_text is not None

    def urdf(self) -> str:
        """The URDF text."""
        if self.urdf_text is not None:
            return self.urdf_text
        if self.urdf_file is not None:
            return (robots_directory() / self.urdf_file).read_text(encoding="utf-8")
        return builtin.generated_urdf_text(self.name)

    def urdf_path(self) -> Path:
        """The URDF as a file: example-robot-data's, or written into the cache at first use."""
        if self.urdf_file is not None:
            return robots_directory() / self.urdf_file
        if self.urdf_text is None:
            return builtin.generated_urdf_path(self.name)
        return _upload_file(self)


def robots_directory() -> Path:
    """Folder of the URDFs that the ``example-robot-data`` wheel installs (it has no module)."""
    dist = importlib.metadata.distribution("example-robot-data")
    return Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))


def _upload_file(record: Arm) -> Path:
    """An upload's URDF in the robots cache, with the zip's meshes beside it at their paths in
    the zip (for viewers: yourdfpy); written at first use."""
    import os

    from ._urdf import cache_directory

    folder = cache_directory() / record.name
    path = folder / "robot.urdf"
    if not path.is_file():
        for rel, data in record.meshes:
            target = (folder / rel).resolve()
            if folder.resolve() in target.parents:  # no file outside the folder ("../")
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(sanitised_mesh(rel, data))
        folder.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(record.urdf(), encoding="utf-8")
        os.replace(tmp, path)
    return path


_OBJ_FILE_LINES = re.compile(rb"^[ \t]*(mtllib|usemtl|maplib|usemap|call|csh)\b.*$", re.M)
# A COLLADA image's file (1.4: <init_from>file</init_from>, 1.5: <ref>file</ref>): anything
# holding a dot, a slash or a colon (image ids that effects point at hold none).
_DAE_FILES = re.compile(rb"<(init_from|ref)>\s*[^<]*[./\\:][^<]*</(init_from|ref)>")
_MISSING_TEXTURE = b"missing-texture.png"


def sanitised_mesh(path: str, data: bytes) -> bytes:
    """A mesh file as the scene may read it: without its own references to other files (an
    OBJ's material libraries and commands, a COLLADA file's image files, pointed at a name
    that is not there: the geometry loads untextured), which trimesh would read from
    wherever they point. Colours come from the URDF's materials."""
    kind = Path(path).suffix.lower()
    if kind == ".obj":
        return _OBJ_FILE_LINES.sub(b"", data)
    if kind == ".dae":
        return _DAE_FILES.sub(
            lambda m: b"<%s>%s</%s>" % (m.group(1), _MISSING_TEXTURE, m.group(1)), data
        )
    return data


def _kr270_stiffness() -> tuple[float, ...]:
    """The inverse of the compliance paper's Table 1 joint compliances
    k1..k6 = 0.26, 0.15, 0.26, 1.79, 1.52, 2.13 x 1e-6 rad/(N m)."""
    return tuple(1.0 / (c * 1e-6) for c in (0.26, 0.15, 0.26, 1.79, 1.52, 2.13))


def _deg(*values: float) -> tuple[float, ...]:
    return tuple(float(v) for v in np.radians(values))


# Joint stiffness [N*m/rad] chosen so the Cartesian stiffness at the work pose is 0.6-4 N/um,
# the range of industrial arms (the chapter: "usually less than 1 N/um"; under the chapter's
# 300 N feed + 300 N cutting + 50 N normal load the TCP moves about 0.3 mm). The big ABB arms:
# 1.2-3.5 N/um (IRB 4400) and 1.3-6 N/um (IRB 6640) over the translation directions with the
# tool down at their built-in work pose (tests/core/robots/test_abb.py checks the softest one is
# 1-3.5 N/um), stiffer than the UR10 and the chapter's IRB 6400 (~0.5 N/um); the Lund papers'
# IRB 2400 (no joint stiffness published) between the UR10 and the IRB 4400.
# Placements: the big arms stand on the floor, the part on a 0.6 m table further out, where
# the tool-down work pose keeps every axis >= 20 deg inside its range (the IRB 2400 reaching
# lower or nearer meets its combined axis-2/3 limit: at 0.85 m the elbow is 28 deg from
# stretched; the KR 270 keeps every axis >= 44 deg inside). The UR5 (850 mm reach) met its
# elbow singularity at the UR10's 0.8 m; at 0.525 m it learns the pump within 0.216 mm and the
# block within 0.204 mm. The UR3 (500 mm) reaches neither part whole with the tool down: it
# keeps the default and says so.
BUILTIN_ARMS: tuple[Arm, ...] = (
    Arm(
        "ur10", "ur", UR_HOME_JOINTS_RAD, (1.2e6, 1.0e6, 7.0e5, 2.5e5, 2.5e5, 2.0e5),
        link_radii_m=(0.075, 0.060, 0.045, 0.045, 0.045),
        urdf_file="ur_description/urdf/ur10_robot.urdf",
    ),
    Arm(
        "ur5", "ur", UR_HOME_JOINTS_RAD, (6.0e5, 5.0e5, 3.5e5, 1.2e5, 1.2e5, 1.0e5),
        part_position_m=(0.525, 0.0, 0.0), link_radii_m=(0.060, 0.050, 0.040, 0.040, 0.040),
        urdf_file="ur_description/urdf/ur5_robot.urdf",
    ),
    Arm(
        "ur3", "ur", UR_HOME_JOINTS_RAD, (3.0e5, 2.5e5, 1.8e5, 6.0e4, 6.0e4, 5.0e4),
        link_radii_m=(0.045, 0.040, 0.035, 0.035, 0.035),
        urdf_file="ur_description/urdf/ur3_robot.urdf",
    ),
    Arm(
        "irb4400", "abb", _deg(0.0, 22.0, 19.0, 0.0, 49.0, -90.0),
        (4.0e6, 3.5e6, 2.5e6, 4.0e5, 4.0e5, 2.5e5), part_position_m=(1.30, 0.0, 0.60),
    ),
    Arm(
        "irb2400", "abb", _deg(0.0, 4.1, 30.2, 0.0, 55.8, -90.0),
        (2.5e6, 2.0e6, 1.5e6, 2.5e5, 2.5e5, 1.5e5), part_position_m=(0.85, 0.0, 0.60),
    ),
    Arm(
        "irb6640", "abb", _deg(0.0, 0.0, 41.0, 0.0, 49.0, -90.0),
        (8.0e6, 7.0e6, 5.0e6, 8.0e5, 8.0e5, 5.0e5), part_position_m=(1.50, 0.0, 0.60),
    ),
    Arm(
        "kr270", "kuka", _deg(0.0, -69.4, 96.9, 0.0, 62.5, 90.0), _kr270_stiffness(),
        part_position_m=(1.80, 0.0, 0.60),
    ),
)  # fmt: skip
BUILTIN_NAMES: tuple[str, ...] = tuple(a.name for a in BUILTIN_ARMS)
assert set(BUILTIN_NAMES) - {"ur10", "ur5", "ur3"} == set(builtin.GENERATED_ARMS)

_ARMS: dict[str, Arm] = {a.name: a for a in BUILTIN_ARMS}
_LOCK = threading.Lock()


def arm(name: str) -> Arm:
    """The record of the arm ``name`` (any case); ``<upload>_<family>`` is the upload with
    that family's controller (registered on the way).

    Raises:
        UnknownNameError: no such arm (the message lists the built-in ones).
    """
    key = str(name).lower()
    found = _ARMS.get(key)
    if found is None:
        found = _family_variant(key)
    if found is None:
        raise UnknownNameError(
            f"unknown robot {name!r}; choose one of {', '.join(sorted(BUILTIN_NAMES))} or "
            "upload a URDF"
        )
    return found


def known(name: str) -> bool:
    """True when ``arm(name)`` has a record (built-in, uploaded, or a family of an upload)."""
    key = str(name).lower()
    return key in _ARMS or _family_variant(key) is not None


def register(record: Arm) -> Arm:
    """Adds (or replaces) an arm's record; returns it."""
    with _LOCK:
        _ARMS[record.name] = record
    return record


def forget(name: str) -> None:
    """Drops an uploaded arm's record (the built-in ones stay)."""
    if name not in BUILTIN_NAMES:
        with _LOCK:
            _ARMS.pop(name, None)


def _family_variant(name: str) -> Arm | None:
    base, _, family = name.rpartition("_")
    upload = _ARMS.get(base)
    if family not in builtin.ARM_FAMILIES or upload is None or not upload.uploaded:
        return None
    return register(replace(upload, name=name, family=family))
