"""JSON forms of the machining setup and result, as the project file and the store keep them."""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

import numpy as np

from ..postprocess import Targets
from ._machining import MachiningResult, MachiningSetup


def machining_setup_document(setup: MachiningSetup) -> dict[str, Any]:
    """JSON form of the setup (the stock mesh by file name only)."""
    from ..machining import settings_to_dict

    return {
        "settings": settings_to_dict(setup.settings),
        "stock_source": setup.stock_source,
        "stock_profile_mm": None
        if setup.stock_profile_mm is None
        else [list(p) for p in setup.stock_profile_mm],
        "stock_mesh": None if setup.stock_mesh is None else setup.stock_mesh[0],
        "cell_options": None if setup.cell_options is None else list(setup.cell_options),
        "variations": setup.variations,
        "campaign_stiffness_Nm_rad": None
        if setup.campaign_stiffness_Nm_rad is None
        else list(setup.campaign_stiffness_Nm_rad),
    }


def machining_setup_from_document(doc: dict[str, Any], mesh: tuple[str, bytes] | None = None):
    """The setup from ``machining_setup_document`` (controller settings back to the defaults)."""
    from ..machining import MachiningSettings

    values = dict(doc.get("settings") or {})
    values.pop("controller_settings", None)
    known = set(MachiningSettings.__dataclass_fields__)
    settings = MachiningSettings(**{k: v for k, v in values.items() if k in known})
    profile = doc.get("stock_profile_mm")
    source = doc.get("stock_source", "builtin")
    if source == "mesh" and mesh is None:
        source = "builtin"
    options = doc.get("cell_options")
    return MachiningSetup(
        settings,
        source,
        None if profile is None else tuple((float(a), float(b)) for a, b in profile),
        mesh if source == "mesh" else None,
        cell_options=None if options is None else tuple(str(o) for o in options),
        variations=int(doc.get("variations") or 0),
        campaign_stiffness_Nm_rad=None
        if doc.get("campaign_stiffness_Nm_rad") is None
        else tuple(float(k) for k in doc["campaign_stiffness_Nm_rad"]),
    )


def machining_result_document(result: MachiningResult) -> dict[str, Any]:
    """JSON form of a result: rows, table, choice, inputs and the offline programs."""
    return {
        "rows": list(result.rows),
        "table_text": result.table_text,
        "chosen": result.chosen,
        "inputs": result.inputs,
        "programs": {k: _targets_doc(t) for k, t in result.programs.items()},
        "reason": result.reason,
        "capabilities": list(result.capabilities),
        "variation": result.variation,
    }


def machining_result_from_document(doc: dict[str, Any]) -> MachiningResult:
    chosen = doc.get("chosen")
    return MachiningResult(
        rows=tuple(doc["rows"]),
        table_text=str(doc["table_text"]),
        chosen=None if chosen is None else int(chosen),
        programs={k: _targets_from(v) for k, v in (doc.get("programs") or {}).items()},
        inputs=str(doc["inputs"]),
        reason=str(doc.get("reason") or ""),
        capabilities=tuple(doc.get("capabilities") or ()),
        variation=doc.get("variation"),
    )


def _targets_doc(t: Targets) -> dict[str, Any]:
    return {k: np.asarray(v).tolist() for k, v in asdict(t).items()}


def _targets_from(doc: dict[str, Any]) -> Targets:
    return Targets(
        position_m=np.asarray(doc["position_m"], dtype=float),
        quaternion_wxyz=np.asarray(doc["quaternion_wxyz"], dtype=float),
        joints_rad=np.asarray(doc["joints_rad"], dtype=float),
        speed_m_s=np.asarray(doc["speed_m_s"], dtype=float),
        curvature_1_m=np.asarray(doc["curvature_1_m"], dtype=float),
        sample_index=np.asarray(doc["sample_index"], dtype=int),
    )
