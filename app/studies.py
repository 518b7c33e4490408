"""The process-control studies of the workbench: CMRR and deformation compensation as jobs.

PROBLEM   The GUI and the REST API both start CMRR studies (``robomach_core.cmrr``) and the
          stiffness / compensation studies (``robomach_core.stiffness``), watch their progress,
          cancel them, show the last result's numbers and plots, and keep the settings with the
          project so that they survive a restart.
STRATEGY  One ``StudyService`` per session, built with it (``Session.studies``) and read by
          the GUI and the API, submits each study to the session's ``JobRunner``,
          so it shows in ``/api/jobs`` and cancels like any job. A run
          writes the core's files into a fresh folder under ``<data>/studies/.tmp``; when it is
          done, the folder replaces ``<data>/studies/<project id>/<kind>/`` and the summary and
          settings JSON are saved in the project's store as the exports ``_study-cmrr`` and
          ``_study-compensation`` (names no export may take; the old ``cmrr-study`` and
          ``compensation-study`` are read once and moved). Opening a project loads them back
          (plots from the folder). Before a study is queued its numbers are checked against
          ``robomach_core.limits``, a CMRR study's samples against the cap, and the queue
          against ``MAX_ACTIVE_STUDIES`` (``StudyQueueFullError``, 429); a study that fails
          anyway ends as a failed job with a one-line message (``StudyFailedError``).
          Every folder name is made here from fixed names and integer ids, never from input.
SOLUTION  Public API (thread-safe):

  start_cmrr(scenario, controller, seed=, reference_force_N=, command_speed_mm_s=) -> job_id
  start_compensation(study, quick=, seed=, mode=, offline_model=) -> job_id
  cmrr_result() / compensation_result() -> CmrrOutcome | CompensationOutcome | None
  cmrr_settings_json(controller=None) / compensation_settings_json() -> str
  compensation_plot(name) -> bytes
  subscribe(callback) -> unsubscribe      callback("cmrr" | "compensation") after a study
                                          ends (done or not) or the project changes
"""

from __future__ import annotations

import functools
import json
import logging
import math
import os
import shutil
import tempfile
import threading
import time
import uuid
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, get_args

from robomach_core.cmrr import CONTROLLER_NAMES, SCENARIO_NAMES
from robomach_core.cmrr.errors import (
    UnknownControllerError,
    UnknownScenarioError,
)
from robomach_core.cmrr.settings import check_cmrr_numbers, check_study_size
from robomach_core.errors import InvalidInputError, RobomachError
from robomach_core.limits import SEED
from robomach_core.stiffness import StudyOptions, read_compensation
from robomach_core.stiffness.errors import UnknownStudyError
from robomach_core.stiffness.studies import StudyName

from .session.jobs import JobContext
from .session.records import ConflictError, JobInfo, NotFoundError

if TYPE_CHECKING:
    from robomach_core.cmrr.scenarios import Scenario

    from .session import Session

log = logging.getLogger(__name__)

StudyKind = Literal["cmrr", "compensation"]
CompensationStudy = StudyName
COMPENSATION_STUDIES: tuple[CompensationStudy, ...] = get_args(CompensationStudy)
CMRR_CONTROLLER_CHOICES: tuple[str, ...] = (*CONTROLLER_NAMES, "all")

CMRR_JOB_KIND = "cmrr_study"
COMPENSATION_JOB_KIND = "compensation_study"
# The names the studies are saved under in the project's exports. They start with "_", which
# no export name may (``EXPORT_NAME_RE``), so no export can replace a study; the old names are
# read once, when a project saved before them has no study under the new ones.
CMRR_EXPORT = "_study-cmrr"
COMPENSATION_EXPORT = "_study-compensation"
LEGACY_EXPORTS = {CMRR_EXPORT: "cmrr-study", COMPENSATION_EXPORT: "compensation-study"}
# Queued and running studies at once, of both kinds: each holds its arrays in memory.
MAX_ACTIVE_STUDIES = 2
STUDY_META_FILE = "study.json"
CMRR_SUMMARY_FILE = "cmrr_summary.json"
CMRR_SETTINGS_FILE = "cmrr_settings.json"
CMRR_PLOT_FILE = "cmrr.png"
COMPENSATION_SUMMARY_FILE = "compensation_summary.json"
COMPENSATION_SETTINGS_FILE = "compensation_settings.json"
STUDIES_FOLDER = "studies"
TMP_FOLDER = ".tmp"
SEED_MAX = int(SEED.max)
# Share of a CMRR job's progress bar for the simulation; the rest is writing CSV and plot.
CMRR_SIMULATION_SHARE = 0.9


class StudyQueueFullError(RobomachError, RuntimeError):
    """Too many studies are queued or running: wait for one to end or cancel one."""


class StudyFailedError(RobomachError, RuntimeError):
    """A study stopped on a numerical or internal failure; its message says which."""


# --- the last results -----------------------------------------------------------------------


@dataclass(frozen=True)
class CmrrOutcome:
    """The last CMRR study of the open project.

    Attributes:
        scenario: Scenario name.
        controller: Controller name, or ``"all"`` for a comparison.
        seed: Seed of the sensor noise.
        summary: ``cmrr_summary.json`` (units in the key names; NaN as None).
        settings: ``cmrr_settings.json``: one controller's settings, or a list with ``all``.
        plot_png: The figure, or None when it is not on disk any more.
        finished_s: Unix time the study ended.
        folder: Where the CSV, summary, plot and settings files are, when they are on disk.
    """

    scenario: str
    controller: str
    seed: int
    summary: dict[str, Any]
    settings: dict[str, Any] | list[dict[str, Any]]
    plot_png: bytes | None
    finished_s: float
    folder: Path | None = None

    @property
    def controllers(self) -> list[str]:
        """The controllers the study ran."""
        if isinstance(self.settings, list):
            return [s["controller"] for s in self.settings]
        return [self.settings["controller"]]


@dataclass(frozen=True)
class CompensationOutcome:
    """The last compensation study of the open project.

    Attributes:
        study: identify, gravity, milling, ilc, compliance or all.
        quick: Shorter cuts and fewer poses.
        seed: Seed of every random element.
        summary: ``compensation_summary.json`` (µm, mm, N in the key names; NaN as None).
        settings: ``compensation_settings.json`` of the last study that identified the
            stiffness (identify or all) in this project, or None before one did.
        plots: Plot name (file stem, e.g. ``identification``) -> PNG bytes.
        finished_s: Unix time the study ended.
        folder: Where the study's CSV and PNG files are, when they are on disk.
    """

    study: str
    quick: bool
    seed: int
    summary: dict[str, Any]
    settings: dict[str, Any] | None
    plots: dict[str, bytes] = field(default_factory=dict)
    finished_s: float = 0.0
    folder: Path | None = None


class StudyService:
    """Runs CMRR and compensation studies on the session's job runner (module docstring).

    Args:
        session: The workbench session: its job runner, store, data folder, open project.
    """

    def __init__(self, session: Session) -> None:
        self.session = session
        self._lock = threading.RLock()
        self._listeners: list[Callable[[StudyKind], None]] = []
        if session.data_dir is not None:
            self.root = (session.data_dir / STUDIES_FOLDER).resolve()
        else:  # no data folder: outputs live in a private temp folder, removed at exit
            self.root = Path(tempfile.mkdtemp(prefix="robomach-studies-")).resolve()
            weakref.finalize(self, shutil.rmtree, str(self.root), True)
        self._project_id = -1
        self._cmrr: CmrrOutcome | None = None
        self._compensation: CompensationOutcome | None = None
        self._load_project()
        self._unsubscribe = session.subscribe(self._on_session_change)

    def close(self) -> None:
        """Stop following the session (the studies' files stay)."""
        self._unsubscribe()

    # --- listeners ---------------------------------------------------------------------------

    def subscribe(self, callback: Callable[[StudyKind], None]) -> Callable[[], None]:
        """Call ``callback(kind)`` when a study of that kind ends (done, failed or cancelled)
        or the open project changes; returns a function that unsubscribes. It runs in the job
        thread or the thread that changed the project: keep it short."""
        with self._lock:
            self._listeners.append(callback)

        def unsubscribe() -> None:
            with self._lock:
                if callback in self._listeners:
                    self._listeners.remove(callback)

        return unsubscribe

    def _notify(self, *kinds: StudyKind) -> None:
        with self._lock:
            listeners = list(self._listeners)
        for kind in kinds:
            for callback in listeners:
                try:
                    callback(kind)
                except Exception:
                    log.exception("study listener failed on %r", kind)

    def _on_session_change(self, topic: str) -> None:
        if topic != "project":
            return
        changed = self._load_project()
        self._forget_deleted_projects()
        if changed:
            self._notify("cmrr", "compensation")

    # --- reading -----------------------------------------------------------------------------

    def cmrr_result(self) -> CmrrOutcome | None:
        """The open project's last CMRR study."""
        self._load_project()
        return self._cmrr

    def compensation_result(self) -> CompensationOutcome | None:
        """The open project's last compensation study."""
        self._load_project()
        return self._compensation

    def require_cmrr(self) -> CmrrOutcome:
        outcome = self.cmrr_result()
        if outcome is None:
            raise ConflictError("no CMRR study in this project yet: run one first")
        return outcome

    def require_compensation(self) -> CompensationOutcome:
        outcome = self.compensation_result()
        if outcome is None:
            raise ConflictError("no compensation study in this project yet: run one first")
        return outcome

    def cmrr_settings_json(self, controller: str | None = None) -> str:
        """The last CMRR study's ``cmrr_settings.json``; with a comparison (``all``), the list,
        or the one of ``controller``."""
        outcome = self.require_cmrr()
        settings: Any = outcome.settings
        if controller is not None:
            if controller not in outcome.controllers:
                raise NotFoundError(
                    f"the last CMRR study did not run {controller!r}; it ran "
                    f"{', '.join(outcome.controllers)}"
                )
            if isinstance(settings, list):
                settings = settings[outcome.controllers.index(controller)]
        return json.dumps(settings, indent=2) + "\n"

    def compensation_settings_json(self) -> str:
        """``compensation_settings.json``: the identified stiffness, tool gravity and mode."""
        outcome = self.require_compensation()
        if outcome.settings is None:
            raise ConflictError(
                "no compensation settings yet: run the identify study (or all), which "
                "identifies the joint stiffness they hold"
            )
        return json.dumps(outcome.settings, indent=2) + "\n"

    def compensation_plot(self, name: str) -> bytes:
        """One PNG of the last compensation study by name (see ``plots``)."""
        outcome = self.require_compensation()
        png = outcome.plots.get(name)
        if png is None:
            names = ", ".join(sorted(outcome.plots)) or "none"
            raise NotFoundError(f"the last compensation study has no plot {name!r}; it has {names}")
        return png

    # --- starting studies --------------------------------------------------------------------

    def start_cmrr(
        self,
        scenario: str,
        controller: str = "default",
        *,
        seed: int = 0,
        reference_force_N: float | None = None,
        command_speed_mm_s: float | None = None,
    ) -> str:
        """Queue a CMRR study; returns the job id.

        Args:
            scenario: One of ``SCENARIO_NAMES``.
            controller: One of ``CONTROLLER_NAMES``, ``"all"`` to compare them, or
                ``"default"`` for the scenario's own (the paper's).
            seed: Seed of the sensor noise.
            reference_force_N: Force reference; None keeps the scenario's.
            command_speed_mm_s: Programmed (greatest) feed; None keeps the scenario's.
        """
        if scenario not in SCENARIO_NAMES:
            raise UnknownScenarioError(
                f"unknown CMRR scenario {scenario!r}; choose one of {', '.join(SCENARIO_NAMES)}"
            )
        if controller not in (*CMRR_CONTROLLER_CHOICES, "default"):
            raise UnknownControllerError(
                f"unknown CMRR controller {controller!r}; choose one of "
                f"{', '.join(CMRR_CONTROLLER_CHOICES)}"
            )
        seed = _seed(seed)
        check_cmrr_numbers(
            reference_force_N=reference_force_N, command_speed_mm_s=command_speed_mm_s
        )
        overrides: dict[str, float] = {}
        if reference_force_N is not None:
            overrides["reference_force_N"] = float(reference_force_N)
        if command_speed_mm_s is not None:
            overrides["command_speed_mm_s"] = float(command_speed_mm_s)
        # Refuse a study too long to simulate before it allocates its arrays (issue 10, 3).
        base = _default_scenario(scenario)
        estimate = replace(
            base,
            reference_force_N=overrides.get("reference_force_N", base.reference_force_N),
            command_speed_m_s=overrides.get("command_speed_mm_s", base.command_speed_m_s * 1e3)
            * 1e-3,
        )
        count = len(CONTROLLER_NAMES) if controller == "all" else 1
        check_study_size(estimate, count)
        self._check_queue()
        project_id = self.session.current_project().id

        def work(ctx: JobContext) -> CmrrOutcome:
            from robomach_core.cmrr import build_scenario, compare_controllers, settings_for
            from robomach_core.cmrr.report import write_study_outputs

            built = build_scenario(scenario, **overrides)
            name = built.default_controller if controller == "default" else controller
            names = list(CONTROLLER_NAMES) if name == "all" else [name]
            check_study_size(built, len(names))
            folder = self._new_run_folder()
            try:
                results = compare_controllers(
                    built,
                    [settings_for(n) for n in names],
                    seed=seed,
                    progress=lambda f: ctx.progress(CMRR_SIMULATION_SHARE * f),
                    cancel=ctx.cancelled,
                )
                ctx.check_cancelled()
                write_study_outputs(results, folder)
                ctx.check_cancelled()
                return CmrrOutcome(
                    scenario=scenario,
                    controller=name,
                    seed=seed,
                    summary=_read_json(folder / CMRR_SUMMARY_FILE),
                    settings=_read_json(folder / CMRR_SETTINGS_FILE),
                    plot_png=(folder / CMRR_PLOT_FILE).read_bytes(),
                    finished_s=time.time(),
                    folder=folder,
                )
            except BaseException:
                shutil.rmtree(folder, ignore_errors=True)
                raise

        def done(outcome: CmrrOutcome) -> None:
            self._keep("cmrr", project_id, outcome)

        return self.session.jobs.submit(
            CMRR_JOB_KIND, _clean_failures("CMRR", work), on_done=done, on_end=self._ended("cmrr")
        )

    def start_compensation(
        self,
        study: str = "all",
        *,
        quick: bool = False,
        seed: int = 0,
        mode: str = StudyOptions.mode,
        offline_model: str | None = None,
    ) -> str:
        """Queue a compensation study; returns the job id.

        Args:
            study: identify, gravity, milling, ilc, compliance (the KR 270 line of the
                compliance paper, always on the KR 270) or all.
            quick: Shorter cuts and fewer poses (a preview in seconds).
            seed: Seed of every random element.
            mode: Compensation written to the settings (``stiffness.modes``: off, offline,
                online; the old spellings offline_linear / offline_nonlinear read as offline
                with that model).
            offline_model: linear or nonlinear (eq. 32); None: the old spelling's, or linear.
        """
        if study not in COMPENSATION_STUDIES:
            raise UnknownStudyError(
                f"unknown compensation study {study!r}; choose one of "
                f"{', '.join(COMPENSATION_STUDIES)}"
            )
        compensation, model = read_compensation(mode, offline_model, name="compensation mode")
        seed = _seed(seed)
        self._check_queue()
        project_id = self.session.current_project().id

        def work(ctx: JobContext) -> CompensationOutcome:
            from robomach_core.stiffness.studies import StudyOptions, run_studies

            folder = self._new_run_folder()
            try:
                # The cell's arm: the identified stiffness is the one its program compensates
                # with (``robomach compensate`` runs each paper's arm instead).
                options = StudyOptions(
                    robot=self.session.robot.cell.robot.name,
                    seed=seed,
                    mode=compensation,
                    offline_model=model,
                    quick=bool(quick),
                )
                results = run_studies(
                    study, folder, options, progress=ctx.progress, cancel=ctx.cancelled
                )
                ctx.check_cancelled()
                plots = {
                    p.stem: p.read_bytes()
                    for r in results.values()
                    for p in r.files
                    if p.suffix == ".png"
                }
                settings_path = folder / COMPENSATION_SETTINGS_FILE
                return CompensationOutcome(
                    study=study,
                    quick=bool(quick),
                    seed=seed,
                    summary=_read_json(folder / COMPENSATION_SUMMARY_FILE),
                    settings=_read_json(settings_path) if settings_path.is_file() else None,
                    plots=plots,
                    finished_s=time.time(),
                    folder=folder,
                )
            except BaseException:
                shutil.rmtree(folder, ignore_errors=True)
                raise

        def done(outcome: CompensationOutcome) -> None:
            self._keep("compensation", project_id, outcome)

        return self.session.jobs.submit(
            COMPENSATION_JOB_KIND,
            _clean_failures("compensation", work),
            on_done=done,
            on_end=self._ended("compensation"),
        )

    def _check_queue(self) -> None:
        """``StudyQueueFullError`` when ``MAX_ACTIVE_STUDIES`` studies are queued or running."""
        active = self.session.jobs.active((CMRR_JOB_KIND, COMPENSATION_JOB_KIND))
        if len(active) >= MAX_ACTIVE_STUDIES:
            raise StudyQueueFullError(
                f"{len(active)} studies are already queued or running (at most "
                f"{MAX_ACTIVE_STUDIES}): wait for one to end or cancel one at /api/jobs"
            )

    def _ended(self, kind: StudyKind) -> Callable[[JobInfo], None]:
        def end(info: JobInfo) -> None:
            self._notify(kind)

        return end

    # --- keeping results: memory, disk, store ------------------------------------------------

    def _keep(
        self, kind: StudyKind, project_id: int, outcome: CmrrOutcome | CompensationOutcome
    ) -> None:
        """Save a finished study to the project it was started in (in the job thread)."""
        store = self.session.store
        with self._lock:
            if store.get_project(project_id) is None:
                if outcome.folder is not None:
                    shutil.rmtree(outcome.folder, ignore_errors=True)
                raise ConflictError(
                    f"project {project_id} was deleted while the study ran; nothing was saved"
                )
            if isinstance(outcome, CompensationOutcome) and outcome.settings is None:
                # Keep the identified model of an earlier study: a milling or ILC run does not
                # identify one, and the settings are what the project exports.
                earlier = self._stored_files(project_id, COMPENSATION_EXPORT)
                text = earlier.get(COMPENSATION_SETTINGS_FILE)
                if text is not None:
                    outcome = replace(outcome, settings=_loads(text))
            folder = self._install_folder(project_id, kind, outcome.folder)
            outcome = replace(outcome, folder=folder)
            export, files = _export_files(outcome)
            store.save_export(project_id, export, files)
            self._write_export_copy(project_id, export, files)
            if project_id == self._project_id:
                if isinstance(outcome, CmrrOutcome):  # kind "cmrr"
                    self._cmrr = outcome
                else:
                    self._compensation = outcome

    def _write_export_copy(self, project_id: int, export: str, files: dict[str, str]) -> None:
        """The saved files also in ``<data>/exports/<project id>/<export>/``, where the
        session's exports list says they are (no copy without a data folder)."""
        if self.session.data_dir is None:
            return
        folder = self.session.data_dir / "exports" / str(int(project_id)) / export
        folder.mkdir(parents=True, exist_ok=True)
        for filename, text in files.items():
            tmp = folder / f".{filename}.tmp"
            tmp.write_text(text, encoding="utf-8")
            os.replace(tmp, folder / filename)

    def _new_run_folder(self) -> Path:
        tmp = self.root / TMP_FOLDER
        tmp.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(dir=tmp, prefix="run-"))

    def _study_folder(self, project_id: int, kind: StudyKind) -> Path:
        """``<root>/<project id>/<kind>``: integers and fixed names only, checked anyway."""
        folder = (self.root / str(int(project_id)) / kind).resolve()
        if not folder.is_relative_to(self.root) or folder == self.root:
            raise InvalidInputError(f"study folder {folder} would leave the data folder")
        return folder

    def _install_folder(self, project_id: int, kind: StudyKind, run: Path | None) -> Path | None:
        """Move a finished run's folder into place, replacing the project's previous one."""
        if run is None:
            return None
        final = self._study_folder(project_id, kind)
        final.parent.mkdir(parents=True, exist_ok=True)
        old = None
        if final.exists():
            old = run.parent / f"old-{uuid.uuid4().hex[:8]}"
            os.replace(final, old)
        os.replace(run, final)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return final

    def _stored_files(self, project_id: int, export: str) -> dict[str, str]:
        """The files of a saved study; a study saved under its old export name (before the
        reserved names) is copied to the new name the first time it is read."""
        store = self.session.store
        files = store.get_export(project_id, export)
        if files is not None:
            return files
        legacy = store.get_export(project_id, LEGACY_EXPORTS.get(export, ""))
        if legacy is None:
            return {}
        kind = "cmrr" if export == CMRR_EXPORT else "compensation"
        try:
            is_study = _loads(legacy[STUDY_META_FILE])["kind"] == kind
        except (KeyError, TypeError, ValueError):
            is_study = False  # an export of the PbD program that took the old name
        if not is_study:
            return {}
        with self._lock:
            if store.get_export(project_id, export) is None:
                store.save_export(project_id, export, legacy)
                log.info("project %d: study moved from export %r to %r", project_id,
                         LEGACY_EXPORTS[export], export)  # fmt: skip
        return legacy

    def _load_project(self) -> bool:
        """Load the open project's saved studies when the project changed; True if it did."""
        try:
            project_id = self.session.current_project().id
        except Exception:  # the store is closed: the server is stopping
            return False
        with self._lock:
            if project_id == self._project_id:
                return False
            self._project_id = project_id
            self._cmrr = self._load_cmrr(project_id)
            self._compensation = self._load_compensation(project_id)
        return True

    def _load_cmrr(self, project_id: int) -> CmrrOutcome | None:
        files = self._stored_files(project_id, CMRR_EXPORT)
        try:
            meta = _loads(files[STUDY_META_FILE])
            folder = self._study_folder(project_id, "cmrr")
            plot = folder / CMRR_PLOT_FILE
            return CmrrOutcome(
                scenario=str(meta["scenario"]),
                controller=str(meta["controller"]),
                seed=int(meta["seed"]),
                summary=_loads(files[CMRR_SUMMARY_FILE]),
                settings=_loads(files[CMRR_SETTINGS_FILE]),
                plot_png=plot.read_bytes() if plot.is_file() else None,
                finished_s=float(meta["finished_s"]),
                folder=folder if folder.is_dir() else None,
            )
        except (KeyError, TypeError, ValueError, OSError):
            if files:
                log.warning("the saved CMRR study of project %d is unreadable", project_id)
            return None

    def _load_compensation(self, project_id: int) -> CompensationOutcome | None:
        files = self._stored_files(project_id, COMPENSATION_EXPORT)
        try:
            meta = _loads(files[STUDY_META_FILE])
            folder = self._study_folder(project_id, "compensation")
            plots = {}
            if folder.is_dir():
                plots = {p.stem: p.read_bytes() for p in sorted(folder.glob("*.png"))}
            settings = files.get(COMPENSATION_SETTINGS_FILE)
            return CompensationOutcome(
                study=str(meta["study"]),
                quick=bool(meta["quick"]),
                seed=int(meta["seed"]),
                summary=_loads(files[COMPENSATION_SUMMARY_FILE]),
                settings=None if settings is None else _loads(settings),
                plots=plots,
                finished_s=float(meta["finished_s"]),
                folder=folder if folder.is_dir() else None,
            )
        except (KeyError, TypeError, ValueError, OSError):
            if files:
                log.warning("the saved compensation study of project %d is unreadable", project_id)
            return None

    def _forget_deleted_projects(self) -> None:
        """Remove the study folders of deleted projects (the store drops their exports)."""
        try:
            alive = {str(p.id) for p in self.session.projects.list_projects()}
            folders = [p for p in self.root.iterdir() if p.is_dir() and p.name.isdigit()]
        except Exception:
            return
        for folder in folders:
            if folder.name not in alive:
                shutil.rmtree(folder, ignore_errors=True)


# --- helpers ---------------------------------------------------------------------------------


def _seed(seed: object) -> int:
    if isinstance(seed, float):  # 3.0 is a float but not a seed a user meant
        raise InvalidInputError(f"seed must be an integer within {SEED.text()}, got {seed!r}")
    return int(SEED.check(seed))


@functools.cache
def _default_scenario(name: str) -> Scenario:
    """The named CMRR scenario without overrides (built once: learned-path takes ~1.5 s)."""
    from robomach_core.cmrr import build_scenario

    return build_scenario(name)


def _clean_failures(label: str, work: Callable[[JobContext], Any]) -> Callable[[JobContext], Any]:
    """``work`` whose unforeseen exceptions end the job as a failure with a one-line message
    (``StudyFailedError``) instead of an internal error: every input passed validation, so a
    failure here is the simulation's, and the user needs to know which, not a traceback."""

    def run(ctx: JobContext) -> Any:
        try:
            return work(ctx)
        except RobomachError:  # cancelled, or a clear user error already
            raise
        except Exception as exc:
            log.warning("%s study failed: %s: %s", label, exc.__class__.__name__, exc)
            log.debug("%s study failure", label, exc_info=True)
            raise StudyFailedError(
                f"the {label} study failed: {exc.__class__.__name__}: {exc}"
            ) from None

    return run


def _jsonable(value: Any) -> Any:
    """Plain JSON: NaN and infinities become None (strict JSON has neither)."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_jsonable(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _loads(text: str) -> Any:
    return _jsonable(json.loads(text))


def _read_json(path: Path) -> Any:
    return _loads(path.read_text(encoding="utf-8"))


def _export_files(outcome: CmrrOutcome | CompensationOutcome) -> tuple[str, dict[str, str]]:
    """The export name and files (name -> text) a study is saved to the project as."""

    def dump(doc: Any) -> str:
        return json.dumps(doc, indent=2) + "\n"

    if isinstance(outcome, CmrrOutcome):
        meta = {
            "kind": "cmrr",
            "scenario": outcome.scenario,
            "controller": outcome.controller,
            "seed": outcome.seed,
            "finished_s": outcome.finished_s,
        }
        return CMRR_EXPORT, {
            STUDY_META_FILE: dump(meta),
            CMRR_SUMMARY_FILE: dump(outcome.summary),
            CMRR_SETTINGS_FILE: dump(outcome.settings),
        }
    meta = {
        "kind": "compensation",
        "study": outcome.study,
        "quick": outcome.quick,
        "seed": outcome.seed,
        "finished_s": outcome.finished_s,
        "plots": sorted(outcome.plots),
    }
    files = {STUDY_META_FILE: dump(meta), COMPENSATION_SUMMARY_FILE: dump(outcome.summary)}
    if outcome.settings is not None:
        files[COMPENSATION_SETTINGS_FILE] = dump(outcome.settings)
    return COMPENSATION_EXPORT, files
