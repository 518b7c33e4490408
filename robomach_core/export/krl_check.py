"""A parser and checker for the KRL subset robomach generates (a ``.src`` / ``.dat`` pair).

PROBLEM   A KRL pair the controller refuses to select costs a trip to the cell, and the
          pipeline reads targets back from the program for its reachability check.
STRATEGY  Line-based, as KRL is: ``;`` comments and ``&`` attribute lines dropped; the .src is
          ``DEF name( )`` .. ``END`` holding assignments, subroutine calls and the motion
          statements PTP / LIN / CIRC with an optional approximation (C_PTP, C_DIS, C_VEL,
          C_ORI); the .dat is ``DEFDAT name [PUBLIC]`` .. ``ENDDAT`` holding ``DECL`` lines of
          E6POS / POS / E6AXIS / FRAME aggregates. KRL names are case-insensitive.
SOLUTION  ``check_krl_program(src, dat) -> KrlProgramInfo`` or ``KrlSyntaxError`` naming the
          file and line. Checked: DEF and DEFDAT name the same module (and the file, when its
          stem is given); identifiers (letter first, [A-Za-z0-9_], <= 24 characters, not a
          keyword); aggregates' braces, field names and numbers; every E6POS / POS has X, Y, Z,
          A, B, C (finite; A, B, C in [-180, 180]) and S (0..127), T (0..63); every point a
          motion uses is declared (CIRC: two, the others one); no name declared twice; $BASE and
          $TOOL assigned before the first motion (from a FRAME of the .dat with all six
          components, or one written in place; reading BASE_DATA[n] / TOOL_DATA[n] is a table
          this checker does not know, and writing them is refused: a program leaves the
          controller's measured bases and tools alone), $LOAD from a declared LOAD (M >= 0),
          $VEL.CP (0 < v <= 3 m/s) before the first LIN / CIRC, $APO.CDIS (>= 0 mm) before a
          C_DIS; END and ENDDAT close their files. Not checked: expressions beyond
          numbers and names, control flow (IF, LOOP, ...: refused), system variables other
          than the ones listed in ``KNOWN_SYSTEM_VARIABLES``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import InvalidInputError
from ..transforms import make_transform

MAX_IDENTIFIER_LEN = 24
MAX_VEL_CP_M_S = 3.0  # KSS 8: $VEL.CP up to 3 m/s
MAX_STATUS = 127
MAX_TURN = 63
POINT_TYPES = ("E6POS", "POS", "E6AXIS", "FRAME")
FRAME_FIELDS = ("X", "Y", "Z", "A", "B", "C")
APPROXIMATIONS = ("C_PTP", "C_DIS", "C_VEL", "C_ORI")
KEYWORDS = frozenset(
    "AND ANIN ANOUT B_AND B_NOT B_OR B_EXOR BRAKE CASE CIRC CIRC_REL CONST CONTINUE DECL DEF "
    "DEFAULT DEFDAT DEFFCT DELAY DO ELSE END ENDDAT ENDFCT ENDFOR ENDIF ENDLOOP ENDSWITCH "
    "ENDWHILE EXIT EXT EXTFCT FOR GLOBAL GOTO HALT IF IMPORT INTERRUPT IS LIN LIN_REL LOOP "
    "MAXIMUM MINIMUM NOT OR PRIO PTP PTP_REL PUBLIC REPEAT RESUME RETURN SEC SIGNAL STRUC "
    "SWITCH THEN TO TRIGGER UNTIL WAIT WHEN WHILE EXOR".split()
)
KNOWN_SYSTEM_VARIABLES = frozenset(
    {
        "$BASE",
        "$TOOL",
        "$LOAD",
        "$VEL.CP",
        "$VEL.ORI1",
        "$VEL.ORI2",
        "$APO.CDIS",
        "$APO.CPTP",
        "$APO.CVEL",
        "$APO.CORI",
        "$ACC.CP",
        "$ADVANCE",
        "$ORI_TYPE",
        "$CIRC_TYPE",
    }
)
DATA_ARRAYS = ("BASE_DATA", "TOOL_DATA", "LOAD_DATA")
_IDENT = re.compile(r"[A-Za-z][A-Za-z0-9_]*$")
_NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([Ee][+-]?\d+)?$")


class KrlSyntaxError(InvalidInputError):
    """A KRL pair does not parse, or breaks a rule of the checked subset."""

    def __init__(self, file: str, line: int, message: str) -> None:
        super().__init__(f"{file} line {line}: {message}")
        self.file = file
        self.line = line
        self.message = message


@dataclass(frozen=True)
class KrlPose:
    """One declared point: position [mm], KUKA's A, B, C [deg], Status and Turn (None when
    the point does not give them)."""

    xyz_mm: np.ndarray
    abc_deg: np.ndarray
    status: int | None
    turn: int | None

    def transform(self) -> np.ndarray:
        """4x4 pose [m]: R = Rz(A) Ry(B) Rx(C)."""
        from .krl import kuka_rotation

        return make_transform(kuka_rotation(self.abc_deg), self.xyz_mm * 1e-3)


@dataclass(frozen=True)
class KrlMotion:
    """One motion statement: ``kind`` (PTP, LIN, CIRC), its points (CIRC: via, to), the
    approximation (None: exact stop) and the $VEL.CP [m/s] in force (None before any)."""

    kind: str
    points: tuple[str, ...]
    approximation: str | None
    vel_cp_m_s: float | None
    line: int


@dataclass(frozen=True)
class KrlProgramInfo:
    """What a checked pair declares and does.

    Attributes:
        module_name: The DEF / DEFDAT name as written in the .src.
        points: Upper-case name -> ``KrlPose`` of every E6POS / POS / FRAME in the .dat.
        motions: The motion statements in order.
        base: The frame made $BASE (mm, deg), or None.
        tool: The same for $TOOL.
    """

    module_name: str
    points: dict[str, KrlPose]
    motions: tuple[KrlMotion, ...]
    base: KrlPose | None
    tool: KrlPose | None
    assignments: dict[str, str] = field(default_factory=dict)

    def motion_poses(self) -> list[tuple[str, np.ndarray]]:
        """(point name, 4x4 T_base_tcp [m] in the robot base: $BASE x point) of every
        motion target in order (a CIRC's via point first)."""
        T_base = np.eye(4) if self.base is None else self.base.transform()
        out = []
        for motion in self.motions:
            for name in motion.points:
                out.append((name, T_base @ self.points[name.upper()].transform()))
        return out


def _lines(text: str) -> list[tuple[int, str]]:
    """(line number, code) without comments, attribute lines and blank lines."""
    out = []
    for number, raw in enumerate(text.splitlines(), start=1):
        if any(ord(ch) > 126 or (ord(ch) < 32 and ch != "\t") for ch in raw):
            raise ValueError(number)
        code = raw.split(";", 1)[0].strip()
        if not code or code.startswith("&"):
            continue
        out.append((number, code))
    return out


def _check_name(name: str, file: str, line: int, what: str) -> str:
    if not _IDENT.match(name):
        raise KrlSyntaxError(file, line, f"{what} {name!r} is not a KRL name")
    if len(name) > MAX_IDENTIFIER_LEN:
        raise KrlSyntaxError(
            file, line, f"{what} {name!r} is longer than {MAX_IDENTIFIER_LEN} characters"
        )
    if name.upper() in KEYWORDS:
        raise KrlSyntaxError(file, line, f"{what} {name!r} is a KRL keyword")
    return name


def _number(text: str, file: str, line: int, what: str) -> float:
    if not _NUMBER.match(text):
        raise KrlSyntaxError(file, line, f"{what}: {text!r} is not a number")
    value = float(text)
    if not math.isfinite(value):
        raise KrlSyntaxError(file, line, f"{what}: {text!r} is not finite")
    return value


def _aggregate(text: str, file: str, line: int) -> dict[str, object]:
    """Parse ``{F v, G {H w, ...}, ...}`` (an optional leading ``TYPE:`` is dropped): field
    name (upper case) -> number or nested dict."""
    text = text.strip()
    if not (text.startswith("{") and text.endswith("}")):
        raise KrlSyntaxError(file, line, f"expected an aggregate {{...}}, got {text[:40]!r}")
    body = text[1:-1].strip()
    if ":" in body.split(",", 1)[0] and "{" not in body.split(":", 1)[0]:
        body = body.split(":", 1)[1]  # {FRAME: X 1, ...}
    parts, depth, start = [], 0, 0
    for i, ch in enumerate(body):
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
            if depth < 0:
                raise KrlSyntaxError(file, line, "unbalanced braces")
        elif ch == "," and depth == 0:
            parts.append(body[start:i])
            start = i + 1
    if depth != 0:
        raise KrlSyntaxError(file, line, "unbalanced braces")
    parts.append(body[start:])
    out: dict[str, object] = {}
    for part in parts:
        part = part.strip()
        if not part:
            raise KrlSyntaxError(file, line, "an empty field in an aggregate")
        name, _, value = part.partition(" ")
        key = name.upper()
        if not _IDENT.match(name):
            raise KrlSyntaxError(file, line, f"field name {name!r} is not a KRL name")
        if key in out:
            raise KrlSyntaxError(file, line, f"field {name} given twice")
        value = value.strip()
        if value.startswith("{"):
            out[key] = _aggregate(value, file, line)
        else:
            out[key] = _number(value, file, line, f"field {name}")
    return out


def _pose(fields: dict[str, object], file: str, line: int, what: str, *, st: bool) -> KrlPose:
    missing = [f for f in FRAME_FIELDS if f not in fields]
    if missing:
        raise KrlSyntaxError(file, line, f"{what} lacks {', '.join(missing)}")
    values = {f: v for f in FRAME_FIELDS if isinstance(v := fields[f], float)}
    if len(values) < len(FRAME_FIELDS):
        raise KrlSyntaxError(file, line, f"{what}: X, Y, Z, A, B, C must be numbers")
    for f in ("A", "B", "C"):
        if not -180.0 <= values[f] <= 180.0:
            raise KrlSyntaxError(file, line, f"{what}: {f} {values[f]:g} is outside [-180, 180]")
    status = turn = None
    if st:
        whole: dict[str, int] = {}
        for f, top in (("S", MAX_STATUS), ("T", MAX_TURN)):
            if f not in fields:
                raise KrlSyntaxError(file, line, f"{what} lacks {f}")
            v = fields[f]
            if not isinstance(v, float) or v != int(v) or not 0 <= v <= top:
                raise KrlSyntaxError(file, line, f"{what}: {f} must be an integer 0..{top}")
            whole[f] = int(v)
        status, turn = whole["S"], whole["T"]
    xyz = np.array([values["X"], values["Y"], values["Z"]])
    abc = np.array([values["A"], values["B"], values["C"]])
    return KrlPose(xyz, abc, status, turn)


def _load(fields: dict[str, object], file: str, line: int, what: str) -> None:
    """A LOAD aggregate: a mass M >= 0 [kg], and CM a frame when given."""
    if "M" not in fields or not isinstance(fields["M"], float) or fields["M"] < 0:
        raise KrlSyntaxError(file, line, f"{what} needs a mass M >= 0")
    if "CM" in fields:
        if not isinstance(fields["CM"], dict):
            raise KrlSyntaxError(file, line, f"{what}: CM must be a frame")
        _pose(fields["CM"], file, line, f"{what}.CM", st=False)


def _parse_dat(dat: str, file: str) -> tuple[str, dict[str, KrlPose], set[str]]:
    try:
        lines = _lines(dat)
    except ValueError as exc:
        raise KrlSyntaxError(file, exc.args[0], "non-ASCII or control character") from None
    if not lines:
        raise KrlSyntaxError(file, 1, "empty file: expected DEFDAT")
    number, first = lines[0]
    words = first.split()
    if words[0].upper() != "DEFDAT" or len(words) not in (2, 3):
        raise KrlSyntaxError(file, number, "expected DEFDAT name [PUBLIC]")
    if len(words) == 3 and words[2].upper() != "PUBLIC":
        raise KrlSyntaxError(file, number, f"unexpected {words[2]!r} after the DEFDAT name")
    name = _check_name(words[1], file, number, "module")
    if lines[-1][1].upper() != "ENDDAT":
        raise KrlSyntaxError(file, lines[-1][0], "the .dat must end with ENDDAT")
    points: dict[str, KrlPose] = {}
    declared: set[str] = set()
    for number, code in lines[1:-1]:
        match = re.match(
            r"DECL\s+(GLOBAL\s+)?([A-Za-z0-9_]+)\s+([A-Za-z0-9_]+)\s*=\s*(.*)$", code, re.I
        )
        if not match:
            raise KrlSyntaxError(file, number, f"expected DECL type name=value, got {code[:40]!r}")
        kind, var, value = match.group(2).upper(), match.group(3), match.group(4)
        _check_name(var, file, number, "point")
        if var.upper() in declared:
            raise KrlSyntaxError(file, number, f"{var} is declared twice")
        declared.add(var.upper())
        if kind == "LOAD":
            _load(_aggregate(value, file, number), file, number, var)
            continue
        if kind not in POINT_TYPES:
            raise KrlSyntaxError(file, number, f"{var}: type {kind} is not a point type")
        fields = _aggregate(value, file, number)
        if kind == "E6AXIS":
            continue
        points[var.upper()] = _pose(fields, file, number, var, st=kind in ("E6POS", "POS"))
    return name, points, declared


def check_krl_program(src: str, dat: str, *, stem: str | None = None) -> KrlProgramInfo:
    """Parse and check a KRL ``.src`` and its ``.dat`` (module docstring lists the rules).

    Args:
        src, dat: The two files' texts.
        stem: The files' name without suffix; when given, DEF must name it.

    Raises:
        KrlSyntaxError: the file, line and rule broken.
    """
    src_file, dat_file = f"{stem or 'program'}.src", f"{stem or 'program'}.dat"
    dat_name, points, declared = _parse_dat(dat, dat_file)
    try:
        lines = _lines(src)
    except ValueError as exc:
        raise KrlSyntaxError(src_file, exc.args[0], "non-ASCII or control character") from None
    if not lines:
        raise KrlSyntaxError(src_file, 1, "empty file: expected DEF")
    number, first = lines[0]
    match = re.match(r"DEF\s+([A-Za-z0-9_]+)\s*\(\s*\)$", first, re.I)
    if not match:
        raise KrlSyntaxError(src_file, number, "expected DEF name( )")
    name = _check_name(match.group(1), src_file, number, "module")
    if name.upper() != dat_name.upper():
        raise KrlSyntaxError(
            src_file, number, f"DEF {name} and DEFDAT {dat_name} name different modules"
        )
    if stem is not None and name.upper() != stem.upper():
        raise KrlSyntaxError(src_file, number, f"DEF {name} does not name the file {stem}")
    if lines[-1][1].upper() != "END":
        raise KrlSyntaxError(src_file, lines[-1][0], "the .src must end with END")
    # the .dat's FRAMEs (no Status / Turn) may be made $BASE and $TOOL
    frames: dict[str, KrlPose] = {k: v for k, v in points.items() if v.status is None}
    loads = declared - set(points)
    state: dict[str, object] = {}
    motions: list[KrlMotion] = []
    assignments: dict[str, str] = {}
    for number, code in lines[1:-1]:
        head = code.split()[0].upper()
        if head in ("PTP", "LIN", "CIRC"):
            motions.append(_motion(code, number, src_file, points, declared, state))
            continue
        if "=" in code:
            target, _, value = (part.strip() for part in code.partition("="))
            _assignment(target, value, number, src_file, frames, state, loads)
            assignments[target.upper()] = value
            continue
        call = re.match(r"([A-Za-z][A-Za-z0-9_]*)\s*\((.*)\)$", code)
        if call and call.group(1).upper() not in KEYWORDS:
            continue  # a subroutine call (BAS(#INITMOV, 0))
        raise KrlSyntaxError(src_file, number, f"unsupported statement {code[:40]!r}")
    return KrlProgramInfo(
        module_name=name,
        points=points,
        motions=tuple(motions),
        base=state.get("$BASE"),  # type: ignore[arg-type]
        tool=state.get("$TOOL"),  # type: ignore[arg-type]
        assignments=assignments,
    )


def _assignment(
    target: str,
    value: str,
    number: int,
    file: str,
    frames: dict[str, KrlPose],
    state: dict[str, object],
    loads: set[str],
) -> None:
    key = target.upper().replace(" ", "")
    array = re.match(r"([A-Z_]+)\[(\d+)\]$", key)
    if array and array.group(1) in DATA_ARRAYS:
        raise KrlSyntaxError(
            file,
            number,
            f"{target} = ...: a program does not overwrite the controller's {array.group(1)} "
            "table (its measured bases and tools); declare a FRAME or LOAD in the .dat",
        )
    if not key.startswith("$"):
        raise KrlSyntaxError(file, number, f"assignment to {target!r}: not a system variable")
    if key not in KNOWN_SYSTEM_VARIABLES:
        raise KrlSyntaxError(file, number, f"unknown system variable {target}")
    if key in ("$BASE", "$TOOL"):
        source = value.upper().replace(" ", "")
        if source in frames:
            state[key] = frames[source]
        elif source.startswith("{"):
            state[key] = _pose(_aggregate(value, file, number), file, number, key, st=False)
        else:
            raise KrlSyntaxError(file, number, f"{key} = {value}: no such frame assigned before")
        return
    if key == "$LOAD":
        source = value.upper().replace(" ", "")
        if source.startswith("{"):
            _load(_aggregate(value, file, number), file, number, key)
        elif source not in loads and not re.match(r"LOAD_DATA\[\d+\]$", source):
            raise KrlSyntaxError(file, number, f"$LOAD = {value}: no such LOAD declared")
        state[key] = value
        return
    v = _number(value, file, number, target)
    if key == "$VEL.CP" and not 0.0 < v <= MAX_VEL_CP_M_S:
        raise KrlSyntaxError(file, number, f"$VEL.CP {v:g} m/s is outside (0, {MAX_VEL_CP_M_S:g}]")
    if key.startswith("$APO.") and v < 0.0:
        raise KrlSyntaxError(file, number, f"{key} must be >= 0, got {v:g}")
    state[key] = v


def _motion(
    code: str,
    number: int,
    file: str,
    points: dict[str, KrlPose],
    declared: set[str],
    state: dict[str, object],
) -> KrlMotion:
    kind, _, rest = code.partition(" ")
    kind = kind.upper()
    words = rest.replace(",", " , ").split()
    approximation = None
    if words and words[-1].upper() in APPROXIMATIONS:
        approximation = words.pop().upper()
    names = [w for w in words if w != ","]
    if words.count(",") != len(names) - 1:
        raise KrlSyntaxError(file, number, f"{kind}: malformed point list")
    expected = 2 if kind == "CIRC" else 1
    if len(names) != expected:
        raise KrlSyntaxError(file, number, f"{kind} takes {expected} point(s), got {len(names)}")
    for name in names:
        if name.upper() not in declared:
            raise KrlSyntaxError(file, number, f"{kind} {name}: no such point in the .dat")
        if name.upper() not in points:
            raise KrlSyntaxError(file, number, f"{kind} {name}: not a Cartesian point")
    for needed in ("$BASE", "$TOOL"):
        if needed not in state:
            raise KrlSyntaxError(file, number, f"{kind} before {needed} is assigned")
    if kind != "PTP" and "$VEL.CP" not in state:
        raise KrlSyntaxError(file, number, f"{kind} before $VEL.CP is assigned")
    if approximation == "C_DIS" and "$APO.CDIS" not in state:
        raise KrlSyntaxError(file, number, "C_DIS before $APO.CDIS is assigned")
    if approximation == "C_PTP" and kind != "PTP":
        raise KrlSyntaxError(file, number, f"{kind} cannot use C_PTP")
    vel = state.get("$VEL.CP")
    return KrlMotion(kind, tuple(names), approximation, vel, number)  # type: ignore[arg-type]
