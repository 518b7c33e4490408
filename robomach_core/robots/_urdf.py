"""URDF text pieces and the cache folder shared by the arms built from published kinematics.

The generated URDFs carry simple shapes (boxes, cylinders) in place of the vendors' meshes:
they are drawn by the GUIs (yourdfpy) and loaded by pinocchio; supervision builds its own
capsules from the joint positions.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

CACHE_ENV = "ROBOMACH_CACHE_DIR"


def number(x: float) -> str:
    """A URDF number: six significant digits."""
    return f"{x:.6g}"


def xyz(*v: float) -> str:
    """Space-separated numbers (``origin xyz``, ``axis xyz``, ``rpy``)."""
    return " ".join(number(x) for x in v)


def visual(shape: str, origin_xyz: tuple[float, ...], rpy: tuple[float, ...], rgba: str) -> str:
    """A ``<visual>`` and the same ``<collision>`` of one shape in a link."""
    geometry = f"<geometry>{shape}</geometry>"
    origin = f'<origin xyz="{xyz(*origin_xyz)}" rpy="{xyz(*rpy)}"/>'
    return (
        f'    <visual>{origin}{geometry}<material name="m"><color rgba="{rgba}"/></material>'
        f"</visual>\n    <collision>{origin}{geometry}</collision>\n"
    )


def box(size: tuple[float, float, float]) -> str:
    """A ``<box>`` geometry [m]."""
    return f'<box size="{xyz(*size)}"/>'


def cylinder(radius: float, length: float) -> str:
    """A ``<cylinder>`` geometry along its z axis [m]."""
    return f'<cylinder radius="{number(radius)}" length="{number(length)}"/>'


def cache_directory() -> Path:
    """Folder for generated files: ``$ROBOMACH_CACHE_DIR``, else ~/.cache/robomach, else /tmp."""
    env = os.environ.get(CACHE_ENV)
    candidates = [Path(env)] if env else []
    candidates += [Path.home() / ".cache" / "robomach", Path(tempfile.gettempdir()) / "robomach"]
    for folder in candidates:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(folder, os.W_OK):
            return folder
    raise OSError("no writable cache folder for generated robot files")


def cached_urdf(name: str, text: str) -> Path:
    """``text`` written once into the cache folder; the file name holds a hash of the content."""
    digest = hashlib.sha256(text.encode()).hexdigest()[:12]
    path = cache_directory() / f"{name.lower()}-{digest}.urdf"
    if not path.is_file():
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)  # atomic: a concurrent reader never sees half a file
    return path
