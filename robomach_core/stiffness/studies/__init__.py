"""Study runners: identification, gravity compensation, milling compensation and ILC.

Each runner is a plain function a CLI, a GUI panel or a REST job can call: options in, a
``StudyResult`` out (summary dict in boundary units, named arrays, paths of the CSVs and PNGs it
wrote when given a folder). ``progress(fraction)`` is called as the work advances and
``cancel()`` is polled; True stops the study with ``CancelledError``.

The simulator's true joint stiffness is used only to bend the simulated arm and to score the
identified model; every controller in here uses the identified model.
"""

from ._common import PAPER_REFERENCES as PAPER_REFERENCES
from ._common import RAPID_FILE as RAPID_FILE
from ._common import SETTINGS_FILE as SETTINGS_FILE
from ._common import STUDIES as STUDIES
from ._common import SUMMARY_FILE as SUMMARY_FILE
from ._common import StudyName as StudyName
from ._common import StudyOptions as StudyOptions
from ._common import StudyResult as StudyResult
from ._gravity import run_gravity_study as run_gravity_study
from ._identify import run_identification_study as run_identification_study
from ._ilc import run_ilc_study as run_ilc_study
from ._milling import run_milling_study as run_milling_study
from ._runner import run_studies as run_studies
