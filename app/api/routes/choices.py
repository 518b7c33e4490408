"""Every named choice and number range of the core, for the pendant page (``GET /api/choices``).

The pendant's menus and number inputs take their values and bounds from here, so they never
drift from what the server accepts (``robomach_core.choices``, ``robomach_core.limits``).
"""

from __future__ import annotations

from functools import cache
from typing import Any

from fastapi import APIRouter

from robomach_core.choices import catalogue

router = APIRouter(prefix="/api", tags=["state"])


@cache
def _catalogue() -> dict[str, Any]:
    return catalogue()


@router.get("/choices")
async def get_choices() -> dict[str, Any]:
    """``enums``: name -> ``{"values": [...], "labels": {value: words}}`` (controller names,
    compensation modes, program languages, wall sides, jog frames, ...); ``ranges``: the name
    of each ``limits`` range -> ``{"label", "min", "max", "unit", "integer", "text"}``."""
    return _catalogue()
