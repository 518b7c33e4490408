"""The identified stiffness model and the compensation mode as JSON settings.

The file is a boundary: stiffness in N*m/rad, lengths in mm, forces in N, every field named with
its unit. It travels with the exported program, and the workbench and API read it back.

Format version 2 names the compensation in the one vocabulary (``stiffness.modes``): ``mode``
``off``, ``offline`` or ``online`` and ``offline_model`` ``linear`` or ``nonlinear``. Version 1
files (and projects saved with them) spelled the offline model into the mode
(``offline_linear``, ``offline_nonlinear``); they are read by ``modes.read_compensation``'s rule
(``offline`` with that model) and written back as version 2.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..cell import JointCompliance, ToolGravity
from ..limits import (
    FORCE_FILTER_CUTOFF_HZ,
    JOINT_STIFFNESS_NM_RAD,
    JOINT_STIFFNESS_STD_NM_RAD,
    SENSOR_FORCE_BIAS_N,
    SENSOR_TORQUE_BIAS_NM,
    TOOL_COM_MM,
    TOOL_MASS_KG,
    Range,
)
from .compensation import FORCE_FILTER_CUTOFF_HZ as DEFAULT_CUTOFF_HZ
from .errors import SettingsFileError
from .modes import (
    COMPENSATIONS,
    DEFAULT_OFFLINE_MODEL,
    OFFLINE_MODELS,
    Compensation,
    OfflineModel,
    read_compensation,
)

SETTINGS_FORMAT = "robomach.compensation"
SETTINGS_VERSION = 2
# Versions read: 1 spelled the offline model into the mode (module docstring).
READ_VERSIONS = (1, 2)


@dataclass(frozen=True)
class CompensationSettings:
    """What the controller needs to compensate deflection.

    Attributes:
        robot: Robot model name.
        joint_stiffness_Nm_rad: (6,) identified Kq.
        mode: ``"off"``, ``"offline"`` (corrected robtargets) or ``"online"`` (chapter
            fig. 15): ``stiffness.modes.Compensation``.
        offline_model: How the offline mode corrects the targets: ``"linear"`` or
            ``"nonlinear"`` (eq. 32); kept, and unused, in the other modes.
        joint_stiffness_std_Nm_rad: (6,) one-sigma uncertainty, if known.
        tool_gravity: Identified tool weight and sensor bias (needed online).
        force_filter_cutoff_hz: Low-pass on the measured wrench (online).
    """

    robot: str
    joint_stiffness_Nm_rad: tuple[float, ...]
    mode: Compensation = "online"
    joint_stiffness_std_Nm_rad: tuple[float, ...] | None = None
    tool_gravity: ToolGravity | None = None
    force_filter_cutoff_hz: float = DEFAULT_CUTOFF_HZ
    offline_model: OfflineModel = DEFAULT_OFFLINE_MODEL

    def __post_init__(self) -> None:
        if self.mode not in COMPENSATIONS:  # old spellings are read at the boundaries only
            raise SettingsFileError(
                f"compensation mode {self.mode!r} is not one of {', '.join(COMPENSATIONS)}"
                " (an offline model goes in offline_model)"
            )
        if self.offline_model not in OFFLINE_MODELS:
            raise SettingsFileError(
                f"offline model {self.offline_model!r} is not one of {', '.join(OFFLINE_MODELS)}"
            )
        JointCompliance(tuple(self.joint_stiffness_Nm_rad))  # validates the six values
        FORCE_FILTER_CUTOFF_HZ.check(
            self.force_filter_cutoff_hz, "force_filter_cutoff_hz", error=SettingsFileError
        )
        if self.mode == "online" and self.tool_gravity is None:
            raise SettingsFileError("online compensation needs the identified tool gravity")

    @property
    def model(self) -> JointCompliance:
        return JointCompliance(tuple(self.joint_stiffness_Nm_rad))


def settings_to_dict(settings: CompensationSettings) -> dict[str, Any]:
    """JSON-ready dict (units in the field names)."""
    out: dict[str, Any] = {
        "format": SETTINGS_FORMAT,
        "version": SETTINGS_VERSION,
        "robot": settings.robot,
        "mode": settings.mode,
        "offline_model": settings.offline_model,
        "joint_stiffness_Nm_rad": [float(k) for k in settings.joint_stiffness_Nm_rad],
        "force_filter_cutoff_hz": settings.force_filter_cutoff_hz,
    }
    if settings.joint_stiffness_std_Nm_rad is not None:
        out["joint_stiffness_std_Nm_rad"] = [float(s) for s in settings.joint_stiffness_std_Nm_rad]
    if settings.tool_gravity is not None:
        g = settings.tool_gravity
        out["tool"] = {
            "mass_kg": g.mass_kg,
            "com_mm": [float(v) * 1e3 for v in g.com_m],
            "force_bias_N": [float(v) for v in g.force_bias_N],
            "torque_bias_Nm": [float(v) for v in g.torque_bias_Nm],
        }
    return out


def _floats(data: dict, key: str, count: int, rng: Range) -> tuple[float, ...]:
    """``count`` numbers under ``key``, each within ``rng`` (the message names the range)."""
    value = data.get(key)
    if not isinstance(value, list) or len(value) != count:
        raise SettingsFileError(f"{key!r} must be a list of {count} numbers")
    try:
        numbers = tuple(float(v) for v in value)
    except (TypeError, ValueError, OverflowError):
        raise SettingsFileError(f"{key!r} must be a list of {count} numbers") from None
    if not all(math.isfinite(v) for v in numbers):
        raise SettingsFileError(f"{key!r} must hold finite numbers")
    for v in numbers:
        rng.check(v, key, error=SettingsFileError)
    return numbers


def settings_from_dict(data: dict[str, Any]) -> CompensationSettings:
    """Parse and validate a settings dict.

    Raises:
        SettingsFileError: wrong format or version, missing or malformed fields.
    """
    if not isinstance(data, dict) or data.get("format") != SETTINGS_FORMAT:
        raise SettingsFileError(f"not a compensation settings file (format {SETTINGS_FORMAT!r})")
    if data.get("version") not in READ_VERSIONS:
        raise SettingsFileError(
            f"settings version {data.get('version')!r} is not supported (this robomach reads "
            f"{', '.join(map(str, READ_VERSIONS))})"
        )
    if not isinstance(data.get("robot"), str):
        raise SettingsFileError("'robot' must be a robot name")
    tool = None
    if "tool" in data:
        t = data["tool"]
        if not isinstance(t, dict):
            raise SettingsFileError("'tool' must be an object")
        mass = _floats({"mass_kg": [t.get("mass_kg")]}, "mass_kg", 1, TOOL_MASS_KG)[0]
        cx, cy, cz = _floats(t, "com_mm", 3, TOOL_COM_MM)
        fx, fy, fz = _floats(t, "force_bias_N", 3, SENSOR_FORCE_BIAS_N)
        tx, ty, tz = _floats(t, "torque_bias_Nm", 3, SENSOR_TORQUE_BIAS_NM)
        tool = ToolGravity(
            mass_kg=mass,
            com_m=(cx * 1e-3, cy * 1e-3, cz * 1e-3),
            force_bias_N=(fx, fy, fz),
            torque_bias_Nm=(tx, ty, tz),
        )
    std = None
    if "joint_stiffness_std_Nm_rad" in data:
        std = _floats(data, "joint_stiffness_std_Nm_rad", 6, JOINT_STIFFNESS_STD_NM_RAD)
    mode, model = read_compensation(
        data.get("mode", CompensationSettings.mode),
        data.get("offline_model"),
        name="compensation mode",
        error=SettingsFileError,
    )
    try:
        default_cutoff = CompensationSettings.force_filter_cutoff_hz
        cutoff = float(data.get("force_filter_cutoff_hz", default_cutoff))
        return CompensationSettings(
            robot=data["robot"],
            joint_stiffness_Nm_rad=_floats(
                data, "joint_stiffness_Nm_rad", 6, JOINT_STIFFNESS_NM_RAD
            ),
            mode=mode,
            offline_model=model,
            joint_stiffness_std_Nm_rad=std,
            tool_gravity=tool,
            force_filter_cutoff_hz=cutoff,
        )
    except SettingsFileError:
        raise
    except (TypeError, ValueError, OverflowError) as exc:
        raise SettingsFileError(f"invalid compensation settings: {exc}") from None


def save_settings(settings: CompensationSettings, path: str | Path) -> Path:
    """Write the settings as indented JSON; returns the path."""
    target = Path(path)
    target.write_text(json.dumps(settings_to_dict(settings), indent=2) + "\n", encoding="utf-8")
    return target


def load_settings(path: str | Path) -> CompensationSettings:
    """Read settings written by ``save_settings``.

    Raises:
        SettingsFileError: the file is missing, not JSON, or not valid settings.
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SettingsFileError(f"settings file {path} does not exist") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SettingsFileError(f"cannot read settings file {path}: {exc}") from None
    return settings_from_dict(data)
