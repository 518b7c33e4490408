"""Study runners: identification, gravity compensation, milling compensation, ILC and the
compliance paper's KR 270 line, each on its paper's arm by default (``PAPER_ARMS``).

Each runner is a plain function a CLI, a GUI panel or a REST job can call: options in, a
``StudyResult`` out (summary dict in boundary units, named arrays, paths of the CSVs and PNGs it
wrote when given a folder). ``progress(fraction)`` is called as the work advances and
``cancel()`` is polled; True stops the study with ``CancelledError``.

The simulator's true joint stiffness is used only to bend the simulated arm and to score the
identified model; every controller in here uses the identified model, but for the compliance
study's replay of the paper's compensation with the paper's own stiffness model (Table 1),
shown beside the identified one.
"""

from ._common import PAPER_ARMS as PAPER_ARMS
from ._common import PAPER_REFERENCES as PAPER_REFERENCES
from ._common import RAPID_FILE as RAPID_FILE
from ._common import SETTINGS_FILE as SETTINGS_FILE
from ._common import STUDIES as STUDIES
from ._common import SUMMARY_FILE as SUMMARY_FILE
from ._common import StudyName as StudyName
from ._common import StudyOptions as StudyOptions
from ._common import StudyResult as StudyResult
from ._common import study_robot as study_robot
from ._common import work_position_m as work_position_m
from ._compliance import run_compliance_study as run_compliance_study
from ._gravity import run_gravity_study as run_gravity_study
from ._identify import run_identification_study as run_identification_study
from ._ilc import run_ilc_study as run_ilc_study
from ._milling import run_milling_study as run_milling_study
from ._runner import run_studies as run_studies
