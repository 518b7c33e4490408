"""Every enum and range is defined once in the core and derived everywhere else (issue 17,
item 2): this contract fails when a boundary types a copy.

- No module of the app (CLI commands, REST schemas and routes, viser panels, the session) holds
  a literal list, tuple, set, dict's keys or ``Literal[...]`` of an enum's values (the
  controller names, the compensation, the program languages, the wall sides, ...); the core
  defines each once and types no copy either.
- The compensation's old spellings (``offline_linear``, ...) are typed only where the rule that
  reads them lives (``stiffness.modes``).
- A number a user gets when they give none is typed once: a REST field, a query, a viser
  input, a pendant input or a CLI option bounded by a ``limits`` range that has a default
  takes that default from there (never a number of its own), and bounds come from the range.
- No script or page of the pendant (``static/``) holds an array or a ``<select>`` of them, and
  no number input carries its own ``min``/``max``: it names a ``limits`` range
  (``data-range``) that ``GET /api/choices`` serves.
- No viser slider is bounded by numbers typed in the panel.
- ``GET /api/choices`` serves ``robomach_core.choices.catalogue()``.
"""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

from robomach_core import choices, limits

ROOT = Path(__file__).resolve().parents[2]
# The enums whose copies drifted or could (values specific enough to be recognised).
WATCHED = (
    "cmrr_controller",
    "compensation",
    "offline_model",
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


def _translation(node: ast.Dict) -> bool:
    """A dict from words to words (``{"offline": "offline_linear", ...}``): a second
    vocabulary mapped onto the first. Labels (words with spaces) and data are not."""
    return bool(node.values) and all(
        isinstance(v, ast.Constant)
        and isinstance(v.value, str)
        and re.fullmatch(r"[\w-]+", v.value) is not None
        for v in node.values
    )


def _strings(node: ast.AST) -> set[str] | None:
    """The strings of a literal tuple, list, set or ``Literal[...]``; None for other nodes."""
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        elements = node.elts
    elif isinstance(node, ast.Dict) and _translation(node):
        elements = [k for k in node.keys if k is not None]  # a table from one word to another
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
            if isinstance(node, ast.Dict):
                continue  # a table over the whole enum: data keyed by it (a family's language)
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


# Data, not a copy: the arm families that have an online path correction (all three today),
# and each compensation study's paper arm.
CORE_DATA = {
    ("robomach_core/machining/choice.py", "arm_family"),
    ("robomach_core/stiffness/studies/_common.py", "compensation_study"),
}
# The compensation's old spellings (and their prefix, which parsing or building them takes),
# and the one module that reads and writes them (its rule).
OLD_COMPENSATION_SPELLINGS = ("offline_linear", "offline_nonlinear", "offline_")
OLD_SPELLINGS_RULE = "robomach_core/stiffness/modes.py"


def test_the_old_compensation_spellings_live_only_with_their_rule() -> None:
    """``offline_linear`` and ``offline_nonlinear`` were a second vocabulary (issue 30):
    only ``stiffness.modes`` may type them (it reads them and writes the one-word names);
    the app, the core and the pendant use the pair ``offline`` + ``offline_model``."""
    found = []
    for path in sorted([*(ROOT / "robomach_core").rglob("*.py"), *(ROOT / "app").rglob("*.py")]):
        where = str(path.relative_to(ROOT))
        if where == OLD_SPELLINGS_RULE:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and node.value in OLD_COMPENSATION_SPELLINGS:
                found.append(f"{where}:{node.lineno}: {node.value!r}")
    for path, text in _static_texts().items():
        for word in OLD_COMPENSATION_SPELLINGS:
            if re.search(rf"[\"'`]{word}[\"'`]", text):
                found.append(f"static/{path.name}: {word!r}")
    assert not found, "old compensation spellings typed outside their rule:\n" + "\n".join(found)


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
    assert {h.split()[1] for h in hits} == {"cmrr_controller:", "compensation:"}


# --- defaults: each number a user gets when they give none is typed once (issue 30) ---------

_RANGE_NAME = re.compile(r"\b([A-Z][A-Z0-9_]+)\.(?:min|max)\b")
# A parameter's unit suffix -> (the range unit it matches, the factor from that unit).
_SUFFIX_UNITS = {
    "_N": ("N", 1.0),
    "_mm": ("mm", 1.0),
    "_m": ("mm", 1e-3),
    "_mm_s": ("mm/s", 1.0),
    "_m_s": ("mm/s", 1e-3),
}
# Other quantities that happen to share a default's number (name -> why).
OTHER_QUANTITIES = {
    "tool_stop_m": "the supervisor's stop distance, not the floor clearance",
    "wall_offset_mm": "a casting's wall offset, not the floor clearance",
    "arm_stop_m": "the supervisor's stop distance",
    "search_speed_m_s": "the contact search's speed, not the learning speed",
    "axial_engagement_m": "the cut's height, not the learning speed",
    "length_m": "a CMRR cut's length",
    "transition_m": "a depth profile's ramp",
    "window_m": "the wall-normal window",
    "resolution_m": "a depth profile's resolution",
    "allowance_m": "a CMRR stock's allowance",
    "base_depth_mm": "a CMRR scenario's depth",
    "spacing_m": "a stock's point spacing",
    "zone_mm": "RAPID's zone",
    "tool_slow_m": "the supervisor's slow-down distance",
    "tolerance_m": "a push's or IK's position tolerance, not the reduction's",
    "normal_force_N": "a milling scenario's normal force",
    "deviation_scale_m": "the colour scale of the deviation map",
    "height_m": "a CMRR block's height",
    "depth_of_cut_m": "a milling scenario's depth of cut",
    "command_speed_cap_m_s": "the machining feed's cap, not the jog speed",
    "speed_mean_m_s": "the program's mean feed, not the jog speed",
}


# Pendant inputs that are a setting of their own within a range that has a default (id -> why).
PAGE_SETTINGS = {"jog-step-z": "the Z step, longer than the X/Y step's default (8 mm)"}


def _with_default() -> dict[str, limits.Range]:
    return {n: r for n, r in choices.ranges().items() if r.default is not None}


def _number(node: ast.AST | None) -> bool:
    if isinstance(node, ast.UnaryOp):
        node = node.operand
    return (
        isinstance(node, ast.Constant)
        and isinstance(node.value, (int, float))
        and not (isinstance(node.value, bool))
    )


def _value(node: ast.AST) -> float:
    if isinstance(node, ast.UnaryOp):
        return -float(node.operand.value)  # type: ignore[attr-defined]
    return float(node.value)  # type: ignore[attr-defined]


def _boundary_default_copies(path: Path) -> list[str]:
    """Calls bounded by a range that has a default (``ge=R.min``, ``min=R.min``) whose default
    is a number typed there; function parameters typed ``Query(ge=R.min, ...)`` likewise; and
    bounds typed as the very numbers of a range."""
    with_default, found = _with_default(), []
    tree = ast.parse(path.read_text())
    where = str(path.relative_to(ROOT))
    # every range's bounds but a fraction's 0-1 (a job's progress is no range of a setting)
    spans = {(r.min, r.max) for r in choices.ranges().values()} - {(0.0, 1.0)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            kw = {k.arg: k.value for k in node.keywords if k.arg}
            bounds = [kw[k] for k in ("ge", "gt", "le", "lt", "min", "max") if k in kw]
            named = set(_RANGE_NAME.findall(" ".join(ast.unparse(b) for b in bounds)))
            func = ast.unparse(node.func)
            default = kw.get("default")
            if default is None and node.args:
                first = 1 if func.endswith(("add_number", "add_slider")) else 0
                default = node.args[first] if len(node.args) > first else None
            if named & set(with_default) and _number(default):
                found.append(f"{where}:{node.lineno} {func}: default {ast.unparse(default)}")
            low = next((kw[k] for k in ("ge", "gt", "min") if k in kw), None)
            high = next((kw[k] for k in ("le", "lt", "max") if k in kw), None)
            if _number(low) and _number(high) and (_value(low), _value(high)) in spans:
                found.append(f"{where}:{node.lineno} {func}: a range's bounds typed again")
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args.args + node.args.kwonlyargs
            defaults = [None] * (len(node.args.args) - len(node.args.defaults))
            defaults += list(node.args.defaults) + list(node.args.kw_defaults)
            for arg, default in zip(args, defaults, strict=True):
                text = ast.unparse(arg.annotation) if arg.annotation is not None else ""
                if set(_RANGE_NAME.findall(text)) & set(with_default) and _number(default):
                    found.append(f"{where}:{node.lineno} {arg.arg}: default {ast.unparse(default)}")
    return found


def _unit_default_copies(path: Path) -> list[str]:
    """Parameters and fields named with a unit (``force_N``, ``speed_m_s``) whose default is
    a number equal to a range's default in that unit: the number typed again."""
    typed = [(name, r.unit, r.default_value()) for name, r in _with_default().items() if r.unit]
    found, where = [], str(path.relative_to(ROOT))

    def check(name: str, node: ast.AST | None, line: int) -> None:
        if not _number(node) or name in OTHER_QUANTITIES:
            return
        for suffix, (unit, factor) in _SUFFIX_UNITS.items():
            if not name.endswith(suffix):
                continue
            for range_name, range_unit, value in typed:
                if range_unit == unit and math.isclose(_value(node), value * factor):
                    found.append(f"{where}:{line} {name} = {ast.unparse(node)} ({range_name})")

    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            check(node.target.id, node.value, node.lineno)
        elif isinstance(node, ast.Assign):
            for target in node.targets:
                if isinstance(target, ast.Name):
                    check(target.id, node.value, node.lineno)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args.args + node.args.kwonlyargs
            defaults = [None] * (len(node.args.args) - len(node.args.defaults))
            defaults += list(node.args.defaults) + list(node.args.kw_defaults)
            for arg, default in zip(args, defaults, strict=True):
                check(arg.arg, default, node.lineno)
        elif isinstance(node, ast.Call):
            for k in node.keywords:
                if k.arg == "default" and node.args and isinstance(node.args[0], ast.Constant):
                    option = str(node.args[0].value).lstrip("-").replace("-", "_")
                    check(option, k.value, node.lineno)
    return found


def test_each_default_is_typed_once() -> None:
    """The 10 N, 5 mm/s, 0.2 mm, 0.5 mm floor clearance, the touch-off's 10 N and 30 mm, ...:
    typed on their ``limits`` range (``default=``) and read from there (or from the settings
    class that reads it) by the settings classes, the CLI, the REST schemas, both GUIs and the
    pendant; a copy anywhere fails here."""
    paths = sorted([*(ROOT / "app").rglob("*.py"), *(ROOT / "robomach_core").rglob("*.py")])
    found = [
        hit for p in paths if p.is_relative_to(ROOT / "app") for hit in _boundary_default_copies(p)
    ]
    found += [hit for p in paths for hit in _unit_default_copies(p)]
    with_default = _with_default()
    for path, text in _static_texts().items():
        for tag in re.findall(r"<input[^>]*type=\"number\"[^>]*>", text):
            name = re.search(r'data-range="([^"]+)"', tag)
            own = re.search(r'id="([^"]+)"', tag)
            if own and own.group(1) in PAGE_SETTINGS:
                continue
            if name and name.group(1) in with_default and re.search(r"\bvalue=", tag):
                found.append(f"{path.name}: {tag} (the range {name.group(1)} has a default)")
    assert not found, "defaults typed again:\n" + "\n".join(found)


def test_the_default_scan_sees_a_copy() -> None:
    """The scan catches the copies issue 30 found (so a pass means something)."""
    probe = ROOT / "tests" / "app" / "_defaults_probe.py"
    probe.write_text(
        "from robomach_core import limits\n"
        "touch_force_N: float = 10.0\n"
        "def check(force_N: Annotated[float, Query(ge=limits.LEARNING_FORCE_N.min)] = 10.0):\n"
        "    pass\n"
        "x = Field(default=30.0, ge=limits.TOUCH_OFF_TRAVEL_MM.min)\n"
        "y = Query(ge=1.0, le=50.0)\n"
        "p.add_argument('--force-N', type=float, default=10.0)\n"
    )
    try:
        hits = _boundary_default_copies(probe) + _unit_default_copies(probe)
    finally:
        probe.unlink()
    lines = sorted(int(h.split(":")[1].split()[0]) for h in hits)
    assert set(lines) == {2, 3, 5, 6, 7}, hits
