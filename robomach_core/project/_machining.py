"""The machining stage: the project's program cut on the simulated compliant arm (issue 8).

PROBLEM   The program a project holds is learned from a recording; what it does to the part (how
          long the cut takes, where the force peaks, how far the finished wall ends from the
          nominal one) depends on the stock, the process, the feed controller and the
          deflection compensation, and the configuration the user picks must reach the exports.
STRATEGY  ``MachiningSetup`` (the project's ``machining_settings`` slot) holds the run settings
          (``machining.MachiningSettings``: process K, alpha, beta, force limit, and the CHOSEN
          controller and compensation) and the stock source. ``machine`` cuts the post-processed
          targets (the nominal program: the run applies its own compensation) along the stock,
          one configuration or the matrix, with the project's identified stiffness when it
          holds compensation settings, else ``machining.stiffness_model``. Its result is
          stamped with ``machining_inputs_key``, which leaves the controller and compensation
          out (a comparison covers them all), so choosing never makes a result stale.
SOLUTION  ``choose`` saves the configuration: it sets the machining settings' controller and
          compensation AND the project's ``cmrr`` slot (the FC SpeedChange block, from the same
          reference, speed cap and minimum ratio; None for constant feed) and the
          ``compensation`` slot's mode, so the CMRR settings and the machining choice are one
          thing. ``program_targets`` then exports the run's corrected program when offline
          compensation is chosen and the machining result holding it is current.

The stage's modules: this one (the setup, the result, the choice and what follows it),
``_machining_cut`` (``machine``: the program, its stock and the runs), ``_machining_program``
(what the exported program carries of the choice) and ``_machining_documents`` (JSON forms).

Choice rule (``machining.choice.choose``, the one the CLI, REST and both GUIs use): among the
completed runs the cell can run (``capabilities_of``) whose peak force stays within the
limit, those within 5 % of the fastest cycle time; of these the smallest finished-wall max
error; with a variation sweep (``MachiningSetup.variations``) on the 95th percentiles.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

from ..errors import InvalidInputError
from ..postprocess import Targets
from ._value import Project

STOCK_SOURCES = ("builtin", "profile", "mesh")
# Stocks of a variation sweep (0: the one stock only).
MAX_VARIATIONS = 1000


@dataclass(frozen=True)
class MachiningSetup:
    """The project's machining settings (its ``machining_settings`` slot).

    Attributes:
        settings: ``machining.MachiningSettings``; its ``controller`` and ``compensation`` are
            the chosen configuration.
        stock_source: ``"builtin"`` (from the cell's seed), ``"profile"`` or ``"mesh"``.
        stock_profile_mm: ((s_mm, allowance_mm), ...) for ``"profile"``.
        stock_mesh: (filename, bytes) of a stock mesh (mm, base frame) for ``"mesh"``.
        cell_options: The cell's controller options (``machining.choice.OPTION_NAMES``);
            None: the defaults of the arm's program language.
        variations: Stocks drawn from the part's variation per configuration (0: the one
            stock); the choice then reads the 95th percentiles.
        campaign_stiffness_Nm_rad: The joint stiffness ``choose`` copied into the project's
            compensation slot from the simulated CMM campaign, if it did: compensation
            settings holding it are the campaign, so a result cut with the campaign stays
            current when they are copied in (``inputs_key``).
    """

    settings: Any = None
    stock_source: str = "builtin"
    stock_profile_mm: tuple[tuple[float, float], ...] | None = None
    stock_mesh: tuple[str, bytes] | None = field(default=None, repr=False)
    cell_options: tuple[str, ...] | None = None
    variations: int = 0
    campaign_stiffness_Nm_rad: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.settings is None:
            from ..machining import MachiningSettings

            object.__setattr__(self, "settings", MachiningSettings())
        if self.stock_source not in STOCK_SOURCES:
            raise InvalidInputError(
                f"stock source must be one of {', '.join(STOCK_SOURCES)}, got {self.stock_source!r}"
            )
        if self.stock_source == "profile" and not self.stock_profile_mm:
            raise InvalidInputError("a profile stock needs its allowance profile (s_mm, mm)")
        if self.stock_profile_mm is not None:
            from ..machining.stock import check_profile_mm

            object.__setattr__(self, "stock_profile_mm", check_profile_mm(self.stock_profile_mm))
        if self.stock_source == "mesh" and self.stock_mesh is None:
            raise InvalidInputError("a mesh stock needs its mesh file")
        if self.cell_options is not None:
            from ..machining.choice import CellCapabilities

            options = tuple(sorted(CellCapabilities(frozenset(self.cell_options)).options))
            object.__setattr__(self, "cell_options", options)
        if isinstance(self.variations, bool) or not (
            isinstance(self.variations, int) and 0 <= self.variations <= MAX_VARIATIONS
        ):
            raise InvalidInputError(
                f"variations must be an integer within 0-{MAX_VARIATIONS}, got {self.variations!r}"
            )

    def key(self) -> str:
        """Fingerprint of what a result depends on: everything but the chosen controller and
        compensation (a comparison covers every configuration)."""
        return self._key

    @cached_property
    def _key(self) -> str:
        from ..machining import settings_to_dict

        doc = settings_to_dict(self.settings)
        doc.pop("controller", None)
        doc.pop("compensation", None)
        doc.pop("controller_settings", None)
        if doc.get("stages") == "online":  # the default: results saved before it keep their key
            doc.pop("stages")
        h = hashlib.blake2b(digest_size=12)
        h.update(json.dumps(doc, sort_keys=True, default=str).encode())
        h.update(self.stock_source.encode())
        h.update(json.dumps(self.stock_profile_mm).encode())
        if self.variations:
            h.update(f"variations {self.variations}".encode())
        if self.stock_mesh is not None:
            h.update(self.stock_mesh[0].encode())
            h.update(self.stock_mesh[1])
        return h.hexdigest()

    def inputs_key(self, project: Project) -> str:
        """``key`` and where the stiffness the compensated runs use comes from: the project's
        compensation settings, or the simulated campaign (named by its arm and settings, not
        run: ``Project.status`` stays cheap), the same whether or not ``choose`` copied the
        campaign's stiffness in."""
        comp = project.compensation
        robot = project.cell.robot
        if comp is not None and comp.robot == robot:
            own = tuple(float(k) for k in comp.joint_stiffness_Nm_rad)
            if own != self.campaign_stiffness_Nm_rad:
                return f"{self.key()}:{json.dumps(own)}"
        s = self.settings
        campaign = f"campaign {robot} {s.seed} {s.identification_poses} {s.cmm_noise_m!r}"
        return f"{self.key()}:{campaign}"


@dataclass(frozen=True, eq=False)
class MachiningResult:
    """The machining stage's result (the project's ``machining`` slot).

    Attributes:
        rows: One dict per configuration (``machining.comparison_rows``: units in the keys;
            with a variation sweep also its p50 / p95 figures), ``runnable`` and ``needs``
            marked for the cell it was chosen for.
        table_text: The side-by-side table.
        chosen: Index into ``rows`` of the rule's pick (``machining.choice.choose``); None
            when the cell can run no completed configuration.
        programs: "controller/compensation" -> corrected program of each offline run.
        runs: The ``MachiningRun`` values (traces), when computed in this process.
        stock: The ``machining.Stock`` cut (None when read back from a store).
        inputs: ``machining_inputs_key`` of the project it was computed from.
        reason: The rule's reason for ``chosen``, in words.
        capabilities: The cell options the rows were marked for.
        variation: The variation sweep (stocks, seed, ranges) or None.
    """

    rows: tuple[dict[str, Any], ...]
    table_text: str
    chosen: int | None
    programs: dict[str, Targets]
    runs: tuple[Any, ...] = ()
    stock: Any = None
    inputs: str = ""
    reason: str = ""
    capabilities: tuple[str, ...] = ()
    variation: dict[str, Any] | None = None

    def summary(self) -> dict[str, Any]:
        """``machining_summary.json``: the runs, the rule's pick and why."""
        from ..machining import table_notes
        from ..machining.choice import RULE_TEXT

        chosen = None if self.chosen is None else self.rows[self.chosen]
        return {
            "runs": [dict(r, chosen=i == self.chosen) for i, r in enumerate(self.rows)],
            "chosen": None
            if chosen is None
            else {"controller": chosen["controller"], "compensation": chosen["compensation"]},
            "choice_rule": RULE_TEXT,
            "choice_reason": self.reason,
            "notes": table_notes(self.rows),
            "cell_options": list(self.capabilities),
            "variation": self.variation,
        }

    def for_cell(self, capabilities: Any) -> MachiningResult:
        """The result re-chosen for another cell (rows re-marked; the figures are the same)."""
        from ..machining import format_table
        from ..machining.choice import choose, mark_runnable

        rows = tuple(mark_runnable(list(self.rows), capabilities))
        pick = choose(list(rows), capabilities)
        return replace(
            self,
            rows=rows,
            table_text=format_table(rows, chosen=pick.index),
            chosen=pick.index,
            reason=pick.reason,
            capabilities=tuple(sorted(capabilities.options)),
        )

    def run_for(self, controller: str, compensation: str) -> Any:
        """The ``MachiningRun`` of a configuration, or None."""
        for run in self.runs:
            if run.controller == controller and run.compensation == compensation:
                return run
        return None


def capabilities_of(project: Project) -> Any:
    """The cell's controller options: the machining setup's (those the arm's controller can
    have: ``machining.choice.OPTION_FAMILIES``), else the defaults of the program language of
    the cell's arm (``machining.choice.LANGUAGE_DEFAULT_OPTIONS``)."""
    from ..machining.choice import CellCapabilities

    family = _arm_family(project.cell.robot)
    setup = project.machining_settings
    if isinstance(setup, MachiningSetup) and setup.cell_options is not None:
        return CellCapabilities.for_family(family, setup.cell_options)
    try:
        from ..cell import program_language

        language = program_language(project.cell.robot)
    except Exception:  # an arm not (yet) registered in this process: no options assumed
        return CellCapabilities(frozenset(), family)
    return CellCapabilities.for_language(language)


def _arm_family(robot_name: str) -> str | None:
    """The arm's family (``abb``, ``ur``, ``kuka``), None when it is not registered here."""
    from ..robots import registry

    try:
        return registry.arm(robot_name).family
    except Exception:  # an arm not (yet) registered in this process
        return None


def machining_setup_of(project: Project) -> MachiningSetup:
    """The project's machining setup (defaults when it holds none), its controller and
    compensation read from the project's CMRR and compensation slots: those are what the
    exports carry, so the machining choice and the CMRR settings cannot disagree (a CMRR
    controller set another way, e.g. from a study, is the machining controller; without
    machining settings, its reference force too)."""
    setup = project.machining_settings
    if not isinstance(setup, MachiningSetup):
        setup = MachiningSetup()
        if project.cmrr is None and project.compensation is None:
            return setup
    controller = "constant" if project.cmrr is None else project.cmrr.controller.kind
    comp = project.compensation
    compensation = "off" if comp is None else comp.mode
    s = setup.settings
    # without machining settings, the CMRR's reference force (a study's, --cmrr-settings) is the
    # machining's; a reference over the limit brings the limit the default fraction pairs with
    # it (a study's 200 N: 286 N). With them, their reference rules (a choice copies it).
    reference = {}
    own_settings = isinstance(project.machining_settings, MachiningSetup)
    if (
        project.cmrr is not None
        and not own_settings
        and abs(project.cmrr.reference_force_N - s.reference_N) > 1e-9
    ):
        f_ref = project.cmrr.reference_force_N
        reference = {"reference_force_N": f_ref}
        if f_ref > s.force_limit_N:
            from ..machining.settings import DEFAULT_REFERENCE_FRACTION

            reference["force_limit_N"] = f_ref / DEFAULT_REFERENCE_FRACTION
    if (s.controller, s.compensation) == (controller, compensation) and not reference:
        return setup
    own = s.controller_settings
    s = replace(
        s,
        controller=controller,
        compensation=compensation,
        controller_settings=own if own is not None and own.kind == controller else None,
        **reference,
    )
    return replace(setup, settings=s)


def compensation_model(project: Project, robot_name: str) -> Any:
    """The identified stiffness: the project's compensation settings when it holds some (on this
    robot), else the simulated CMM campaign of ``machining.stiffness_model``."""
    from ..cell import JointCompliance
    from ..machining import stiffness_model

    comp = project.compensation
    if comp is not None and comp.robot == robot_name:
        return JointCompliance(tuple(comp.joint_stiffness_Nm_rad))
    return stiffness_model(robot_name, machining_setup_of(project).settings)


def best_row(
    rows: tuple[dict[str, Any], ...] | list[dict[str, Any]], capabilities: Any = None
) -> int | None:
    """Index of the configuration to choose (``machining.choice.choose``; every configuration
    counts as runnable without ``capabilities``); None when none completed."""
    from ..machining.choice import OPTION_NAMES, CellCapabilities, choose

    caps = capabilities or CellCapabilities(frozenset(OPTION_NAMES))
    return choose(list(rows), caps).index


def with_machining_result(project: Project, result: MachiningResult) -> Project:
    """The project holding ``result`` (stamped with the key it was computed from)."""
    return replace(project, machining=result, machining_inputs=result.inputs)


def with_machining_setup(project: Project, setup: MachiningSetup) -> Project:
    """The project with new machining settings; the chosen configuration follows them into the
    CMRR and compensation slots (``choose``).

    Raises:
        MachiningSettingsError: a cell option the arm's controller cannot have (FC SpeedChange
            on a KUKA).
    """
    if setup.cell_options is not None:
        from ..machining.choice import check_options_for_arm

        robot = project.cell.robot
        check_options_for_arm(setup.cell_options, _arm_family(robot), robot)
    project = replace(project, machining_settings=setup)
    return choose(project, setup.settings.controller, setup.settings.compensation)


def choose(project: Project, controller: str, compensation: str) -> Project:
    """Save the configuration the exports carry: the machining settings' controller and
    compensation, the CMRR slot (the FC SpeedChange block; None for constant feed) and the
    compensation slot's mode (module docstring)."""
    from ..machining import MACHINING_CONTROLLERS
    from ..stiffness.modes import COMPENSATIONS

    if controller not in MACHINING_CONTROLLERS:
        raise InvalidInputError(
            f"unknown controller {controller!r}; choose one of {', '.join(MACHINING_CONTROLLERS)}"
        )
    if compensation not in COMPENSATIONS:
        raise InvalidInputError(
            f"unknown compensation {compensation!r}; choose one of {', '.join(COMPENSATIONS)}"
        )
    setup = machining_setup_of(project)
    s = replace(setup.settings, controller=controller, compensation=compensation)
    if s.controller_settings is not None and s.controller_settings.kind != controller:
        s = replace(s, controller_settings=None)
    setup = replace(setup, settings=s)
    project = replace(project, machining_settings=setup)
    project = replace(project, cmrr=cmrr_for(s, designed=_designed_settings(project, controller)))
    comp = project.compensation
    if compensation != "off" and (comp is None or comp.robot != project.cell.robot):
        from ..stiffness import CompensationSettings

        model = compensation_model(replace(project, compensation=None), project.cell.robot)
        stiffness = tuple(float(k) for k in model.stiffness_Nm_rad)
        comp = CompensationSettings(
            robot=project.cell.robot,
            joint_stiffness_Nm_rad=stiffness,
            mode="off",
            # another arm's settings: their offline model stays the user's
            offline_model=(
                CompensationSettings.offline_model if comp is None else comp.offline_model
            ),
        )
        setup = replace(setup, campaign_stiffness_Nm_rad=stiffness)
        project = replace(project, machining_settings=setup)
    if comp is not None:
        gravity = comp.tool_gravity
        if compensation == "online" and gravity is None:
            # Not identified here: the tool's nominal mass and centre of mass, no sensor bias.
            from ..cell import ToolGravity

            tool = project.tool()
            gravity = ToolGravity.from_tool(tool)
        # The same word in both slots; an offline model the settings hold stays theirs.
        comp = replace(comp, mode=compensation, tool_gravity=gravity)
    return replace(project, compensation=comp)


def _designed_settings(project: Project, controller: str) -> Any:
    """The controller's settings as the current machining result designed them for the cut
    (``machining.design``: e.g. the two-stage low stage), or None."""
    result = project.machining
    if not isinstance(result, MachiningResult) or project.status()["machining"] != "current":
        return None
    from ..cmrr.settings import controller_settings_from_dict

    for row in result.rows:
        doc = row.get("controller_settings")
        if row["controller"] == controller and doc:
            try:
                return controller_settings_from_dict(controller, doc)
            except InvalidInputError:
                return None
    return None


def cmrr_for(settings: Any, *, designed: Any = None) -> Any:
    """The CMRR settings of a machining configuration (None for constant feed): the same
    controller (as ``designed`` for the cut, when given), reference force, speed cap and
    minimum speed ratio the run used."""
    if settings.controller == "constant":
        return None
    from ..cmrr import CmrrSettings
    from ..cmrr.controllers import settings_for

    return CmrrSettings(
        controller=settings.controller_settings or designed or settings_for(settings.controller),
        reference_force_N=settings.reference_N,
        command_speed_m_s=settings.command_speed_cap_m_s,
        min_speed_ratio=settings.min_speed_ratio,
    )


def planned_schedule(project: Project) -> bool:
    """Whether the chosen configuration's feed is a stage schedule planned offline
    (``machining.schedule``): offline compensation under a staged controller, chosen from a
    current machining result whose run of it cut the program's own speeds. Its program then
    carries the schedule as its speeds and no feed control."""
    result = project.machining
    if not isinstance(project.machining_settings, MachiningSetup) or not isinstance(
        result, MachiningResult
    ):
        return False
    s = machining_setup_of(project).settings
    if s.stages != "planned" or s.compensation != "offline":
        return False  # the default: the stages switch in the cell
    if f"{s.controller}/offline" not in result.programs:
        return False
    if project.status()["machining"] != "current":
        return False
    return any(
        (r["controller"], r["compensation"]) == (s.controller, "offline")
        and r.get("feed") == "program"
        for r in result.rows
    )


def chosen_feed(project: Project) -> str:
    """The chosen configuration's feed source (``machining.run.FeedSource``)."""
    return "program" if planned_schedule(project) else "controller"


def with_runnable_choice(project: Project) -> tuple[Project, str]:
    """The project whose machining choice its cell can run: a part of the chosen
    configuration the cell's controller lacks (after a cell change: a UR10's force-mode feed
    control in a KUKA cell) goes back to the neutral one (constant feed, no compensation),
    and a sentence says what was cleared and why ("" when nothing was). A program never
    carries a choice its controller cannot run (issue 31: the KRL header said "MISSING in
    this cell")."""
    from ..machining.choice import REQUIREMENT_TEXT, missing

    if project.cmrr is None and project.compensation is None:
        return project, ""  # the neutral choice: nothing to clear
    s = machining_setup_of(project).settings
    caps = capabilities_of(project)
    lacks = missing(s.controller, s.compensation, caps, chosen_feed(project))
    if not lacks:
        return project, ""
    controller = "constant" if "feed_override" in lacks else s.controller
    compensation = "off" if "online_correction" in lacks else s.compensation
    cleared = choose(project, controller, compensation)
    why = " and ".join(REQUIREMENT_TEXT[r] for r in lacks)
    return cleared, (
        f"The machining choice {s.controller} / {s.compensation} needs {why}, which the "
        f"{project.cell.robot}'s controller does not have here, so it is now {controller} / "
        f"{compensation}. Compare the configurations again to choose among those it can run."
    )


def stale_settings(project: Project) -> dict[str, str]:
    """Settings that belong to another arm than the cell's, with a sentence each: they are
    re-derived for the cell's arm when the program is exported, not a reason to refuse it."""
    comp = project.compensation
    if comp is not None and comp.robot != project.cell.robot:
        return {
            "compensation": (
                f"the compensation's joint stiffness was identified on {comp.robot}; the "
                f"export re-derives it for {project.cell.robot} (simulated CMM campaign)"
            )
        }
    return {}


def compensation_for_arm(project: Project, robot_name: str) -> Any:
    """The project's compensation settings for ``robot_name``: as they are when identified on
    it, else re-derived (the simulated CMM campaign's stiffness, the same mode and tool)."""
    comp = project.compensation
    if comp is None or comp.robot == robot_name:
        return comp
    model = compensation_model(replace(project, compensation=None), robot_name)
    return replace(
        comp,
        robot=robot_name,
        joint_stiffness_Nm_rad=tuple(float(k) for k in model.stiffness_Nm_rad),
    )
