"""A user's own serial 6-axis arm from a URDF file (or a zip of the URDF and its meshes).

PROBLEM   Users bring arms the workbench does not ship. Pinocchio builds any URDF, but the rest
          of the cell needs more than a kinematic tree: a serial chain of exactly six actuated
          joints with limits (the IK, supervision and confdata assume it), a flange frame
          ``tool0``, a home pose above the part, a placement of the part in reach, and the
          simulator's joint stiffness. A bad file must be refused with what is wrong in it.
STRATEGY  ``validate_urdf`` parses the XML (no mesh is loaded), walks the chain from the root
          link and names the first fault: not XML, no or several root links, a branch, a
          joint of an unsupported type, a revolute joint without limits, not six revolute
          joints. The chain's last link gets a fixed ``tool0`` child when the file has none.
          ``register_urdf`` registers the arm's record (``robots.registry``: URDF text, home,
          family and program language, part placement, joint stiffness) under a
          content-addressed name. An arm with a built-in arm's kinematics
          (``robots.recognise``: a UR5 copied out of example-robot-data) is that arm: its
          family (a UR gets URScript), placement, home and stiffness. Any other arm is taken
          for an ABB controller's (RAPID, as before), the part in front of it at 62 % of its
          reach and 0.1 reach below the shoulder but not below the base (near the UR10's and
          IRB 4400's placements), its home the IK of the tool pointing down 150 mm above the
          part. The user may name the controller's family at upload (``family``): the arm is
          then registered under the name with ``_<family>`` appended, so the choice is part of
          the name the project keeps.
SOLUTION  ``register_urdf(filename, data, family="auto") -> name``; ``Robot(name)`` then
          builds it like a built-in arm. The project keeps the file's bytes
          (``Project.robot_urdf``) and registers it again when opened, so the name is stable
          across restarts (a ``_<family>`` name is registered again on first use).
"""

from __future__ import annotations

import hashlib
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import RobomachError
from . import registry
from .urdf_check import check_urdf_native, check_urdf_text, read_package_meshes, read_robot_zip

MAX_ROBOT_FILE_BYTES = 50 * 1024 * 1024
ROBOT_FILE_SUFFIXES = (".urdf", ".zip")
NAME_PREFIX = "urdf_"
FLANGE_LINK = "tool0"
HOME_CLEARANCE_M = 0.10  # elbow and wrist joints above the table at home


class RobotFileError(RobomachError, ValueError):
    """A robot file is not a serial 6-axis URDF with joint limits (the message says why)."""


@dataclass(frozen=True)
class UrdfChain:
    """The serial chain of a URDF.

    Attributes:
        robot_name: The ``<robot name>`` attribute.
        links: Link names from the root to the last link.
        joints: Names of the six revolute joints, base to wrist.
        lower_rad: (6,) lower limits.
        upper_rad: (6,) upper limits.
        has_flange: The file has a ``tool0`` link.
    """

    robot_name: str
    links: tuple[str, ...]
    joints: tuple[str, ...]
    lower_rad: np.ndarray
    upper_rad: np.ndarray
    has_flange: bool


def validate_urdf(text: str) -> UrdfChain:
    """The serial chain of ``text``, or ``RobotFileError`` naming what is wrong."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotFileError(f"the URDF is not valid XML ({exc})") from None
    if root.tag != "robot":
        raise RobotFileError(f"the URDF's root element is <{root.tag}>, expected <robot>")
    names = [link.get("name") for link in root.findall("link")]
    links = [name for name in names if name is not None]
    joints = root.findall("joint")
    if len(links) < len(names):
        raise RobotFileError("the URDF has a <link> without a name")
    if not links:
        raise RobotFileError("the URDF has no <link>")
    children: dict[str, list[ET.Element]] = {}
    child_links = set()
    for joint in joints:
        parent, child = joint.find("parent"), joint.find("child")
        parent_link = None if parent is None else parent.get("link")
        child_link = None if child is None else child.get("link")
        if parent_link is None or child_link is None:
            raise RobotFileError(f"joint {joint.get('name')!r} lacks a <parent> or <child> link")
        children.setdefault(parent_link, []).append(joint)
        child_links.add(child_link)
    roots = [name for name in links if name not in child_links]
    if len(roots) != 1:
        raise RobotFileError(
            f"the URDF has {len(roots)} root links ({', '.join(map(str, roots)) or 'none'}); "
            "a serial arm has one"
        )
    chain_links, revolute, lower, upper = [roots[0]], [], [], []
    link = roots[0]
    while link in children:
        outgoing = children[link]
        moving = [j for j in outgoing if j.get("type") != "fixed" or link_has_children(j, children)]
        if len(moving) > 1:
            raise RobotFileError(
                f"link {link!r} branches into joints "
                f"{', '.join(repr(j.get('name')) for j in moving)}: not a serial chain"
            )
        joint = (moving or outgoing)[0]
        kind, name = joint.get("type"), joint.get("name")
        if name is None:
            raise RobotFileError(f"a joint of the chain after link {link!r} has no name")
        if kind in ("continuous", "prismatic", "floating", "planar"):
            raise RobotFileError(
                f"joint {name!r} is {kind}: a supported arm has six revolute joints with limits"
            )
        if kind == "revolute":
            limit = joint.find("limit")
            bounds = {} if limit is None else limit.attrib
            try:
                lo, hi = float(bounds["lower"]), float(bounds["upper"])
            except (KeyError, ValueError):
                raise RobotFileError(
                    f"revolute joint {name!r} has no <limit lower=... upper=...>"
                ) from None
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise RobotFileError(f"revolute joint {name!r} has limits {lo} >= {hi}")
            revolute.append(name)
            lower.append(lo)
            upper.append(hi)
        elif kind != "fixed":
            raise RobotFileError(f"joint {name!r} has an unknown type {kind!r}")
        link = _child_link(joint)
        chain_links.append(link)
    if len(revolute) != 6:
        raise RobotFileError(
            f"the chain from {roots[0]!r} to {link!r} has {len(revolute)} revolute joints "
            f"({', '.join(revolute) or 'none'}); a supported arm has exactly 6"
        )
    return UrdfChain(
        robot_name=root.get("name") or "robot",
        links=tuple(chain_links),
        joints=tuple(revolute),
        lower_rad=np.array(lower),
        upper_rad=np.array(upper),
        has_flange=FLANGE_LINK in links,
    )


def link_has_children(joint: ET.Element, children: dict[str, list[ET.Element]]) -> bool:
    """True when the joint's child link carries further joints (part of the chain)."""
    return _child_link(joint) in children


def _child_link(joint: ET.Element) -> str:
    """The name of the link ``joint`` moves (``validate_urdf`` requires one of every joint)."""
    child = joint.find("child")
    link = None if child is None else child.get("link")
    if link is None:
        raise RobotFileError(f"joint {joint.get('name')!r} lacks a <child> link")
    return link


def with_flange(text: str, chain: UrdfChain) -> str:
    """The URDF with a fixed ``tool0`` link on the chain's last link when it has none."""
    if chain.has_flange:
        return text
    addition = (
        f'<link name="{FLANGE_LINK}"/>'
        f'<joint name="{FLANGE_LINK}_fixed" type="fixed"><parent link="{chain.links[-1]}"/>'
        f'<child link="{FLANGE_LINK}"/><origin xyz="0 0 0" rpy="0 0 0"/></joint>'
    )
    closing = text.rstrip().rfind("</robot>")
    return text[:closing] + addition + text[closing:]


def urdf_from_file(filename: str, data: bytes) -> tuple[str, dict[str, bytes]]:
    """The URDF text (and the zip's other files by path) of an uploaded ``.urdf`` or ``.zip``."""
    suffix = Path(filename).suffix.lower()
    if suffix not in ROBOT_FILE_SUFFIXES:
        raise RobotFileError(
            f"{filename}: expected a .urdf file or a .zip holding one (and its meshes)"
        )
    if len(data) > MAX_ROBOT_FILE_BYTES:
        raise RobotFileError(
            f"{filename}: {len(data) / 1e6:.1f} MB exceeds the "
            f"{MAX_ROBOT_FILE_BYTES / 1e6:.0f} MB limit"
        )
    if suffix == ".urdf":
        text = _decode(filename, data)
        check_urdf_text(text, filename, RobotFileError)  # bounded before it is parsed whole
        return text, read_package_meshes(text, filename, RobotFileError)
    # Declared sizes summed before extraction; only the files the URDF references are read.
    return read_robot_zip(filename, data, RobotFileError)


def _decode(filename: str, data: bytes) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise RobotFileError(f"{filename}: not UTF-8 text") from None


def read_robot_file(path: Path) -> tuple[str, bytes]:
    """(filename, bytes) of a robot file given on the command line, checked for size."""
    if not path.is_file():
        raise RobotFileError(f"{path}: no such file")
    if path.stat().st_size > MAX_ROBOT_FILE_BYTES:
        raise RobotFileError(f"{path.name}: exceeds the {MAX_ROBOT_FILE_BYTES / 1e6:.0f} MB limit")
    return path.name, path.read_bytes()


def robot_name_for(filename: str, data: bytes) -> str:
    """The registered name of a robot file: ``urdf_<stem>_<8 hex digits of its content>``."""
    stem = re.sub(r"[^a-z0-9]+", "_", Path(filename).stem.lower()).strip("_")[:24] or "arm"
    return f"{NAME_PREFIX}{stem}_{hashlib.blake2b(data, digest_size=4).hexdigest()}"


def is_custom(name: str) -> bool:
    """True for a registered user arm (a ``_<family>`` variant of a registered one is
    registered on the way)."""
    return registry.known(name) and registry.arm(name).uploaded


def urdf_text(name: str) -> str:
    """The normalised URDF text of a registered user arm."""
    return registry.arm(name).urdf()


def mesh_path(record: registry.Arm, reference: str) -> str:
    """The file a ``<mesh filename>`` of an upload's URDF names, inside the upload's own folder
    in the cache (``urdf_check.resolve_reference``): "" (no file) for a reference that names no
    member of the upload. The scene's loader (yourdfpy) reads an upload's meshes through this,
    so it cannot read a file of the server's disk (issue 32)."""
    from .urdf_check import resolve_reference

    member = resolve_reference(reference, [m for m, _ in record.meshes])
    if member is None or record.urdf_text is None:
        return ""
    folder = record.urdf_path().parent.resolve()
    target = (folder / member).resolve()
    return str(target) if folder in target.parents and target.is_file() else ""


def urdf_file(name: str) -> Path:
    """The registered arm's URDF as a file for viewers (``Arm.urdf_path``)."""
    return registry.arm(name).urdf_path()


def uploaded_file(name: str) -> tuple[str, bytes]:
    """The file a registered user arm came from, (filename, bytes), as the user gave it."""
    source = registry.arm(name).source_file
    if source is None:
        raise RobotFileError(f"{name!r} is not an uploaded arm")
    return source


def register_urdf(filename: str, data: bytes, family: str = "auto") -> str:
    """Validate a robot file and register its arm; returns the name ``Robot`` takes.

    Args:
        filename, data: The uploaded file.
        family: The controller's family (``robots.builtin.ARM_FAMILIES``), or ``"auto"``: the
            family of the built-in arm with the same kinematics, else ABB's (RAPID).

    Raises:
        RobotFileError: not a .urdf/.zip, too large, not XML, or not a serial chain of six
            revolute joints with limits (the message names the fault); an unknown family.
    """
    from .builtin import ARM_FAMILIES

    if family != "auto" and family not in ARM_FAMILIES:
        raise RobotFileError(
            f"unknown controller family {family!r}; choose auto, {', '.join(ARM_FAMILIES)}"
        )
    name = _register_file(filename, data)
    if family == "auto" or registry.arm(name).family == family:
        return name
    return registry.arm(f"{name}_{family}").name


def _register_file(filename: str, data: bytes) -> str:
    """``register_urdf`` with the family found from the kinematics."""
    from ..cell import robot as robot_module
    from .recognise import recognise_arm

    name = robot_name_for(filename, data)
    if registry.known(name):
        return name
    text, files = urdf_from_file(filename, data)
    check_urdf_text(text, filename, RobotFileError)  # size, links, depth: before any parser
    chain = validate_urdf(text)
    normalised = with_flange(text, chain)
    check_urdf_native(normalised, filename, RobotFileError)  # pinocchio once, in a child
    import pinocchio as pin

    try:
        model = pin.buildModelFromXML(normalised)
    except Exception as exc:  # pinocchio raises std exceptions for malformed models
        raise RobotFileError(f"{filename}: pinocchio cannot build the model ({exc})") from None
    if model.nq != 6:
        raise RobotFileError(f"{filename}: the model has {model.nq} joints, expected 6")
    lower, upper = model.lowerPositionLimit, model.upperPositionLimit
    same = recognise_arm(model)
    if same is not None:  # a built-in arm's kinematics: its controller, placement, home
        twin = registry.arm(same)
        home = tuple(np.clip(twin.home_rad, lower, upper))
        registry.register(
            replace(
                twin, name=name, home_rad=home, urdf_file=None, urdf_text=normalised,
                meshes=tuple(files.items()), source_file=(filename, bytes(data)),
            )
        )  # fmt: skip
        return name
    # A placeholder home until the IK below finds one; the stiffness of an arm of its size.
    record = registry.Arm(
        name, "abb", tuple(np.clip(np.zeros(6), lower, upper)),
        registry.arm("ur10").stiffness_Nm_rad, urdf_text=normalised, meshes=tuple(files.items()),
        source_file=(filename, bytes(data)),
    )  # fmt: skip
    registry.register(record)
    arm = robot_module.Robot(name)
    reach = arm.reach_m
    shoulder_z = float(arm.base_to_shoulder_m[2])
    if reach > 1.5:
        record = replace(record, stiffness_Nm_rad=registry.arm("irb4400").stiffness_Nm_rad)
    # ``reach_m`` is an upper bound (link lengths summed): nearer placements are tried too.
    for fraction in (0.62, 0.5, 0.4, 0.3):
        wobj = (fraction * reach, 0.0, max(0.0, shoulder_z - 0.1 * reach))
        try:
            home_rad = _home(name, np.array(wobj))
        except RobomachError:
            continue
        registry.register(replace(record, home_rad=tuple(home_rad), part_position_m=wobj))
        return name
    registry.forget(name)
    raise RobotFileError(
        f"{filename}: the arm cannot point its tool down above a part placed in front of it "
        f"(tried 30-62 % of its {reach:.2f} m reach)"
    )


def _home(name: str, wobj_m: np.ndarray) -> np.ndarray:
    """Joints putting the default tool down 150 mm above the middle of a built-in part, with
    the elbow and wrist at least ``HOME_CLEARANCE_M`` above the part's base (the table)."""
    import pinocchio as pin

    from ..cell import TOOL_DOWN, Tool
    from ..cell import robot as robot_module
    from ..transforms import make_transform

    arm = robot_module.Robot(name, Tool().T_flange_tcp)
    goal = make_transform(TOOL_DOWN, wobj_m + np.array([0.125, 0.09, 0.15]))
    rng = np.random.default_rng(0)
    mid = 0.5 * (arm.lower_rad + arm.upper_rad)
    seeds = [np.zeros(6), robot_module.HOME_JOINTS_RAD, mid]
    seeds += [rng.uniform(arm.lower_rad, arm.upper_rad) for _ in range(60)]
    data = arm.model.createData()
    for seed in seeds:
        try:
            q = arm.ik(goal, np.clip(seed, arm.lower_rad, arm.upper_rad))
        except RobomachError:
            continue
        pin.forwardKinematics(arm.model, data, q)
        lowest = min(data.oMi[i].translation[2] for i in range(3, arm.model.njoints))
        if (
            arm.singular_value_min(q) > 10 * robot_module.SINGULAR_VALUE_MIN
            and lowest > wobj_m[2] + HOME_CLEARANCE_M
        ):
            return q
    raise RobotFileError("no home pose")
