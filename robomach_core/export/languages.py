"""The registry of program languages: one line per language, everything else reads it.

PROBLEM   A program language used to be typed in robot.py, the writers, the CLI's choices, a
          Session method, a route file and the GUIs' menus, so adding one touched ten files; and
          an arm was offered languages its controller does not run.
STRATEGY  A ``ProgramLanguage`` names the language, its file suffixes, its writer (a function
          of a ``ProgramContext``), the arm families whose controllers run it, whether it has a
          force-controlled variant and how to read the poses back (the reachability check).
          ``program_files`` (project), the export route ``GET /api/export/program/{language}``,
          the CLI's ``--language`` choices, the viser and pendant menus all list
          ``languages()`` or ``languages_for(robot)``; nothing else names a language.
SOLUTION  ``register_language`` (a new language: one writer module plus one call),
          ``languages``, ``language``, ``languages_for``, ``language_choices``,
          ``program_file_names``; the built-in RAPID, URScript and KRL are registered below.

RAPID is also written for the UR arms, beside their URScript: the FC SpeedChange block (CMRR)
and the Force Control variant exist only in RAPID, and the machining study, the CLI's
summary and saved exports of UR cells carry ``program.mod`` as the method's reference
program. The ABB arms get RAPID only, the KUKA arms KRL only.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InvalidInputError, UnknownNameError

if TYPE_CHECKING:  # names only: the writers import these at run time, the registry need not
    from ..cell import Robot, Tool
    from ..part import Workpiece
    from ..postprocess import Move, Targets
    from .rapid import SpeedChangeSettings
    from .urscript_feed import UrFeedLoop

AUTO = "auto"  # the languages of the arm's controller
PROGRAM_STEM = "program"
FORCE_CONTROL_STEM = "program_fc"


@dataclass(frozen=True)
class ProgramContext:
    """What a writer gets: the program's targets and everything around them.

    Attributes:
        targets: In the base frame, their joints the IK of each target on ``robot``
            (``project.program_targets``).
        tool: The tool on the flange (its TCP and payload).
        workpiece: The part (its ``T_base_wobj`` is the work object).
        robot: The arm, with the tool as its TCP.
        moves: The move sequence (circular moves, ``postprocess.arcs``), or None for a linear
            move to each target.
        comment: Header comment lines.
        module_name: The program's name where the language has one (RAPID's MODULE).
        force_control_N: The force-controlled variant pressing with this force; None for the
            position-controlled program.
        speed_change: The FC SpeedChange block of a CMRR controller (RAPID), or None.
        feed_loop: The feed loop a UR program of a CMRR controller runs itself, or None.
    """

    targets: Targets
    tool: Tool
    workpiece: Workpiece
    robot: Robot
    moves: Sequence[Move] | None
    comment: tuple[str, ...]
    module_name: str
    force_control_N: float | None = None
    speed_change: SpeedChangeSettings | None = None
    feed_loop: UrFeedLoop | None = None


@dataclass(frozen=True)
class ProgramLanguage:
    """One program language.

    Attributes:
        name: Key in every choice (``"rapid"``); lower case letters, digits and ``_``.
        title: For menus (``"ABB RAPID"``).
        suffixes: File suffixes of one program, in the order ``write`` returns their texts
            (``(".mod",)``, ``(".src", ".dat")``).
        write: ``write(context) -> texts``, one per suffix.
        families: Arm families whose controllers run it (``robots.builtin.ARM_FAMILIES``).
        force_control: It has a force-controlled variant (``context.force_control_N``).
        read_poses: ``read_poses(texts, workpiece) -> [(name, T_base_tcp)]``, the motion
            targets read back from the written files; None: no reachability check.
        default_arm: The built-in arm a job gets when this language is asked for and no arm.
        media_type: Of one file in a download.
    """

    name: str
    title: str
    suffixes: tuple[str, ...]
    write: Callable[[ProgramContext], tuple[str, ...]]
    families: tuple[str, ...]
    force_control: bool = False
    read_poses: Callable[[tuple[str, ...], Workpiece], list[tuple[str, np.ndarray]]] | None = None
    default_arm: str | None = None
    media_type: str = "text/plain; charset=utf-8"

    def file_names(self, *, force_control: bool = False) -> tuple[str, ...]:
        """``program.mod`` / ``program_fc.mod``, ``program.src`` + ``program.dat``, ..."""
        stem = FORCE_CONTROL_STEM if force_control else PROGRAM_STEM
        return tuple(stem + suffix for suffix in self.suffixes)


_REGISTRY: dict[str, ProgramLanguage] = {}


def register_language(language: ProgramLanguage, *, replace: bool = False) -> ProgramLanguage:
    """Add a language to every menu, choice and route; returns it.

    Raises:
        InvalidInputError: the name is not lower-case letters, digits and ``_``, is ``auto``,
            is taken (unless ``replace``), or the language has no suffix.
    """
    name = language.name
    if not name or not name.replace("_", "").isalnum() or name != name.lower() or name == AUTO:
        raise InvalidInputError(f"a language name is lower-case letters and digits, not {name!r}")
    if name in _REGISTRY and not replace:
        raise InvalidInputError(f"a language {name!r} is already registered")
    if not language.suffixes or not all(s.startswith(".") for s in language.suffixes):
        raise InvalidInputError(f"language {name!r}: suffixes must start with a dot")
    _REGISTRY[name] = language
    return language


def unregister_language(name: str) -> None:
    """Remove a language (tests that register a toy one); unknown names are ignored."""
    _REGISTRY.pop(name, None)


def languages() -> tuple[ProgramLanguage, ...]:
    """Every registered language, in registration order."""
    return tuple(_REGISTRY.values())


def language_names() -> tuple[str, ...]:
    """The registered languages' names."""
    return tuple(_REGISTRY)


def language_choices() -> tuple[str, ...]:
    """``auto`` and every language's name: the CLI's ``--language`` choices."""
    return (AUTO, *_REGISTRY)


def language(name: str) -> ProgramLanguage:
    """A registered language by name.

    Raises:
        UnknownNameError: no such language (the message lists them).
    """
    try:
        return _REGISTRY[name.lower()]
    except (KeyError, AttributeError):
        raise UnknownNameError(
            f"unknown program language {name!r}; choose one of {', '.join(_REGISTRY)}"
        ) from None


def languages_for_family(family: str) -> tuple[ProgramLanguage, ...]:
    """The languages whose ``families`` include ``family``."""
    return tuple(lang for lang in _REGISTRY.values() if family in lang.families)


def languages_for(robot: Robot) -> tuple[ProgramLanguage, ...]:
    """The languages the arm's controller is offered (``robot.family``)."""
    return languages_for_family(robot.family)


def resolve_languages(robot: Robot, choice: str = AUTO) -> tuple[ProgramLanguage, ...]:
    """The languages to write for ``choice``: ``auto`` -> every language of the arm's family;
    a name -> that language, if the arm's controller runs it.

    Raises:
        UnknownNameError: no such language.
        InvalidInputError: the arm's controller does not run it.
    """
    if choice == AUTO:
        return languages_for(robot)
    chosen = language(choice)
    if robot.family not in chosen.families:
        offered = ", ".join(lang.name for lang in languages_for(robot)) or "none"
        raise InvalidInputError(
            f"the {robot.name} arm's controller does not run {chosen.title} "
            f"({chosen.name} is for {', '.join(chosen.families)} arms); its languages: {offered}"
        )
    return (chosen,)


def default_arm(choice: str, fallback: str = "ur10") -> str:
    """The built-in arm a job gets when none is named: the chosen language's default arm."""
    if choice == AUTO:
        return fallback
    return language(choice).default_arm or fallback


# ---------------------------------------------------------------------------------------------
# The built-in languages: their writers, behind the registry's one signature.


def _write_rapid(context: ProgramContext) -> tuple[str, ...]:
    from ..robots import ABB_ARMS
    from .program import rapid_program
    from .rapid import rapid_module

    robot = context.robot
    program = rapid_program(
        context.targets,
        context.tool,
        context.workpiece,
        module_name=context.module_name,
        force_control_N=context.force_control_N,
        speed_change=None if context.force_control_N else context.speed_change,
        comment=context.comment,
        arm=robot.name if robot.name in ABB_ARMS else None,
        moves=context.moves,
    )
    return (rapid_module(program),)


def _rapid_poses(texts: tuple[str, ...], workpiece: Workpiece) -> list[tuple[str, np.ndarray]]:
    from ..transforms import make_transform, matrix_from_quaternion
    from .rapid_check import check_rapid_module

    info = check_rapid_module(texts[0])
    return [
        (
            name,
            workpiece.T_base_wobj
            @ make_transform(matrix_from_quaternion(quat), np.asarray(pos) * 1e-3),
        )
        for name, (pos, quat, _conf) in info.robtargets.items()
    ]


def _write_urscript(context: ProgramContext) -> tuple[str, ...]:
    from .urscript import urscript_program

    return (
        urscript_program(
            context.targets,
            context.tool,
            context.workpiece,
            force_control_N=context.force_control_N,
            comment=context.comment,
            arcs=context.moves,
            feed_loop=None if context.force_control_N else context.feed_loop,
        ),
    )


def _urscript_poses(texts: tuple[str, ...], workpiece: Workpiece) -> list[tuple[str, np.ndarray]]:
    from scipy.spatial.transform import Rotation

    from ..transforms import make_transform
    from .urscript import script_poses

    out = []
    for k, (kind, poses) in enumerate(script_poses(texts[0])):
        for j, pose in enumerate(poses):
            R = Rotation.from_rotvec(pose[3:]).as_matrix()
            name = f"path{j + 1}" if kind == "path" else f"move{k + 1}.{j + 1}"
            out.append((name, make_transform(R, pose[:3])))
    return out


def _write_krl(context: ProgramContext) -> tuple[str, ...]:
    from .krl import krl_program

    return krl_program(
        context.targets,
        context.tool,
        context.workpiece,
        context.robot,
        comment=context.comment,
        moves=context.moves,
    )


def _krl_poses(texts: tuple[str, ...], workpiece: Workpiece) -> list[tuple[str, np.ndarray]]:
    from .krl_check import check_krl_program

    return check_krl_program(texts[0], texts[1]).motion_poses()


RAPID = register_language(
    ProgramLanguage(
        name="rapid",
        title="ABB RAPID",
        suffixes=(".mod",),
        write=_write_rapid,
        families=("abb", "ur"),
        force_control=True,
        read_poses=_rapid_poses,
        default_arm="irb4400",
    )
)
URSCRIPT = register_language(
    ProgramLanguage(
        name="urscript",
        title="UR URScript",
        suffixes=(".script",),
        write=_write_urscript,
        families=("ur",),
        force_control=True,
        read_poses=_urscript_poses,
        default_arm="ur10",
    )
)
KRL = register_language(
    ProgramLanguage(
        name="krl",
        title="KUKA KRL",
        suffixes=(".src", ".dat"),
        write=_write_krl,
        families=("kuka",),
        force_control=False,
        read_poses=_krl_poses,
        default_arm="kr270",
    )
)
