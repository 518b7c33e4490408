"""The code's shape stays one a newcomer can read (issue 30): no function of the core longer
than 120 lines, no module of the core or the app longer than 800. A change that grows one past
its bound splits it here, not in a later round of clean-up."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FUNCTION_LINES = 120
MODULE_LINES = 800


def _modules(*packages: str) -> list[Path]:
    return sorted(p for package in packages for p in (ROOT / package).rglob("*.py"))


def test_no_core_function_is_longer_than_120_lines():
    long = []
    for path in _modules("robomach_core"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > FUNCTION_LINES:
                    long.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({lines})")
    assert not long, f"functions over {FUNCTION_LINES} lines: {long}"


def test_no_module_is_longer_than_800_lines():
    long = [
        f"{path.relative_to(ROOT)} ({n})"
        for path in _modules("robomach_core", "app")
        if (n := len(path.read_text().splitlines())) > MODULE_LINES
    ]
    assert not long, f"modules over {MODULE_LINES} lines: {long}"
