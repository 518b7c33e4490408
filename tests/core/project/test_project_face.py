"""``robomach_core.project``'s face: it exports what the CLI and the app use, nothing more, and
no user reaches past it into the package's private modules (issue 30).

The users are the app (workbench, REST API, pendant and the CLI's commands, ``app/``) and the
core's composition of ``robomach demo`` (``robomach_core/pipeline.py``). A name reaches them
as ``from robomach_core.project import name`` (or ``from .project import name``) or as an
attribute of the package imported under an alias (``from robomach_core import project as
core``; ``core.name``).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
PACKAGE = "robomach_core.project"
USERS = (ROOT / "app", ROOT / "robomach_core" / "pipeline.py")
# Exported though no user names it: the error the exported file loaders raise
# (``load_project_file``, ``project_from_file_bytes``); a caller must be able to catch it by
# name (the app lets it through as a 422, the CLI as exit code 2).
RAISED_BY_THE_FACE = {"ProjectFileError"}


def _files(*roots: Path) -> list[Path]:
    out: list[Path] = []
    for root in roots:
        out += [root] if root.is_file() else sorted(root.rglob("*.py"))
    return out


def _module_of(node: ast.ImportFrom, path: Path) -> str:
    """The absolute module an import names (relative imports resolved from ``path``)."""
    if not node.level:
        return node.module or ""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)[: -node.level]
    return ".".join(parts + ([node.module] if node.module else []))


def _uses(path: Path) -> tuple[set[str], set[str]]:
    """(names of the face this file uses, private modules of the package it imports)."""
    tree = ast.parse(path.read_text())
    names: set[str] = set()
    private: set[str] = set()
    aliases: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            module = _module_of(node, path)
            if module == PACKAGE:
                names |= {a.name for a in node.names}
            elif module.startswith(PACKAGE + "._"):
                private.add(module)
            elif module == PACKAGE.rpartition(".")[0]:
                aliases |= {a.asname or a.name for a in node.names if a.name == "project"}
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith(PACKAGE + "._"):
                    private.add(a.name)
                elif a.name == PACKAGE and a.asname:
                    aliases.add(a.asname)
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id in aliases
        ):
            names.add(node.attr)
    return names, private


def _exported() -> set[str]:
    init = ROOT / "robomach_core" / "project" / "__init__.py"
    return {
        a.asname or a.name
        for node in ast.parse(init.read_text()).body
        if isinstance(node, ast.ImportFrom)
        for a in node.names
    }


def _used() -> dict[str, list[str]]:
    used: dict[str, list[str]] = {}
    for path in _files(*USERS):
        for name in _uses(path)[0]:
            used.setdefault(name, []).append(str(path.relative_to(ROOT)))
    return used


def test_the_face_exports_every_name_the_cli_and_the_app_use():
    missing = {name: where for name, where in _used().items() if name not in _exported()}
    assert not missing, f"used but not exported by {PACKAGE}: {missing}"


def test_the_face_exports_nothing_the_cli_and_the_app_do_not_use():
    unused = _exported() - set(_used()) - RAISED_BY_THE_FACE
    assert not unused, f"exported by {PACKAGE} but used by neither the CLI nor the app: {unused}"


def test_no_module_outside_the_package_imports_its_private_modules():
    """The app and the rest of the core go through the face (tests may reach a private helper
    they test on its own)."""
    core = ROOT / "robomach_core"
    offenders = {
        str(path.relative_to(ROOT)): sorted(private)
        for path in _files(ROOT / "app", core)
        if not path.is_relative_to(core / "project")
        for private in [_uses(path)[1]]
        if private
    }
    assert not offenders, offenders
