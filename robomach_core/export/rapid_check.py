"""A parser and checker for the RAPID subset robomach generates (and hand-written variants).

PROBLEM: a module that a controller refuses to load costs a trip to the cell; and the pipeline
wants to read targets back from a RAPID file (its own or a user's) for a reachability check.
STRATEGY: a small tokenizer and a recursive-descent parser over MODULE / data declarations /
PROC, FUNC, TRAP / statements (calls, assignments, IF, WHILE, FOR, RETURN) / expressions, then a
resolve pass once every module-level name is known (RAPID lets routines use data declared later).
SOLUTION: ``check_rapid_module(text)`` returns a ``RapidModuleInfo`` or raises
``RapidSyntaxError`` with the line number. Checked: bracket balance, identifier form (letter
first, [A-Za-z0-9_], <= 32 characters, not reserved), aggregate arity of the known data types,
normalized quaternions, declared data (with the expected type for motion and Force Control
arguments), defined PROCs for calls, ENDPROC/ENDMODULE, duplicate names (case-insensitive, as in
RAPID). Not checked: general expression types, and instructions outside the known list.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from robomach_core.errors import InvalidInputError

MAX_IDENTIFIER_LEN = 32
QUATERNION_NORM_TOL = 1e-4

_KEYWORDS = frozenset(
    "ALIAS AND BACKWARD CASE CONNECT CONST DEFAULT DIV DO ELSE ELSEIF ENDFOR ENDFUNC ENDIF "
    "ENDMODULE ENDPROC ENDRECORD ENDTEST ENDTRAP ENDWHILE ERROR FALSE FOR FROM FUNC GOTO IF "
    "INOUT LOCAL MOD MODULE NOSTEPIN NOT NOVIEW OR PERS PROC RAISE READONLY RECORD RETRY RETURN "
    "STEP SYSMODULE TASK TEST THEN TO TRAP TRUE TRYNEXT UNDO VAR VIEWONLY WHILE WITH XOR".split()
)
_ROUTINE_END = {"PROC": "ENDPROC", "FUNC": "ENDFUNC", "TRAP": "ENDTRAP"}


class RapidSyntaxError(InvalidInputError):
    """A RAPID module does not parse, or breaks a rule of the checked subset."""

    def __init__(self, line: int, message: str) -> None:
        super().__init__(f"line {line}: {message}")
        self.line = line
        self.message = message


@dataclass(frozen=True, eq=False)
class RapidModuleInfo:
    """What a checked module declares.

    Attributes:
        module_name: the module's name as written.
        proc_names: PROC names in file order.
        robtargets: name -> (position_mm (3,), quaternion_wxyz (4,), confdata (4,) int), for every
            robtarget declared with a literal aggregate, in file order.
        data_types: module-level data name -> type name as written.
    """

    module_name: str
    proc_names: tuple[str, ...]
    robtargets: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    data_types: dict[str, str]


# ---------------------------------------------------------------------------------------------
# Data-type shapes: a leaf is "num" | "bool" | "string"; an aggregate is ((field, shape), ...).

_NUM, _BOOL, _STR = "num", "bool", "string"


def _agg(*fields: str, shape: object = _NUM) -> tuple:
    return tuple((f, shape) for f in fields)


_POS = _agg("x", "y", "z")
_ORIENT = _agg("q1", "q2", "q3", "q4")
_POSE = (("trans", _POS), ("rot", _ORIENT))
_LOAD = (("mass", _NUM), ("cog", _POS), ("aom", _ORIENT)) + _agg("ix", "iy", "iz")
_EXTJOINT = _agg("eax_a", "eax_b", "eax_c", "eax_d", "eax_e", "eax_f")
_SHAPES: dict[str, object] = {
    "NUM": _NUM,
    "BOOL": _BOOL,
    "STRING": _STR,
    "POS": _POS,
    "ORIENT": _ORIENT,
    "POSE": _POSE,
    "CONFDATA": _agg("cf1", "cf4", "cf6", "cfx"),
    "EXTJOINT": _EXTJOINT,
    "ROBJOINT": _agg("rax_1", "rax_2", "rax_3", "rax_4", "rax_5", "rax_6"),
    "ROBTARGET": (
        ("trans", _POS),
        ("rot", _ORIENT),
        ("robconf", _agg("cf1", "cf4", "cf6", "cfx")),
        ("extax", _EXTJOINT),
    ),
    "JOINTTARGET": (("robax", _agg(*(f"rax_{i}" for i in range(1, 7)))), ("extax", _EXTJOINT)),
    "LOADDATA": _LOAD,
    "TOOLDATA": (("robhold", _BOOL), ("tframe", _POSE), ("tload", _LOAD)),
    "WOBJDATA": (
        ("robhold", _BOOL),
        ("ufprog", _BOOL),
        ("ufmec", _STR),
        ("uframe", _POSE),
        ("oframe", _POSE),
    ),
    "SPEEDDATA": _agg("v_tcp", "v_ori", "v_leax", "v_reax"),
    "ZONEDATA": (("finep", _BOOL),)
    + _agg("pzone_tcp", "pzone_ori", "pzone_eax", "zone_ori", "zone_leax", "zone_reax"),
}

# Predefined data of the controller's BASE module that programs may use without declaring.
_SPEEDS = (5, 10, 20, 30, 40, 50, 60, 80, 100, 150, 200, 300, 400, 500, 600, 800, 1000, 1500)
_ZONES = (0, 1, 5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 150, 200)
_BUILTIN_DATA: dict[str, str] = {
    **{f"V{v}": "speeddata" for v in (*_SPEEDS, 2000, 2500, 3000, 4000, 5000, 6000, 7000)},
    "VMAX": "speeddata",
    **{f"Z{z}": "zonedata" for z in _ZONES},
    "FINE": "zonedata",
    "TOOL0": "tooldata",
    "WOBJ0": "wobjdata",
    "LOAD0": "loaddata",
    "PI": "num",
}

# Instruction -> (positional argument types, optional argument types); None = not checked.
_MOVE_OPTS = {"WOBJ": "wobjdata", "TLOAD": "loaddata", "V": "num", "T": "num", "Z": "num"}
_FC_OPTS = {**_MOVE_OPTS, "FX": "num", "FY": "num", "FZ": "num", "FORCECHANGE": "num"}
_SIGNATURES: dict[str, tuple[tuple[str | None, ...], dict[str, str]]] = {
    "MOVEL": (("robtarget", "speeddata", "zonedata", "tooldata"), _MOVE_OPTS),
    "MOVEJ": (("robtarget", "speeddata", "zonedata", "tooldata"), _MOVE_OPTS),
    "MOVEC": (("robtarget", "robtarget", "speeddata", "zonedata", "tooldata"), _MOVE_OPTS),
    "MOVEABSJ": (("jointtarget", "speeddata", "zonedata", "tooldata"), _MOVE_OPTS),
    "FCPRESS1LSTART": (("robtarget", "speeddata", "num", "zonedata", "tooldata"), _FC_OPTS),
    "FCPRESSL": (("robtarget", "speeddata", "num", "zonedata", "tooldata"), _FC_OPTS),
    "FCPRESSC": (
        ("robtarget", "robtarget", "speeddata", "num", "zonedata", "tooldata"),
        _FC_OPTS,
    ),
    "FCPRESSEND": (("robtarget", "speeddata", "tooldata"), _FC_OPTS),
    "FCCALIB": (("loaddata",), {}),
    "FCSPDCHGACT": (("num",), {}),
    "FCSPDCHGTUNSET": (("num", "num"), {}),
    "FCSPDCHGDEACT": ((), {}),
    "FCDEACT": ((), {}),
    "WAITTIME": (("num",), {}),
    "CONFL": ((), {}),
    "CONFJ": ((), {}),
}
_OTHER_INSTRUCTIONS = frozenset(
    "ACCSET BREAK CLEAR DECR EXIT INCR IDELETE ITIMER PATHRESOL RESET SET SETDO SETAO SETGO "
    "SINGAREA SPEEDREFRESH STOP STOPMOVE STARTMOVE TPERASE TPWRITE VELSET WAITDI WAITDO WAITUNTIL "
    "WAITROB SEARCHL TRIGGL MOVELDO MOVEJDO MOVELSYNC MOVEJSYNC "
    "FCACT FCCONDFORCE FCCONDORIENT FCCONDPOS FCCONDREORISPEED FCCONDTCPSPEED FCCONDTORQUE "
    "FCCONDWAITWHILE FCREFCIRCLE FCREFFORCE FCREFLINE FCREFMOVEFRAME FCREFROT "
    "FCREFSPIRAL FCREFSPRFORCECART FCREFSTART FCREFSTOP FCREFTORQUE FCRESETDAMPINGTUNE "
    "FCRESETLPFILTERTUNE FCSPDCHGTUNRESET FCSETDAMPINGTUNE FCSETLPFILTERTUNE FCSUPVFORCE "
    "FCSUPVORIENT FCSUPVPOS FCSUPVREORISPEED FCSUPVTCPSPEED FCSUPVTORQUE".upper().split()
)


# ---------------------------------------------------------------------------------------------
# Tokens


class _Tok(NamedTuple):
    kind: str  # "ident" | "num" | "str" | "op" | "eof"
    text: str
    line: int


_TOKEN_RE = re.compile(
    r"""(?P<ws>[ \t\r\f\v]+)|(?P<nl>\n)|(?P<comment>![^\n]*)
    |(?P<str>"(?:[^"\n]|"")*")
    |(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
    |(?P<ident>[A-Za-z_][A-Za-z0-9_]*)
    |(?P<op>:=|<=|>=|<>|[\[\](){},;:\\=<>+\-*/.])""",
    re.VERBOSE,
)
_OPEN = {"[": "]", "(": ")", "{": "}"}


def _tokenize(text: str) -> list[_Tok]:
    tokens: list[_Tok] = []
    line, pos = 1, 0
    while pos < len(text):
        m = _TOKEN_RE.match(text, pos)
        if m is None:
            if text[pos] == '"':
                raise RapidSyntaxError(line, "unterminated string")
            raise RapidSyntaxError(line, f"unexpected character {text[pos]!r}")
        kind, value = m.lastgroup, m.group()
        pos = m.end()
        if kind == "nl":
            line += 1
        elif kind == "num" and pos < len(text) and (text[pos].isalnum() or text[pos] == "_"):
            tail = re.match(r"[A-Za-z0-9_]*", text[pos:])
            assert tail is not None  # "*" matches, if only the empty string
            word = tail.group()
            raise RapidSyntaxError(
                line, f"invalid identifier {value + word!r}: it must start with a letter"
            )
        elif kind == "ident":
            _check_identifier_form(value, line)
            tokens.append(_Tok(kind, value, line))
        elif kind in ("num", "str", "op"):
            tokens.append(_Tok(kind, value, line))
    tokens.append(_Tok("eof", "", line))
    _check_brackets(tokens)
    return tokens


def _check_identifier_form(name: str, line: int) -> None:
    if not name[0].isalpha():
        raise RapidSyntaxError(line, f"invalid identifier {name!r}: it must start with a letter")
    if len(name) > MAX_IDENTIFIER_LEN:
        raise RapidSyntaxError(
            line, f"identifier {name!r} is {len(name)} characters long (max {MAX_IDENTIFIER_LEN})"
        )


def _check_brackets(tokens: list[_Tok]) -> None:
    """Every [ ( { closes with its partner before the statement's ';'."""
    stack: list[_Tok] = []
    for tok in tokens:
        if tok.kind != "op" and tok.kind != "eof":
            continue
        if tok.text in _OPEN:
            stack.append(tok)
        elif tok.text in (")", "]", "}"):
            if not stack:
                raise RapidSyntaxError(
                    tok.line, f"unbalanced brackets: {tok.text!r} was not opened"
                )
            opener = stack.pop()
            if _OPEN[opener.text] != tok.text:
                raise RapidSyntaxError(
                    tok.line,
                    f"unbalanced brackets: {tok.text!r} closes {opener.text!r} opened at line "
                    f"{opener.line}",
                )
        elif (tok.text == ";" or tok.kind == "eof") and stack:
            opener = stack[-1]
            raise RapidSyntaxError(
                opener.line, f"unbalanced brackets: {opener.text!r} is not closed"
            )


# ---------------------------------------------------------------------------------------------
# Expressions: tuples ("num", line, value) ("str", line, text) ("bool", line, value)
# ("agg", line, items) ("name", line, ident, accessed) ("call", line, ident, args)
# ("un", line, op, x) ("bin", line, op, a, b). Call args: (optional_name | None, expr | None).

_BINARY_LEVELS = (
    ("OR", "XOR"),
    ("AND",),
    ("=", "<>", "<", ">", "<=", ">="),
    ("+", "-"),
    ("*", "/", "DIV", "MOD"),
)
# Tokens that end an operand, none of them a binary operator (``_Parser._lone_number``).
_ENDS_OPERAND = frozenset((",", "]", ")", "}", ";"))


@dataclass
class _Routine:
    kind: str
    name: str
    line: int
    scope: dict[str, tuple[str, int, str]]  # upper name -> (type, line, name)
    uses: list[tuple[tuple, str | None, str]]  # (expr, expected type, role text)
    calls: list[tuple[str, int]]


class _Parser:
    def __init__(self, tokens: list[_Tok]) -> None:
        self.toks = tokens
        self.i = 0
        self.module_data: dict[str, tuple[str, int, str]] = {}  # upper -> (type, line, name)
        self.module_uses: list[tuple[tuple, str | None, str]] = []
        self.routines: list[_Routine] = []
        self.robtargets: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    # -- token helpers
    @property
    def tok(self) -> _Tok:
        return self.toks[self.i]

    def advance(self) -> _Tok:
        tok = self.toks[self.i]
        self.i += 1
        return tok

    def at_kw(self, *words: str) -> bool:
        return self.tok.kind == "ident" and self.tok.text.upper() in words

    def at_op(self, *ops: str) -> bool:
        return self.tok.kind == "op" and self.tok.text in ops

    def expect_op(self, op: str) -> _Tok:
        if not self.at_op(op):
            raise RapidSyntaxError(self.tok.line, f"expected {op!r}, got {self._show()}")
        return self.advance()

    def expect_kw(self, word: str) -> _Tok:
        if not self.at_kw(word):
            raise RapidSyntaxError(self.tok.line, f"expected {word}, got {self._show()}")
        return self.advance()

    def name(self, what: str) -> _Tok:
        tok = self.tok
        if tok.kind != "ident":
            raise RapidSyntaxError(tok.line, f"expected {what}, got {self._show()}")
        if tok.text.upper() in _KEYWORDS:
            raise RapidSyntaxError(tok.line, f"{tok.text!r} is a reserved word, not {what}")
        return self.advance()

    def _show(self) -> str:
        return "end of text" if self.tok.kind == "eof" else repr(self.tok.text)

    # -- module level
    def module(self) -> tuple[str, list[str]]:
        self.expect_kw("MODULE")
        module_name = self.name("a module name").text
        if self.at_op("("):  # attributes, e.g. (SYSMODULE, NOSTEPIN)
            self.advance()
            while not self.at_op(")"):
                self.advance()
            self.advance()
        procs: list[str] = []
        while not self.at_kw("ENDMODULE"):
            if self.tok.kind == "eof":
                raise RapidSyntaxError(self.tok.line, f"MODULE {module_name} has no ENDMODULE")
            if self.at_kw("LOCAL", "TASK"):
                self.advance()
            if self.at_kw("CONST", "VAR", "PERS"):
                self.declaration(self.module_data, self.module_uses, module_level=True)
            elif self.at_kw("PROC", "FUNC", "TRAP"):
                routine = self.routine()
                self._declare(self.module_data, routine.name, routine.kind, routine.line)
                if routine.kind == "PROC":
                    procs.append(routine.name)
            else:
                raise RapidSyntaxError(
                    self.tok.line, f"expected a declaration or a routine, got {self._show()}"
                )
        self.advance()
        if self.tok.kind != "eof":
            raise RapidSyntaxError(self.tok.line, f"text after ENDMODULE: {self._show()}")
        return module_name, procs

    def _declare(self, scope: dict, name: str, type_name: str, line: int) -> None:
        key = name.upper()
        if key in scope:
            raise RapidSyntaxError(
                line, f"{name!r} is declared twice (first at line {scope[key][1]})"
            )
        scope[key] = (type_name, line, name)

    def declaration(self, scope: dict, uses: list, *, module_level: bool) -> None:
        kind = self.advance().text.upper()
        type_tok = self.name("a data type")
        name_tok = self.name("a data name")
        dims = None
        if self.at_op("{"):
            self.advance()
            dims = [self.expr()]
            while self.at_op(","):
                self.advance()
                dims.append(self.expr())
            self.expect_op("}")
        init = None
        if self.at_op(":="):
            self.advance()
            init = self.expr()
        elif kind == "CONST":
            raise RapidSyntaxError(name_tok.line, f"CONST {name_tok.text} needs a value")
        self.expect_op(";")
        self._declare(scope, name_tok.text, type_tok.text, name_tok.line)
        if init is None:
            return
        shape = _SHAPES.get(type_tok.text.upper())
        label = f"{type_tok.text} {name_tok.text}"
        if shape is not None and dims is None:
            _check_shape(init, shape, label)
        uses.append((init, None, label))
        if module_level and type_tok.text.upper() == "ROBTARGET" and dims is None:
            values = _robtarget_values(init)
            if values is not None:
                self.robtargets[name_tok.text] = values

    def routine(self) -> _Routine:
        start = self.advance()
        kind = start.text.upper()
        if kind == "FUNC":
            self.name("a return type")
        name = self.name(f"a {kind} name").text
        scope: dict = {}
        if kind != "TRAP":
            self.expect_op("(")
            while not self.at_op(")"):
                if self.at_op("\\", ",", "|"):
                    self.advance()
                    continue
                if self.at_kw("VAR", "PERS", "INOUT"):
                    self.advance()
                type_tok = self.name("a parameter type")
                self._declare(scope, self.name("a parameter name").text, type_tok.text, start.line)
                if self.at_op("{"):  # array parameter {*}
                    while not self.at_op("}"):
                        self.advance()
                    self.advance()
            self.advance()
        routine = _Routine(kind, name, start.line, scope, [], [])
        while self.at_kw("CONST", "VAR", "PERS", "LOCAL"):
            if self.at_kw("LOCAL"):
                self.advance()
            self.declaration(scope, routine.uses, module_level=False)
        end = _ROUTINE_END[kind]
        self.statements(routine, {end, "ERROR", "UNDO", "BACKWARD"})
        while self.at_kw("ERROR", "UNDO", "BACKWARD"):
            self.advance()
            self.statements(routine, {end, "ERROR", "UNDO", "BACKWARD"})
        self.expect_kw(end)
        self.routines.append(routine)
        return routine

    # -- statements
    def statements(self, routine: _Routine, until: set[str]) -> None:
        while True:
            tok = self.tok
            word = tok.text.upper() if tok.kind == "ident" else ""
            if word in until:
                return
            if tok.kind == "eof" or word in ("PROC", "FUNC", "TRAP", "ENDMODULE", "MODULE"):
                end = _ROUTINE_END[routine.kind]
                raise RapidSyntaxError(
                    tok.line,
                    f"{routine.kind} {routine.name} (line {routine.line}) has no {end} before "
                    f"{self._show()}",
                )
            if word in ("CONST", "VAR", "PERS"):
                raise RapidSyntaxError(tok.line, "declarations must come before the statements")
            if word in _KEYWORDS and word not in ("IF", "WHILE", "FOR", "RETURN", "RAISE", "RETRY"):
                expected = " or ".join(sorted(until))
                raise RapidSyntaxError(tok.line, f"unexpected {tok.text}: expected {expected}")
            self.statement(routine)

    def statement(self, routine: _Routine) -> None:
        tok = self.tok
        word = tok.text.upper() if tok.kind == "ident" else ""
        if word == "IF":
            self.advance()
            routine.uses.append((self.expr(), None, "IF condition"))
            if not self.at_kw("THEN"):  # compact IF: one statement
                self.statement(routine)
                return
            self.advance()
            self.statements(routine, {"ELSEIF", "ELSE", "ENDIF"})
            while self.at_kw("ELSEIF"):
                self.advance()
                routine.uses.append((self.expr(), None, "ELSEIF condition"))
                self.expect_kw("THEN")
                self.statements(routine, {"ELSEIF", "ELSE", "ENDIF"})
            if self.at_kw("ELSE"):
                self.advance()
                self.statements(routine, {"ENDIF"})
            self.expect_kw("ENDIF")
        elif word == "WHILE":
            self.advance()
            routine.uses.append((self.expr(), None, "WHILE condition"))
            self.expect_kw("DO")
            self.statements(routine, {"ENDWHILE"})
            self.expect_kw("ENDWHILE")
        elif word == "FOR":
            self.advance()
            var = self.name("a loop variable")
            routine.scope.setdefault(var.text.upper(), ("num", var.line, var.text))
            self.expect_kw("FROM")
            routine.uses.append((self.expr(), None, "FOR"))
            self.expect_kw("TO")
            routine.uses.append((self.expr(), None, "FOR"))
            if self.at_kw("STEP"):
                self.advance()
                routine.uses.append((self.expr(), None, "FOR"))
            self.expect_kw("DO")
            self.statements(routine, {"ENDFOR"})
            self.expect_kw("ENDFOR")
        elif word in ("RETURN", "RAISE", "RETRY"):
            self.advance()
            if not self.at_op(";"):
                routine.uses.append((self.expr(), None, word))
            self.expect_op(";")
        elif tok.kind == "ident" and self.toks[self.i + 1].text in (":=", ".", "{"):
            target = self.primary()
            self.expect_op(":=")
            routine.uses.append((target, None, "assignment"))
            routine.uses.append((self.expr(), None, "assignment"))
            self.expect_op(";")
        elif tok.kind == "ident":
            self.advance()
            args = self.arguments(";")
            self.expect_op(";")
            routine.calls.append((tok.text, tok.line))
            self._call_uses(routine, tok, args)
        else:
            raise RapidSyntaxError(tok.line, f"expected a statement, got {self._show()}")

    def _call_uses(self, routine: _Routine, tok: _Tok, args: list) -> None:
        positional_types, optional_types = _SIGNATURES.get(tok.text.upper(), (None, {}))
        positional = [expr for opt, expr in args if opt is None]
        if positional_types is not None and len(positional) != len(positional_types):
            raise RapidSyntaxError(
                tok.line,
                f"{tok.text} takes {len(positional_types)} positional argument(s), "
                f"got {len(positional)}",
            )
        for k, expr in enumerate(positional):
            expected = positional_types[k] if positional_types is not None else None
            routine.uses.append((expr, expected, f"argument {k + 1} of {tok.text}"))
        for opt, expr in args:
            if opt is not None and expr is not None:
                expected = optional_types.get(opt.upper())
                routine.uses.append((expr, expected, f"\\{opt} of {tok.text}"))

    def arguments(self, closer: str) -> list[tuple[str | None, tuple | None]]:
        """Arguments up to (not including) ``closer``: positional, ``\\Opt`` or ``\\Opt:=x``."""
        args: list[tuple[str | None, tuple | None]] = []
        while not self.at_op(closer):
            if self.at_op("\\"):
                self.advance()
                opt = self.name("an optional argument name").text
                expr = None
                if self.at_op(":="):
                    self.advance()
                    expr = self.expr()
                args.append((opt, expr))
            else:
                if self.tok.kind == "ident" and self.toks[self.i + 1].text == ":=":
                    self.advance()  # named required argument: Name := value
                    self.advance()
                args.append((None, self.expr()))
            if self.at_op(","):
                self.advance()
                if self.at_op(closer):
                    raise RapidSyntaxError(self.tok.line, f"missing argument before {closer!r}")
            elif not self.at_op("\\", closer):
                raise RapidSyntaxError(
                    self.tok.line,
                    f"expected ',' or {closer!r} after an argument, got {self._show()}",
                )
        return args

    # -- expressions
    def expr(self, level: int = 0) -> tuple:
        if level == 0:
            lone = self._lone_number()
            if lone is not None:
                return lone
        if level == len(_BINARY_LEVELS):
            return self.unary()
        left = self.expr(level + 1)
        ops = _BINARY_LEVELS[level]
        while (self.tok.kind == "op" and self.tok.text in ops) or self.at_kw(*ops):
            op = self.advance()
            left = ("bin", op.line, op.text.upper(), left, self.expr(level + 1))
        return left

    def _lone_number(self) -> tuple | None:
        """The node ``expr`` builds for a number or a signed number that is a whole operand
        (the next token ends it: ``_ENDS_OPERAND``), without climbing the operator levels: a
        module's robtargets are thousands of them. None for anything else."""
        toks, i = self.toks, self.i
        tok = toks[i]
        if tok.kind == "op" and tok.text in ("-", "+"):
            num, end = toks[i + 1], toks[i + 2] if toks[i + 1].kind == "num" else None
            if end is not None and end.kind == "op" and end.text in _ENDS_OPERAND:
                self.i = i + 2
                return ("un", tok.line, tok.text, ("num", num.line, float(num.text)))
            return None
        end = toks[i + 1] if tok.kind == "num" else None
        if end is not None and end.kind == "op" and end.text in _ENDS_OPERAND:
            self.i = i + 1
            return ("num", tok.line, float(tok.text))
        return None

    def unary(self) -> tuple:
        if self.at_op("-", "+") or self.at_kw("NOT"):
            op = self.advance()
            return ("un", op.line, op.text.upper(), self.unary())
        return self.primary()

    def primary(self) -> tuple:
        tok = self.tok
        if tok.kind == "num":
            self.advance()
            return ("num", tok.line, float(tok.text))
        if tok.kind == "str":
            self.advance()
            return ("str", tok.line, tok.text[1:-1].replace('""', '"'))
        if self.at_kw("TRUE", "FALSE"):
            self.advance()
            return ("bool", tok.line, tok.text.upper() == "TRUE")
        if self.at_op("("):
            self.advance()
            inner = self.expr()
            self.expect_op(")")
            return inner
        if self.at_op("["):
            self.advance()
            items = [self.expr()]
            while self.at_op(","):
                self.advance()
                items.append(self.expr())
            self.expect_op("]")
            return ("agg", tok.line, items)
        name = self.name("an expression").text
        if self.at_op("("):
            self.advance()
            args = self.arguments(")")
            self.expect_op(")")
            return ("call", tok.line, name, args)
        accessed = False
        while self.at_op(".", "{"):
            accessed = True
            if self.advance().text == ".":
                self.name("a component name")
            else:
                self.expr()
                while self.at_op(","):
                    self.advance()
                    self.expr()
                self.expect_op("}")
        return ("name", tok.line, name, accessed)


# ---------------------------------------------------------------------------------------------
# Shapes and values


def _literal_number(node: tuple) -> float | None:
    if node[0] == "num":
        return node[2]
    if node[0] == "un" and node[2] in ("-", "+"):
        value = _literal_number(node[3])
        if value is not None:
            return -value if node[2] == "-" else value
    return None


def _check_shape(node: tuple, shape: object, where: str) -> None:
    line = node[1]
    if isinstance(shape, str):
        if node[0] == "agg":
            raise RapidSyntaxError(line, f"{where}: expected a {shape}, got an aggregate")
        literal_kind = {"num": _NUM, "un": _NUM, "bool": _BOOL, "str": _STR}.get(node[0])
        if node[0] == "un" and _literal_number(node) is None:
            literal_kind = None
        if literal_kind is not None and literal_kind != shape:
            raise RapidSyntaxError(line, f"{where}: expected a {shape}, got a {literal_kind}")
        return
    assert isinstance(shape, tuple)  # a record's shape: (field name, shape) pairs
    fields = shape
    if node[0] != "agg":
        if node[0] in ("num", "str", "bool"):
            raise RapidSyntaxError(
                line, f"{where}: expected an aggregate of {len(fields)} components"
            )
        return  # a name or call: its type is not checked here
    items = node[2]
    if len(items) != len(fields):
        names = ", ".join(f for f, _ in fields)
        raise RapidSyntaxError(
            line,
            f"{where}: wrong arity, expected {len(fields)} components [{names}], got {len(items)}",
        )
    for item, (field_name, sub) in zip(items, fields, strict=True):
        _check_shape(item, sub, f"{where}.{field_name}")
    if fields is _ORIENT:
        values = [_literal_number(item) for item in items]
        numbers = [v for v in values if v is not None]
        if len(numbers) == len(values):
            norm = math.sqrt(sum(v * v for v in numbers))
            if abs(norm - 1.0) > QUATERNION_NORM_TOL:
                raise RapidSyntaxError(
                    line, f"{where}: quaternion is not normalized (|q| = {norm:.6f})"
                )


def _robtarget_values(node: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    if node[0] != "agg":
        return None
    parts = []
    for component in node[2][:3]:
        if component[0] != "agg":
            return None
        values = [_literal_number(item) for item in component[2]]
        numbers = [v for v in values if v is not None]
        if len(numbers) < len(values):
            return None
        parts.append(numbers)
    if any(v != round(v) for v in parts[2]):
        raise RapidSyntaxError(node[1], f"confdata must be integers, got {parts[2]}")
    return (
        np.array(parts[0], dtype=float),
        np.array(parts[1], dtype=float),
        np.array(parts[2], dtype=int),
    )


# ---------------------------------------------------------------------------------------------
# Resolution


def _names(node: tuple) -> Iterator[tuple]:
    """Yield the data-name nodes an expression reads."""
    kind = node[0]
    if kind == "name":
        yield node
    elif kind == "agg":
        for item in node[2]:
            yield from _names(item)
    elif kind == "call":
        for _, arg in node[3]:
            if arg is not None:
                yield from _names(arg)
    elif kind == "un":
        yield from _names(node[3])
    elif kind == "bin":
        yield from _names(node[3])
        yield from _names(node[4])


def _resolve_use(expr: tuple, expected: str | None, role: str, scopes: list[dict]) -> None:
    if expected is not None and expr[0] == "agg":
        shape = _SHAPES.get(expected.upper())
        if shape is not None:
            _check_shape(expr, shape, f"{role} ({expected})")
    for node in _names(expr):
        _, line, name, accessed = node
        found = next((scope[name.upper()] for scope in scopes if name.upper() in scope), None)
        is_direct = node is expr and not accessed and expected is not None
        if found is None:
            what = expected if is_direct else "identifier"
            raise RapidSyntaxError(line, f"undeclared {what} {name!r} ({role})")
        declared_type = found[0]
        if is_direct and expected is not None and declared_type.upper() != expected.upper():
            raise RapidSyntaxError(
                line, f"{name!r} is a {declared_type}, expected a {expected} ({role})"
            )


def check_rapid_module(text: str) -> RapidModuleInfo:
    """Parse and check one RAPID module.

    Args:
        text: the module source (LF or CRLF line ends).

    Returns:
        The module's name, PROC names and literal robtargets.

    Raises:
        RapidSyntaxError: on the first problem found, with its line number.
    """
    if not isinstance(text, str):
        raise InvalidInputError(f"RAPID text must be a string, got {type(text).__name__}")
    parser = _Parser(_tokenize(text))
    module_name, procs = parser.module()
    builtins = {k: (v, 0, k) for k, v in _BUILTIN_DATA.items()}
    module_scope = parser.module_data
    for expr, expected, role in parser.module_uses:
        _resolve_use(expr, expected, role, [module_scope, builtins])
    routine_kinds = {key: value[0] for key, value in module_scope.items()}
    for routine in parser.routines:
        scopes = [routine.scope, module_scope, builtins]
        for expr, expected, role in routine.uses:
            _resolve_use(expr, expected, role, scopes)
        for callee, line in routine.calls:
            key = callee.upper()
            if routine_kinds.get(key) == "PROC":
                continue
            if key in _SIGNATURES or key in _OTHER_INSTRUCTIONS:
                continue
            raise RapidSyntaxError(line, f"PROC {callee!r} is called but not defined")
    data_types = {
        name: type_name
        for type_name, _, name in module_scope.values()
        if type_name not in ("PROC", "FUNC", "TRAP")
    }
    return RapidModuleInfo(module_name, tuple(procs), dict(parser.robtargets), data_types)
