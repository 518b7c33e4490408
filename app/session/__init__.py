"""The workbench session (see ``session.py`` for its public API): state shared by the viser GUI
and the REST API, its background jobs, and the records it hands out."""

from .exports import rapid_identifier_or as rapid_identifier_or
from .jobs import JobContext as JobContext
from .jobs import JobRunner as JobRunner
from .records import DEFAULT_PROJECT_NAME as DEFAULT_PROJECT_NAME
from .records import EXPORT_NAME_RE as EXPORT_NAME_RE
from .records import LIVE_NOTIFY_S as LIVE_NOTIFY_S
from .records import LIVE_TRACE_EVERY as LIVE_TRACE_EVERY
from .records import LIVE_TRACE_MAX as LIVE_TRACE_MAX
from .records import MAX_GUIDE_POINTS as MAX_GUIDE_POINTS
from .records import PROJECT_NAME_MAX as PROJECT_NAME_MAX
from .records import RECORDING_ARRAYS as RECORDING_ARRAYS
from .records import BusyError as BusyError
from .records import CellSettings as CellSettings
from .records import ConflictError as ConflictError
from .records import ExportInfo as ExportInfo
from .records import ForceTrace as ForceTrace
from .records import GuidePointEntry as GuidePointEntry
from .records import JobInfo as JobInfo
from .records import JobStatus as JobStatus
from .records import NotFoundError as NotFoundError
from .records import PostprocessOutcome as PostprocessOutcome
from .records import ProjectInfo as ProjectInfo
from .records import QueueFullError as QueueFullError
from .records import RobotSnapshot as RobotSnapshot
from .records import Topic as Topic
from .session import ROBOT_JOB_KINDS as ROBOT_JOB_KINDS
from .session import Session as Session
