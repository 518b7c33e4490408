"""One job as one value, and the stages that turn it into a program (chapter section 3).

PROBLEM   The CLI (``robomach demo``) and the workbench (viser, REST, pendant) both run cell ->
          guide points -> path learning -> post-processing -> RAPID. Composed twice, the copies
          drift (two settings.json writers, two RAPID headers, two scoring paths), and when an
          upstream input changes, a result computed from the old one can be shown as if current.
STRATEGY  ``Project`` is a frozen value holding the inputs of every stage and the result of each
          (``LearnedPath``, ``ProcessedPath``, a machining slot). Each stage is a pure function
          of the previous stage's output and its own settings (``learn``, ``process``,
          ``program_files``). Each result carries a fingerprint of the inputs it was computed
          from; ``Project.status()`` compares them with the project's current inputs, so a
          result is ``"current"``, ``"stale"`` (kept, flagged) or ``"none"``.
SOLUTION  Callers replace the value (``dataclasses.replace``) and never mark anything by hand:
          changing the guide points or the cell makes the recording, the post-processing and the
          machining results stale by construction. Writers refuse stale results
          (``StaleResultError``, a 409 in the API): a program is never exported from a path that
          no longer matches the project's guide points or cell. ``settings.json`` carries the
          status, so a saved document says what it was made from.
"""

from ._file import PROJECT_FILE as PROJECT_FILE
from ._file import load_project_file as load_project_file
from ._file import project_file_bytes as project_file_bytes
from ._file import project_from_file_bytes as project_from_file_bytes
from ._file import recording_document as recording_document
from ._file import recording_from_document as recording_from_document
from ._file import save_project_file as save_project_file
from ._file_check import RECORDING_FIELDS as RECORDING_FIELDS
from ._file_check import ProjectFileError as ProjectFileError
from ._machining import STOCK_SOURCES as STOCK_SOURCES
from ._machining import MachiningResult as MachiningResult
from ._machining import MachiningSetup as MachiningSetup
from ._machining import capabilities_of as capabilities_of
from ._machining import choose as choose
from ._machining import machining_setup_of as machining_setup_of
from ._machining import stale_settings as stale_settings
from ._machining import with_machining_result as with_machining_result
from ._machining import with_machining_setup as with_machining_setup
from ._machining import with_runnable_choice as with_runnable_choice
from ._machining_cut import machine as machine
from ._machining_documents import machining_result_document as machining_result_document
from ._machining_documents import (
    machining_result_from_document as machining_result_from_document,
)
from ._machining_documents import machining_setup_document as machining_setup_document
from ._machining_documents import (
    machining_setup_from_document as machining_setup_from_document,
)
from ._machining_program import machining_note as machining_note
from ._stages import build_cell as build_cell
from ._stages import build_workpiece as build_workpiece
from ._stages import guide_check as guide_check
from ._stages import guide_findings as guide_findings
from ._stages import learn as learn
from ._stages import process as process
from ._stages import require_processed as require_processed
from ._stages import route_of as route_of
from ._stages import wobj_transform as wobj_transform
from ._transitions import KEEP as KEEP
from ._transitions import mesh_file_name as mesh_file_name
from ._transitions import post_settings_with as post_settings_with
from ._transitions import with_cell as with_cell
from ._transitions import with_guide_point_added as with_guide_point_added
from ._transitions import with_guide_point_at as with_guide_point_at
from ._transitions import with_guide_points as with_guide_points
from ._transitions import with_learned as with_learned
from ._transitions import with_process_settings as with_process_settings
from ._transitions import with_processed as with_processed
from ._transitions import with_registration as with_registration
from ._transitions import with_robot_file as with_robot_file
from ._transitions import with_uploaded_mesh as with_uploaded_mesh
from ._transitions import without_guide_point as without_guide_point
from ._value import DEFAULT_MODULE_NAME as DEFAULT_MODULE_NAME
from ._value import CellSettings as CellSettings
from ._value import LearnedPath as LearnedPath
from ._value import MissingResultError as MissingResultError
from ._value import ProcessedPath as ProcessedPath
from ._value import Project as Project
from ._value import StageStatus as StageStatus
from ._value import StaleResultError as StaleResultError
from ._value import cmrr_document as cmrr_document
from ._value import compensation_document as compensation_document
from ._value import machining_inputs_key as machining_inputs_key
from ._value import processed_inputs_key as processed_inputs_key
from ._value import recording_inputs_key as recording_inputs_key
from ._writers import cad_only_program_texts as cad_only_program_texts
from ._writers import program_export as program_export
from ._writers import program_files as program_files
from ._writers import program_languages as program_languages
from ._writers import program_texts as program_texts
from ._writers import result_extras as result_extras
from ._writers import settings_document as settings_document
from ._writers import targets_text as targets_text
