"""Every enum and range is defined once in the core and derived everywhere else (issue 17,
item 2): this contract fails when a boundary types a copy.

- No module of the app (CLI commands, REST schemas and routes, viser panels, the session) holds
  a literal list, tuple, set or ``Literal[...]`` of an enum's values (the controller names, the
  three compensation vocabularies, the program languages, the wall sides, ...).
- No script or page of the pendant (``static/``) holds an array or a ``<select>`` of them, and
  no number input carries its own ``min``/``max``: it names a ``limits`` range
  (``data-range``) that ``GET /api/choices`` serves.
- No viser slider is bounded by numbers typed in the panel.
- ``GET /api/choices`` serves ``robomach_core.choices.catalogue()``.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from robomach_core import choices, limits

ROOT = Path(__file__).resolve().parents[2]
# The enums whose copies drifted or could (values specific enough to be recognised).
WATCHED = (
    "cmrr_controller",
    "machining_compensation",
    "compensation_mode",
    "program_language",
    "wall_side",
    "arm_family",
    "jog_frame",
    "compliance_frame",
    "click_mode",
    "nearest_face",
    "cell_option",
    "stock_source",
    "cmrr_scenario",
    "compensation_study",
)
# Sliders of the display, not of a physical input (the colour scale of the deviation map).
DISPLAY_SLIDERS = {"Colour scale (mm)"}


def _watched() -> dict[str, set[str]]:
    enums = choices.enums()
    return {name: set(enums[name]) for name in WATCHED}


def _copy_of(values: set[str], enum: set[str]) -> bool:
    """A literal collection holds a copy when it has at least 3 of the enum's values (all of
    them for a smaller enum)."""
    return len(values & enum) >= min(3, len(enum))


def _strings(node: ast.AST) -> set[str] | None:
    """The strings of a literal tuple, list, set or ``Literal[...]``; None for other nodes."""
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        elements = node.elts
    elif isinstance(node, ast.Subscript) and ast.unparse(node.value).endswith("Literal"):
        inner = node.slice
        elements = inner.elts if isinstance(inner, ast.Tuple) else [inner]
    else:
        return None
    return {e.value for e in elements if isinstance(e, ast.Constant) and isinstance(e.value, str)}


def _python_copies(path: Path, definitions: dict[str, set[str]] | None = None) -> list[str]:
    """Literal collections in ``path`` holding a watched enum's values. With ``definitions``,
    a module-level name bound to exactly an enum's values (``X = Literal[...]``, ``X = (...)``)
    is that enum's definition, recorded there, not a copy."""
    tree = ast.parse(path.read_text())
    bound = set()
    for stmt in tree.body:
        if isinstance(stmt, (ast.Assign, ast.AnnAssign)) and stmt.value is not None:
            bound |= {id(stmt.value), id(getattr(stmt.value, "slice", None))}
    enums, found = _watched(), []
    for node in ast.walk(tree):
        strings = _strings(node)
        if strings is None:
            continue
        where = f"{path.relative_to(ROOT)}:{node.lineno}"
        if definitions is not None and id(node) in bound and strings in enums.values():
            for name, enum in enums.items():
                if strings == enum:
                    definitions[name].add(where)
            continue  # an enum's definition (maybe sharing values with another's)
        for name, enum in enums.items():
            if _copy_of(strings, enum):
                found.append(f"{where} {name}: {ast.unparse(node)[:80]}")
    return found


def test_the_app_types_no_copy_of_an_enum() -> None:
    found = [hit for p in sorted((ROOT / "app").rglob("*.py")) for hit in _python_copies(p)]
    assert not found, "enum values typed outside the core:\n" + "\n".join(found)


# Data, not a copy: the arm families that have an online path correction (all three today).
CORE_DATA = {("robomach_core/machining/choice.py", "arm_family")}


def test_the_core_defines_each_enum_once_and_types_no_copy() -> None:
    definitions: dict[str, set[str]] = {name: set() for name in WATCHED}
    found = [
        hit
        for p in sorted((ROOT / "robomach_core").rglob("*.py"))
        for hit in _python_copies(p, definitions)
        if (hit.split(":")[0], hit.split(" ")[1].rstrip(":")) not in CORE_DATA
    ]
    assert not found, "enum values typed again in the core:\n" + "\n".join(found)
    twice = {name: sorted(where) for name, where in definitions.items() if len(where) > 1}
    assert not twice, f"enums defined twice: {twice}"


def _static_texts() -> dict[Path, str]:
    return {
        p: p.read_text()
        for p in sorted((ROOT / "static").glob("*"))
        if p.suffix in (".js", ".html")
    }


def test_the_pendant_types_no_copy_of_an_enum() -> None:
    found = []
    for path, text in _static_texts().items():
        groups = re.findall(r"\[[^\[\]]*\]", text)  # array literals
        groups += re.findall(r"<select[^>]*>.*?</select>", text, flags=re.S)
        for group in groups:
            strings = set(re.findall(r"[\"'`]([A-Za-z0-9_-]+)[\"'`]", group))
            strings |= set(re.findall(r'value="([^"]+)"', group))
            for name, enum in _watched().items():
                if _copy_of(strings, enum):
                    found.append(f"{path.name} {name}: {group[:80]!r}")
    assert not found, "enum values typed in the pendant:\n" + "\n".join(found)


def test_the_pendant_types_no_range() -> None:
    ranges = choices.ranges()
    found, named = [], 0
    for path, text in _static_texts().items():
        for tag in re.findall(r"<input[^>]*type=\"number\"[^>]*>", text):
            name = re.search(r'data-range="([^"]+)"', tag)
            if re.search(r"\b(min|max)=", tag):
                found.append(f"{path.name}: {tag}")
            if name is None:
                found.append(f"{path.name}: {tag} names no range (data-range)")
            else:
                named += 1
                assert name.group(1) in ranges, f"{path.name}: no range {name.group(1)}"
    assert not found, "number bounds typed, or none, in the pendant:\n" + "\n".join(found)
    assert named >= 20  # the pendant's inputs do name their ranges


def test_no_viser_slider_is_bounded_by_typed_numbers() -> None:
    found = []
    for path in sorted((ROOT / "app" / "gui").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if not (isinstance(node, ast.Call) and ast.unparse(node.func).endswith("add_slider")):
                continue
            label = node.args[0].value if isinstance(node.args[0], ast.Constant) else None
            if any(isinstance(a, ast.Starred) for a in node.args):
                continue  # *SOME_RANGE: derived
            bounds = node.args[1:3]
            if label not in DISPLAY_SLIDERS and any(isinstance(b, ast.Constant) for b in bounds):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {label}")
    assert not found, "viser sliders with typed bounds:\n" + "\n".join(found)


def test_the_pendant_gets_every_choice_and_range_from_an_endpoint(client) -> None:
    from robomach_core.cmrr import CONTROLLER_NAMES

    body = client.get("/api/choices").json()
    assert body == choices.catalogue()
    assert body["enums"]["cmrr_controller"]["values"] == list(CONTROLLER_NAMES)
    force = body["ranges"]["LEARNING_FORCE_N"]
    assert (force["min"], force["max"]) == (
        limits.LEARNING_FORCE_N.min,
        limits.LEARNING_FORCE_N.max,
    )
    pendant = (ROOT / "static" / "pendant.js").read_text()
    api_prefix = re.search(r'const API = "([^"]+)"', pendant).group(1)
    path = re.search(
        r'api\("GET", "([^"]+)"[^)]*\)', pendant[pendant.index("function loadChoices") :]
    )
    assert api_prefix + path.group(1) == "/api/choices"  # the page asks this very route
    tolerance = body["ranges"]["TOLERANCE_MM"]
    assert (tolerance["min"], tolerance["max"]) == (0.01, 5.0)


def test_the_contract_sees_a_copy() -> None:
    """The scans would catch the copies this issue found (so a pass means something)."""
    tree = 'X = ("constant", "fixed-pi", "adaptive-pi")\nY = Literal["off", "offline", "online"]\n'
    probe = ROOT / "tests" / "app" / "_contract_probe.py"
    probe.write_text(tree)
    try:
        hits = _python_copies(probe)
    finally:
        probe.unlink()
    assert {h.split()[1] for h in hits} == {"cmrr_controller:", "machining_compensation:"}
