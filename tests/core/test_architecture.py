"""robomach_core is a pure library: it never imports the app's web or GUI stack."""

from __future__ import annotations

import ast
from pathlib import Path

FORBIDDEN = {"fastapi", "uvicorn", "viser", "starlette", "app"}


def test_core_never_imports_fastapi_uvicorn_or_viser():
    core = Path(__file__).resolve().parents[2] / "robomach_core"
    offenders = []
    for path in core.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            offenders += [f"{path.name}: {n}" for n in names if n.split(".")[0] in FORBIDDEN]
    assert not offenders
