"""The Session is a thin shell: small, and nothing outside its module reaches into it.

The AST of every module of the app (and of the tests, which use it as people do) is walked for
attribute accesses ``x._name`` where ``_name`` is one of the Session's own private attributes
or methods and ``x`` is not ``self`` of the class that defines it: the teaching, pointing,
learning, projects and machining modules work through its public interface
(``view``, ``commit``, ``change_cell``, ``robot``, ``notify``...).
"""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

from app.session import Session
from app.session.robot import LiveRobot

ROOT = Path(__file__).resolve().parents[2]
SESSION_FILE = ROOT / "app" / "session" / "session.py"
ROBOT_FILE = ROOT / "app" / "session" / "robot.py"
MAX_SESSION_LINES = 400


def _private_names(path: Path, class_name: str) -> set[str]:
    """``_x`` attributes a class sets on ``self`` and ``_x`` methods it defines."""
    tree = ast.parse(path.read_text())
    (cls,) = [n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == class_name]
    names = {
        n.name
        for n in cls.body
        if isinstance(n, ast.FunctionDef) and n.name.startswith("_") and not n.name.endswith("__")
    }
    for node in ast.walk(cls):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id == "self"
            and node.attr.startswith("_")
            and not node.attr.endswith("__")
        ):
            names.add(node.attr)
    return names


def _reaches(path: Path, private: set[str]) -> list[str]:
    """``file:line x._name`` for each access to one of ``private`` not through bare ``self``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not (isinstance(node, ast.Attribute) and node.attr in private):
            continue
        if isinstance(node.value, ast.Name) and node.value.id == "self":
            continue  # the module's own object's attribute of the same name
        found.append(f"{path.relative_to(ROOT)}:{node.lineno} {ast.unparse(node)}")
    return found


def _modules(*, besides: Path) -> list[Path]:
    paths = [p for d in ("app", "tests", "benchmarks") for p in (ROOT / d).rglob("*.py")]
    return sorted(p for p in paths if p != besides)


def test_the_session_knows_its_own_private_names() -> None:
    private = _private_names(SESSION_FILE, "Session")
    # the walk finds the state (so an empty set cannot make the next test pass by itself)
    assert {"_lock", "_project", "_project_id", "_save"} <= private, private


def test_no_module_outside_the_session_touches_its_private_attributes() -> None:
    private = _private_names(SESSION_FILE, "Session")
    found = [hit for p in _modules(besides=SESSION_FILE) for hit in _reaches(p, private)]
    assert not found, "reaches into the Session:\n" + "\n".join(found)


def test_no_module_outside_the_robot_touches_the_live_robots_private_attributes() -> None:
    private = _private_names(ROBOT_FILE, "LiveRobot") - {"_lock"}  # others have their own
    found = [hit for p in _modules(besides=ROBOT_FILE) for hit in _reaches(p, private)]
    assert not found, "reaches into the LiveRobot:\n" + "\n".join(found)
    assert LiveRobot.__module__ == "app.session.robot"


def test_the_session_with_what_it_inherits_is_under_400_lines() -> None:
    lines = {
        cls.__qualname__: len(inspect.getsource(cls).splitlines())
        for cls in Session.__mro__
        if cls is not object
    }
    assert sum(lines.values()) < MAX_SESSION_LINES, lines
    # and the module around it, docstring and records included
    assert len(SESSION_FILE.read_text().splitlines()) < MAX_SESSION_LINES


def test_only_the_session_and_the_parts_built_with_it_take_its_lock() -> None:
    """No public lock: what must happen under the session's lock is a method of the Session or
    of a part it builds with the lock (``LiveRobot``, ``Projects``); no other module names the
    lock of a robot or a session (``robot.lock``, ``session._lock``, ``s.robot._lock`` ...)."""
    owners = {SESSION_FILE, ROBOT_FILE, ROOT / "app" / "session" / "projects.py"}
    holders = {"robot", "session", "_session", "s", "projects"}
    found = []
    for path in _modules(besides=SESSION_FILE):
        if path in owners:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if not (isinstance(node, ast.Attribute) and node.attr in ("lock", "_lock")):
                continue
            inner = node.value
            name = inner.attr if isinstance(inner, ast.Attribute) else getattr(inner, "id", "")
            if name in holders:
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {ast.unparse(node)}")
    assert not found, "takes the session's lock from outside:\n" + "\n".join(found)
    session = Session(real_time=False)
    try:
        public = {n for n in (*vars(session), *vars(session.robot)) if "lock" in n.lower()}
        assert not {n for n in public if not n.startswith("_")}, public
    finally:
        session.close()
