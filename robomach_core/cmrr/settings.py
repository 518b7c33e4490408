"""CMRR settings to and from JSON, and to the RAPID exporter's FC SpeedChange block.

The JSON is the boundary format (mm, N, s in the key names)::

    {"format": "robomach-cmrr-settings", "version": 1, "controller": "two-stage",
     "reference_force_N": 200.0, "command_speed_mm_s": 100.0, "min_speed_ratio": 0.1,
     "feedback": "force", "controller_settings": {"low_speed_ratio": 0.5, ...}}
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..limits import (
    CMRR_COMMAND_SPEED_MM_S,
    CMRR_MAX_STUDY_SAMPLES,
    CMRR_MIN_SPEED_RATIO,
    CMRR_REFERENCE_FORCE_N,
)
from .controllers import SETTINGS_CLASSES, ControllerSettings, settings_for
from .controllers.fuzzy import FuzzySettings, TwoStageSettings
from .errors import CmrrSettingsError, UnknownControllerError
from .process import FeedbackSignal

if TYPE_CHECKING:
    from robomach_core.export.rapid import SpeedChangeSettings

    from .scenarios import Scenario

SETTINGS_FORMAT = "robomach-cmrr-settings"
SETTINGS_VERSION = 1
MM = 1e-3
# Continuous controllers map to ABB's staged SpeedChange with stages this far apart at most.
CONTINUOUS_STAGE_STEP = 0.1


@dataclass(frozen=True)
class CmrrSettings:
    """A controller and the cut it runs on: what goes to the robot program."""

    controller: ControllerSettings
    reference_force_N: float
    command_speed_m_s: float
    min_speed_ratio: float
    feedback: FeedbackSignal = "force"

    def __post_init__(self) -> None:
        check_cmrr_numbers(
            reference_force_N=self.reference_force_N,
            command_speed_mm_s=self.command_speed_m_s / MM,
            min_speed_ratio=self.min_speed_ratio,
        )
        if self.feedback not in ("force", "spindle_current"):
            raise CmrrSettingsError(f"feedback must be force or spindle_current: {self.feedback}")


def check_cmrr_numbers(
    *,
    reference_force_N: object = None,
    command_speed_mm_s: object = None,
    min_speed_ratio: object = None,
) -> None:
    """Raise ``CmrrSettingsError`` naming the range when a given (non-None) number is outside
    ``robomach_core.limits``' CMRR ranges."""
    for value, rng, name in (
        (reference_force_N, CMRR_REFERENCE_FORCE_N, "reference_force_N"),
        (command_speed_mm_s, CMRR_COMMAND_SPEED_MM_S, "command_speed_mm_s"),
        (min_speed_ratio, CMRR_MIN_SPEED_RATIO, "min_speed_ratio"),
    ):
        if value is not None:
            rng.check(value, name, error=CmrrSettingsError)


def study_samples(scenario: Scenario, controllers: int = 1) -> int:
    """Control samples a study of ``controllers`` controllers on ``scenario`` may simulate:
    each runs at most ``time_limit_s / dt_s`` steps, whose arrays are allocated up front."""
    per_controller = math.ceil(scenario.time_limit_s / scenario.dt_s) + 1
    return int(controllers) * per_controller


def check_study_size(scenario: Scenario, controllers: int = 1) -> int:
    """The study's sample count (``study_samples``); ``CmrrSettingsError`` above
    ``CMRR_MAX_STUDY_SAMPLES``, before any memory is allocated."""
    total = study_samples(scenario, controllers)
    if total > CMRR_MAX_STUDY_SAMPLES:
        raise CmrrSettingsError(
            f"this study would simulate up to {total:,} control samples ({controllers} "
            f"controller(s) on {scenario.path_length_m * 1e3:.0f} mm at "
            f"{scenario.command_speed_m_s / MM:g} mm/s), more than the "
            f"{CMRR_MAX_STUDY_SAMPLES:,} allowed: raise the command speed or the minimum speed "
            "ratio, or run fewer controllers"
        )
    return total


def cmrr_settings_for(scenario: Scenario, controller: ControllerSettings) -> CmrrSettings:
    """The settings of ``controller`` on ``scenario``'s cut."""
    return CmrrSettings(
        controller=controller,
        reference_force_N=scenario.reference_force_N,
        command_speed_m_s=scenario.command_speed_m_s,
        min_speed_ratio=scenario.min_speed_ratio,
        feedback=scenario.feedback,
    )


def controller_settings_to_dict(settings: ControllerSettings) -> dict[str, Any]:
    """The controller's own fields (without ``kind``), tuples as lists."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(settings):
        if f.name == "kind":
            continue
        value = getattr(settings, f.name)
        out[f.name] = list(value) if isinstance(value, tuple) else value
    return out


def controller_settings_from_dict(kind: str, data: dict[str, Any]) -> ControllerSettings:
    """Build controller settings of ``kind`` from JSON fields; unknown or bad fields raise."""
    if kind not in SETTINGS_CLASSES:
        settings_for(kind)  # raises UnknownControllerError with the list of names
    cls = SETTINGS_CLASSES[kind]
    allowed = {f.name for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise CmrrSettingsError(f"{kind}: unknown setting(s) {', '.join(unknown)}")
    kwargs = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
    try:
        return cls(**kwargs)
    except (TypeError, ValueError, OverflowError) as exc:
        if isinstance(exc, CmrrSettingsError):
            raise
        raise CmrrSettingsError(f"{kind}: {exc}") from None


def settings_to_dict(settings: CmrrSettings) -> dict[str, Any]:
    """JSON-ready dict of the settings (mm, N, s)."""
    return {
        "format": SETTINGS_FORMAT,
        "version": SETTINGS_VERSION,
        "controller": settings.controller.kind,
        "reference_force_N": settings.reference_force_N,
        "command_speed_mm_s": settings.command_speed_m_s / MM,
        "min_speed_ratio": settings.min_speed_ratio,
        "feedback": settings.feedback,
        "controller_settings": controller_settings_to_dict(settings.controller),
    }


def settings_from_dict(data: Any) -> CmrrSettings:
    """Inverse of ``settings_to_dict``; raises ``CmrrSettingsError`` on malformed input."""
    if not isinstance(data, dict):
        raise CmrrSettingsError("CMRR settings must be a JSON object")
    if data.get("format", SETTINGS_FORMAT) != SETTINGS_FORMAT:
        raise CmrrSettingsError(f"not a CMRR settings file (format {data.get('format')!r})")
    if data.get("version", SETTINGS_VERSION) != SETTINGS_VERSION:
        raise CmrrSettingsError(f"unsupported CMRR settings version {data.get('version')!r}")
    required = ("controller", "reference_force_N", "command_speed_mm_s", "min_speed_ratio")
    missing = [k for k in required if k not in data]
    if missing:
        raise CmrrSettingsError(f"CMRR settings lack {', '.join(missing)}")
    extra = set(data) - {*required, "format", "version", "feedback", "controller_settings"}
    if extra:
        raise CmrrSettingsError(f"unknown CMRR setting(s) {', '.join(sorted(extra))}")
    inner = data.get("controller_settings", {})
    if not isinstance(inner, dict):
        raise CmrrSettingsError("controller_settings must be a JSON object")
    try:
        controller = controller_settings_from_dict(str(data["controller"]), inner)
    except UnknownControllerError as exc:
        raise CmrrSettingsError(str(exc)) from None
    check_cmrr_numbers(
        reference_force_N=data["reference_force_N"],
        command_speed_mm_s=data["command_speed_mm_s"],
        min_speed_ratio=data["min_speed_ratio"],
    )
    try:
        return CmrrSettings(
            controller=controller,
            reference_force_N=float(data["reference_force_N"]),
            command_speed_m_s=float(data["command_speed_mm_s"]) * MM,
            min_speed_ratio=float(data["min_speed_ratio"]),
            feedback=data.get("feedback", "force"),
        )
    except (TypeError, ValueError, OverflowError) as exc:
        if isinstance(exc, CmrrSettingsError):
            raise
        raise CmrrSettingsError(f"CMRR settings: {exc}") from None


def save_settings(settings: CmrrSettings, path: str | Path) -> Path:
    """Write the settings as indented JSON."""
    out = Path(path)
    out.write_text(json.dumps(settings_to_dict(settings), indent=2) + "\n")
    return out


def load_settings(path: str | Path) -> CmrrSettings:
    """Read settings written by ``save_settings``."""
    try:
        data = json.loads(Path(path).read_text())
    except OSError as exc:
        raise CmrrSettingsError(f"cannot read CMRR settings {path}: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise CmrrSettingsError(f"CMRR settings {path} is not valid JSON: {exc}") from None
    return settings_from_dict(data)


def speed_levels(settings: CmrrSettings) -> tuple[int, float] | None:
    """(number of speed stages, lowest speed ratio) for FCSpdChgTunSet; None for constant feed.

    The staged controllers map one to one (five stages 0.2 ... 1.0 -> 5, 0.2; two-stage
    0.5 / 1.0 -> 2, 0.5). ABB's SpeedChange is staged, so a continuous controller (PI,
    self-tuning PI, LQ) maps to the finest staging of its range [delta, 1] with steps of at
    most 0.1; its gains stay in the JSON (the robot's own tuning is not set from them).
    """
    c = settings.controller
    if c.kind == "constant":
        return None
    if isinstance(c, TwoStageSettings):
        return 2, c.low_speed_ratio
    if isinstance(c, FuzzySettings):
        return len(c.stages), c.stages[0]
    delta = settings.min_speed_ratio
    levels = max(2, math.ceil(round((1.0 - delta) / CONTINUOUS_STAGE_STEP, 9)) + 1)
    return levels, delta


def to_speed_change_settings(settings: CmrrSettings) -> SpeedChangeSettings | None:
    """The RAPID exporter's FC SpeedChange block for these settings (None: constant feed)."""
    from robomach_core.export.rapid import SpeedChangeSettings

    levels = speed_levels(settings)
    if levels is None:
        return None
    n, lowest = levels
    return SpeedChangeSettings(
        reference_force_N=settings.reference_force_N, speed_levels=n, min_speed_ratio=lowest
    )
