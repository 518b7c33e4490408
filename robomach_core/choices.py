"""Every named choice and every number range a user meets, gathered for the boundaries.

PROBLEM   The CLI's choices, the REST schemas, the viser widgets and the pendant's page each
          typed the controller names, the compensation modes, the wall sides and the ranges
          again, and the copies drifted (the pendant took 10-20 N for learning, the core 1-50;
          the viser slider 0.02-2 mm for the tolerance, the core 0.01-5).
STRATEGY  Each enum is defined once where its meaning lives (the CMRR controllers with their
          settings classes, the program languages in their registry, the wall sides with the
          wall-side decision, ...), each range once in ``limits``; the few choices that belong
          to no other module (jog frames, click modes, the tool's nearest face) are defined
          here. This module names them all, so every boundary derives its list from here.
SOLUTION  ``enums()`` name -> values, ``LABELS`` the words a menu shows, ``TEXTS`` the
          sentences every page shows alike, ``ranges()`` name ->
          ``limits.Range``, and ``catalogue()`` the JSON document the pendant reads from
          ``GET /api/choices``. A contract test fails when a boundary types a copy.
"""

from __future__ import annotations

from typing import Any, Literal, get_args

from . import limits
from .cell import AXES, ComplianceFrame

JogFrame = Literal["base", "tool", "wobj"]
JOG_FRAMES: tuple[JogFrame, ...] = get_args(JogFrame)
COMPLIANCE_FRAMES: tuple[ComplianceFrame, ...] = get_args(ComplianceFrame)
# A touch-off moves along a translational axis only: the first three of ``AXES``, spelt out so
# that a type checker reads ``TouchAxis`` as a type (``Literal[AXES[:3]]`` is not one).
TouchAxis = Literal["x", "y", "z"]
TOUCH_AXES: tuple[TouchAxis, ...] = get_args(TouchAxis)
assert TOUCH_AXES == AXES[:3]
# What a click on the part does in the 3-D scene (both GUIs follow the same setting).
ClickMode = Literal["propose", "teach", "move", "touch", "off"]
CLICK_MODES: tuple[ClickMode, ...] = get_args(ClickMode)
# What the face of the part nearest the tool is: a wall, a floor (faces up) or an underside.
NearestFace = Literal["wall", "floor", "underside"]
NEAREST_FACES: tuple[NearestFace, ...] = get_args(NearestFace)

LABELS: dict[str, dict[str, str]] = {
    "jog_frame": {"base": "base", "tool": "tool", "wobj": "work object"},
    "offline_model": {"linear": "linear", "nonlinear": "non-linear (eq. 32)"},
    "compliance_frame": {"base": "base frame", "tool": "tool frame"},
    "cell_option": {
        "fc_speed_change": "FC SpeedChange",
        "path_correction": "path correction",
        "force_mode": "force mode",
    },
    "click_mode": {
        "propose": "propose the wall",
        "teach": "teach a point",
        "move": "move the selected point",
        "touch": "touch the face (calibration)",
        "off": "nothing",
    },
}


# The sentences every page shows the same (the pendant reads them from ``GET /api/choices``):
# one set of rules in one vocabulary (docs/guide_points.md says them at length).
TEXTS: dict[str, Any] = {
    "guide_point_advice": (
        "A guide point: 1-3 mm from the wall, or touching it with a light push (2-10 N) that "
        "tells the wall side; the tool axis as it should machine, the same turn about it at "
        "every point. Corners and bosses need no point of their own: the run follows the wall "
        "round them by force. Never record in heavy contact. See docs/guide_points.md."
    ),
    # How a finding of the check before a run is marked, by its severity.
    "severity": {
        "refusal": "refused: learning will not start",
        "warning": "warning",
        "info": "note",
    },
    # Glyphs of the fonts every system has (DejaVu: a no-entry sign showed as an empty box).
    "severity_icon": {"refusal": "\u2716", "warning": "\u26a0", "info": "\u2139"},
}


def enums() -> dict[str, tuple[str, ...]]:
    """Every named choice: name -> its values, in the order menus show them."""
    from .cell import ROBOT_NAMES
    from .cmrr import CONTROLLER_NAMES, SCENARIO_NAMES
    from .export.languages import language_choices, language_names
    from .learning.settings import WALL_SIDE_CHOICES
    from .machining.choice import OPTION_NAMES
    from .machining.settings import STAGE_PLANS
    from .part import WORKPIECE_NAMES
    from .project import STOCK_SOURCES, StageStatus
    from .robots import ARM_FAMILIES
    from .stiffness.modes import COMPENSATIONS, OFFLINE_MODELS
    from .stiffness.studies import StudyName
    from .teaching.pointing import PointKind, Reach

    return {
        "cmrr_controller": tuple(CONTROLLER_NAMES),
        "compensation": tuple(COMPENSATIONS),
        "offline_model": tuple(OFFLINE_MODELS),
        "machining_stages": tuple(STAGE_PLANS),
        "program_language": tuple(language_names()),
        "language_choice": tuple(language_choices()),
        "wall_side": tuple(WALL_SIDE_CHOICES),
        "arm_family": tuple(ARM_FAMILIES),
        "robot": tuple(ROBOT_NAMES),
        "workpiece": tuple(WORKPIECE_NAMES),
        "jog_frame": JOG_FRAMES,
        "compliance_frame": COMPLIANCE_FRAMES,
        "compliance_axis": tuple(AXES),
        "touch_axis": TOUCH_AXES,
        "click_mode": CLICK_MODES,
        "nearest_face": NEAREST_FACES,
        "cell_option": tuple(OPTION_NAMES),
        "stock_source": tuple(STOCK_SOURCES),
        "cmrr_scenario": tuple(SCENARIO_NAMES),
        "compensation_study": get_args(StudyName),
        "stage_status": get_args(StageStatus),
        "proposed_point_kind": get_args(PointKind),
        "reach": get_args(Reach),
    }


def ranges() -> dict[str, limits.Range]:
    """Every physical range of ``limits``: its name there -> the range."""
    return {name: value for name, value in vars(limits).items() if isinstance(value, limits.Range)}


def catalogue() -> dict[str, Any]:
    """The JSON document of every choice and range (``GET /api/choices``): ``enums`` name ->
    ``{"values": [...], "labels": {value: words}}``, ``ranges`` name -> ``{"label", "min",
    "max", "unit", "integer", "text", "default"}`` (``default``: null where the user must
    give the number), ``texts`` the sentences every page shows alike (``TEXTS``)."""
    return {
        "texts": TEXTS,
        "enums": {
            name: {"values": list(values), "labels": LABELS.get(name, {v: v for v in values})}
            for name, values in enums().items()
        },
        "ranges": {
            name: {
                "label": r.label,
                "min": r.min,
                "max": r.max,
                "unit": r.unit,
                "integer": r.integer,
                "text": r.text(),
                "default": r.default,
            }
            for name, r in ranges().items()
        },
    }
