"""The one compensation vocabulary: what every layer calls deflection compensation (issue 30).

PROBLEM   Compensation had three vocabularies: the machining run's ``off / offline / online``,
          the settings file's ``off / online / offline_linear / offline_nonlinear`` (a second
          question, which offline model, folded into the first) and the milling study's
          ``none``; the project mapped one to the other both ways, and a nonlinear model chosen
          in a study became linear when the machining choice was saved again.
STRATEGY  One answer to one question each. ``Compensation`` is WHEN the program is corrected
          for the arm's deflection: ``off`` (targets as learned), ``offline`` (targets moved
          before the run, x_c = x - C F) or ``online`` (the controller moves the joint reference
          from the measured force, chapter fig. 15). ``OfflineModel`` is HOW an offline
          correction is computed: ``linear`` (t_F = t_0 - C(q_0) W) or ``nonlinear`` (the
          compliance paper's iteration, eq. 32); it matters only with ``offline``.
SOLUTION  The machining settings, the compensation settings (file, project, REST), the CLI, the
          pendant and both GUIs take these two, from here (``robomach_core.choices`` names
          them). ``read_compensation`` is the one rule for the old spellings: ``offline_linear``
          and ``offline_nonlinear`` (version-1 settings files and projects, older API clients
          and scripts) are ``offline`` with that model, ``none`` is ``off``; anything else is
          refused with the choices named. ``variant_name`` writes a pair as one word where
          output needs one (the milling study's file names and summary keys).
"""

from __future__ import annotations

from typing import Literal, get_args

from ..errors import InvalidInputError
from .model import ModelKind

Compensation = Literal["off", "offline", "online"]
COMPENSATIONS: tuple[Compensation, ...] = get_args(Compensation)
# The offline correction takes the joint-stiffness model's kind (``model.ModelKind``).
OfflineModel = ModelKind
OFFLINE_MODELS: tuple[OfflineModel, ...] = get_args(OfflineModel)
DEFAULT_OFFLINE_MODEL: OfflineModel = "linear"

# Old spellings -> (compensation, offline model or None when the spelling names none).
_OLD_SPELLINGS: dict[str, tuple[Compensation, OfflineModel | None]] = {
    f"offline_{model}": ("offline", model) for model in OFFLINE_MODELS
}
_OLD_SPELLINGS["none"] = ("off", None)


def variant_name(compensation: Compensation, model: OfflineModel = DEFAULT_OFFLINE_MODEL) -> str:
    """One word for a compensation and its model: ``off``, ``online``, ``offline_linear``,
    ``offline_nonlinear`` (output names; ``read_compensation`` reads them back)."""
    return f"offline_{model}" if compensation == "offline" else compensation


def read_compensation(
    value: object,
    offline_model: object = None,
    *,
    name: str = "compensation",
    error: type[InvalidInputError] = InvalidInputError,
) -> tuple[Compensation, OfflineModel]:
    """The compensation ``value`` names and its offline model (``offline_model``, else the one
    an old spelling carries, else ``DEFAULT_OFFLINE_MODEL``).

    Raises:
        error: ``value`` is none of ``COMPENSATIONS`` nor an old spelling, ``offline_model``
            none of ``OFFLINE_MODELS``, or an old spelling's model contradicts
            ``offline_model``; the message names the choices.
    """
    if offline_model is not None and offline_model not in OFFLINE_MODELS:
        raise error(
            f"unknown offline model {offline_model!r}; choose one of {', '.join(OFFLINE_MODELS)}"
        )
    given: OfflineModel | None = offline_model
    if value in COMPENSATIONS:
        return value, given or DEFAULT_OFFLINE_MODEL
    if isinstance(value, str) and value in _OLD_SPELLINGS:
        compensation, model = _OLD_SPELLINGS[value]
        if model is not None and given is not None and given != model:
            raise error(
                f"{name} {value!r} means offline with the {model} model, but the offline "
                f"model given is {given!r}: give {name} 'offline' and one model"
            )
        return compensation, model or given or DEFAULT_OFFLINE_MODEL
    raise error(
        f"unknown {name} {value!r}; choose one of {', '.join(COMPENSATIONS)} (an offline "
        f"correction's model: {' or '.join(OFFLINE_MODELS)})"
    )
