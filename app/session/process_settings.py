"""The CMRR and compensation settings a project's program carries, taken from its studies.

A CMRR study (``app.studies``) ends with ``cmrr_settings.json`` (one controller, or a list when
it compared them all); an identification study ends with ``compensation_settings.json``. The
project adopts them on request, so its RAPID export gets the FC SpeedChange block and the
compensated targets (``robomach_core.project._writers.rapid_text``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .records import ConflictError, NotFoundError

if TYPE_CHECKING:
    from robomach_core.cmrr import CmrrSettings
    from robomach_core.stiffness import CompensationSettings

    from ..studies import StudyService


def settings_from_studies(
    studies: StudyService,
    *,
    controller: str | None = None,
    cmrr: bool = True,
    compensation: bool = True,
) -> tuple[CmrrSettings | None, CompensationSettings | None]:
    """(CmrrSettings | None, CompensationSettings | None) of the open project's last studies.

    Args:
        studies: The session's ``app.studies.StudyService``.
        controller: The controller to take from a study that compared several; None takes a
            single-controller study's own.
        cmrr: Take the CMRR settings (else None).
        compensation: Take the compensation settings (else None).

    Raises:
        ConflictError: A wanted study has not run, or several controllers and none chosen.
        NotFoundError: ``controller`` was not run by the last study.
    """
    cmrr_settings: CmrrSettings | None = None
    compensation_settings: CompensationSettings | None = None
    if cmrr:
        from robomach_core.cmrr import settings_from_dict as cmrr_from_dict

        study = studies.require_cmrr()
        chosen: Any = study.settings
        if isinstance(chosen, list):
            if controller is None:
                raise ConflictError(
                    "the last CMRR study compared controllers; choose one of "
                    f"{', '.join(study.controllers)}"
                )
            if controller not in study.controllers:
                raise NotFoundError(
                    f"the last CMRR study did not run {controller!r}; it ran "
                    f"{', '.join(study.controllers)}"
                )
            chosen = chosen[study.controllers.index(controller)]
        elif controller is not None and controller != chosen.get("controller"):
            raise NotFoundError(
                f"the last CMRR study ran {chosen.get('controller')!r}, not {controller!r}"
            )
        cmrr_settings = cmrr_from_dict(chosen)
    if compensation:
        from robomach_core.stiffness.settings import settings_from_dict as compensation_from_dict

        identified = studies.require_compensation()
        if identified.settings is None:
            raise ConflictError(
                "no compensation settings yet: run the identify study (or all), which "
                "identifies the joint stiffness they hold"
            )
        compensation_settings = compensation_from_dict(identified.settings)
    return cmrr_settings, compensation_settings
