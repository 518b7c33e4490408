"""Tests of the ABB RAPID exporter and its checker."""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.errors import InvalidInputError
from robomach_core.export import (
    ForceControlSettings,
    RapidProgram,
    RapidSyntaxError,
    RapidTarget,
    RapidTool,
    RapidWorkObject,
    SpeedChangeSettings,
    check_rapid_module,
    confdata_from_joints,
    rapid_identifier,
    rapid_module,
    rapid_quaternion,
    write_rapid_module,
)
from robomach_core.export import rapid as rapid_export
from robomach_core.postprocess import Move
from robomach_core.transforms import matrix_from_quaternion
from tests.rapid_grammar import GRAMMAR_ROBTARGETS, rapidchecker_errors

GOLDEN_DIR = Path(__file__).parent / "golden"
UPDATE_GOLDEN = os.environ.get("ROBOMACH_UPDATE_GOLDEN") == "1"
JOINTS = np.array([0.1, -1.2, 1.5, -1.8, -1.57, 0.3])


def rot(axis: tuple[float, float, float], angle_rad: float) -> np.ndarray:
    """Rodrigues rotation matrix."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle_rad) * K + (1.0 - math.cos(angle_rad)) * K @ K


def pose(R: np.ndarray, p_m: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p_m
    return T


def make_tool(name: str = "spindle") -> RapidTool:
    return RapidTool(name, pose(np.eye(3), (0.0, 0.0, 0.15)), 2.5, np.array([0.0, 0.0, 0.07]))


def make_wobj(name: str = "pump housing") -> RapidWorkObject:
    return RapidWorkObject(name, pose(rot((0, 0, 1), 0.3), (0.8, -0.2, 0.1)))


def make_targets(n: int = 3) -> list[RapidTarget]:
    """A short groove: tool pointing down, turning slowly about the wobj z axis."""
    down = rot((1, 0, 0), math.pi)
    return [
        RapidTarget(
            pose(down @ rot((0, 0, 1), 0.1 * i), (0.01 * i, 0.02, -0.001 * i)),
            JOINTS + 0.01 * i,
            5.0 if i < 2 else 7.25,
        )
        for i in range(n)
    ]


def make_program(**overrides: object) -> RapidProgram:
    kwargs: dict[str, object] = {
        "module_name": "groove",
        "tool": make_tool(),
        "wobj": make_wobj(),
        "targets": make_targets(),
        "comment": ["robomach test", "tolerance 0.2 mm"],
    }
    kwargs.update(overrides)
    return RapidProgram(**kwargs)


def assert_round_trip(program: RapidProgram) -> None:
    info = check_rapid_module(rapid_module(program))
    for i, target in enumerate(program.targets):
        pos_mm, quat, conf = info.robtargets[f"p{i + 1}"]
        np.testing.assert_allclose(pos_mm, target.T_wobj_target[:3, 3] * 1000.0, atol=6e-4)
        assert abs(np.linalg.norm(quat) - 1.0) < 1e-5
        np.testing.assert_allclose(
            matrix_from_quaternion(quat), target.T_wobj_target[:3, :3], atol=1e-5
        )
        first_nonzero = quat[np.flatnonzero(quat)[0]]
        assert first_nonzero > 0.0
        assert tuple(conf) == confdata_from_joints(target.joints_rad, cfx=target.cfx)


# rapidchecker (tests/rapid_grammar.py) sees at most this many distinct modules per test (a test
# writes one to three; the Hypothesis property below writes 40+, which took 40 s; the project's
# own checker and the round trip still see every one of them).
RAPIDCHECKER_PER_TEST = 10


@pytest.fixture(autouse=True)
def _rapidchecker_on_every_generated_module(monkeypatch: pytest.MonkeyPatch):
    """Every module a test generates (``rapid_module``, ``write_rapid_module``) also passes
    rapidchecker, besides the project's own checker."""
    generated: list[str] = []
    original = rapid_export.rapid_module

    def recording(program: RapidProgram) -> str:
        text = original(program)
        generated.append(text)
        return text

    monkeypatch.setitem(globals(), "rapid_module", recording)
    monkeypatch.setattr(rapid_export, "rapid_module", recording)
    yield
    for text in list(dict.fromkeys(generated))[:RAPIDCHECKER_PER_TEST]:
        assert rapidchecker_errors(text) == [], text


# -------------------------------------------------------------------------------------------------
# Generator


def test_round_trip_targets_in_mm_and_wxyz() -> None:
    program = make_program()
    assert_round_trip(program)
    info = check_rapid_module(rapid_module(program))
    assert info.module_name == "groove"
    assert info.proc_names == ("main",)
    assert list(info.robtargets) == ["p_approach", "p1", "p2", "p3", "p_retract"]
    # The tool points down (wobj -z), so backing off along the tool axis goes up by 20 mm.
    np.testing.assert_allclose(info.robtargets["p_approach"][0], [0.0, 20.0, 20.0], atol=1e-9)
    np.testing.assert_allclose(info.robtargets["p_retract"][0], [20.0, 20.0, 18.0], atol=1e-9)
    assert info.data_types["spindle"] == "tooldata"
    assert info.data_types["pump_housing"] == "wobjdata"


@pytest.mark.parametrize(
    "overrides",
    [
        {},
        {"targets": make_targets(7), "max_moves_per_proc": 3},
        {"force_control": ForceControlSettings(10.0)},
        {"force_control": ForceControlSettings(12.5, "z", pos_supv_dist_mm=15.0)},
        {"speed_change": SpeedChangeSettings(30.0)},
        {
            "targets": make_targets(5),
            "max_moves_per_proc": 2,
            "force_control": ForceControlSettings(10.0, force_change_N_s=None),
            "speed_change": SpeedChangeSettings(30.0, speed_levels=2, min_speed_ratio=0.5),
        },
        {"zone_mm": 0.0, "monitor_config": True, "approach_offset_mm": 0.0},
    ],
    ids=["plain", "split", "fc", "fc_z", "speed_change", "fc_sc_split", "fine"],
)
def test_every_variant_passes_the_checker(overrides: dict[str, object]) -> None:
    program = make_program(**overrides)
    text = rapid_module(program)
    info = check_rapid_module(text)
    assert text.isascii() and text.endswith("ENDMODULE\n")
    assert_round_trip(program)
    if "max_moves_per_proc" in overrides:
        n_procs = math.ceil(len(program.targets) / program.max_moves_per_proc)
        assert info.proc_names == ("main", *(f"path_{k + 1}" for k in range(n_procs)))
        calls = [line.strip() for line in text.splitlines() if line.strip().startswith("path_")]
        assert calls == [f"path_{k + 1};" for k in range(n_procs)]


def test_split_keeps_every_move_once_and_in_order() -> None:
    program = make_program(targets=make_targets(7), max_moves_per_proc=3)
    text = rapid_module(program)
    moved = [line.split()[1].rstrip(",") for line in text.splitlines() if "MoveL p" in line]
    assert moved == ["p_retract"] + [f"p{i}" for i in range(1, 8)]  # main comes first
    assert text.index("PROC path_1()") < text.index("MoveL p1,") < text.index("PROC path_2()")


def test_force_control_instructions() -> None:
    fc = ForceControlSettings(10.0, load_name="spindle load")
    text = rapid_module(make_program(force_control=fc, speed_change=SpeedChangeSettings(30.0)))
    body = [line.strip() for line in text.splitlines()]
    assert (
        "PERS loaddata spindle_load := [2.5,[0.0000,0.0000,70.0000],[1,0,0,0],0.001,0.001,0.001];"
        in body
    )
    order = [
        "MoveJ p_approach, v_air, fine, spindle\\WObj:=pump_housing;",
        "WaitTime \\InPos, 0.5;",
        "FCCalib spindle_load;",
        "FCSpdChgTunSet 5, 0.2;",
        "FCSpdChgAct 30;",
        "FCPress1LStart p1, vp5, \\Fy:=10, 90, \\ForceChange:=100, z_path, "
        "spindle\\WObj:=pump_housing;",
        "FCPressL p2, vp5, 10, z_path, spindle\\WObj:=pump_housing;",
        "FCPressL p3, vp7_25, 10, z_path, spindle\\WObj:=pump_housing;",
        "FCSpdChgDeact;",
        "FCPressEnd p_retract, v_air, spindle\\WObj:=pump_housing;",
    ]
    assert [body.index(line) for line in order] == sorted(body.index(line) for line in order)
    assert not any(line.startswith("MoveL") for line in body)


def test_speeds_rounded_half_up_and_named_validly() -> None:
    targets = make_targets(3)
    # 0.01 mm/s: the machining program's feeds (multiples of it) are written exactly.
    speeds = [0.006, 12.125, 12.376]  # 12.125 is exact in binary: half up gives 12.13
    targets = [
        RapidTarget(t.T_wobj_target, t.joints_rad, s) for t, s in zip(targets, speeds, strict=True)
    ]
    text = rapid_module(make_program(targets=targets))
    assert "CONST speeddata vp0_01 := [0.01,500,5000,1000];" in text
    assert "CONST speeddata vp12_13 := [12.13,500,5000,1000];" in text
    assert "CONST speeddata vp12_38 := [12.38,500,5000,1000];" in text
    check_rapid_module(text)


def test_deterministic_byte_identical(tmp_path: Path) -> None:
    a = rapid_module(make_program())
    b = rapid_module(make_program())
    assert a == b
    path = write_rapid_module(make_program(), tmp_path / "program.mod")
    assert path.read_bytes() == a.encode("ascii")


def test_golden_three_target_program() -> None:
    program = make_program(force_control=None)
    text = rapid_module(program)
    golden = GOLDEN_DIR / "rapid_three_targets.mod"
    if UPDATE_GOLDEN:
        golden.parent.mkdir(exist_ok=True)
        golden.write_text(text, encoding="ascii", newline="\n")
    assert text == golden.read_text(encoding="ascii")


# -------------------------------------------------------------------------------------------------
# Numbers, quaternions, confdata


def test_quaternion_sign_convention() -> None:
    np.testing.assert_allclose(rapid_quaternion(np.eye(3)), [1, 0, 0, 0])
    np.testing.assert_allclose(rapid_quaternion(rot((1, 0, 0), math.pi)), [0, 1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rapid_quaternion(rot((1, 0, 0), -math.pi)), [0, 1, 0, 0], atol=1e-12)
    q = rapid_quaternion(rot((0, 0, 1), 1.5 * math.pi))  # w < 0 before the flip
    assert q[0] > 0.0
    np.testing.assert_allclose(matrix_from_quaternion(q), rot((0, 0, 1), 1.5 * math.pi), atol=1e-12)


@pytest.mark.parametrize(
    ("joints_deg", "expected"),
    [
        ((10, -90, 90, 10, 30, 10), (0, 0, 0, 4)),
        ((-10, -90, 90, -10, -30, -10), (-1, -1, -1, 5)),
        ((200, -90, -90, 370, 30, -190), (2, 4, -3, 2)),
        ((90, 0, 30, 0, 30, 0), (1, 0, 0, 4)),
        ((0, -180, 30, 0, 30, 0), (0, 0, 0, 0)),
    ],
)
def test_confdata_quadrants_and_case(joints_deg: tuple[float, ...], expected: tuple) -> None:
    joints = np.radians(joints_deg)
    assert confdata_from_joints(joints) == expected
    assert confdata_from_joints(joints, cfx=3)[3] == 3


def test_cfx_override_is_exported() -> None:
    t = make_targets(1)[0]
    target = RapidTarget(t.T_wobj_target, t.joints_rad, 5.0, cfx=7)
    info = check_rapid_module(rapid_module(make_program(targets=[target])))
    assert info.robtargets["p1"][2][3] == 7


# -------------------------------------------------------------------------------------------------
# Identifiers


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("pump housing", "pump_housing"),
        ("Gehäuse-2", "Geh_use_2"),
        ("3axis", "t_3axis"),
        ("_tool", "t_tool"),
        ("x" * 40, "x" * 32),
        ("PROC", "PROC_"),
        ("endmodule", "endmodule_"),
        ("  spindle ", "spindle"),
    ],
)
def test_identifier_sanitized(name: str, expected: str) -> None:
    out = rapid_identifier(name, prefix="t")
    assert out == expected
    assert out[0].isalpha() and len(out) <= 32


@pytest.mark.parametrize("name", ["", "   ", "!!!", "___", "ÄÖÜ"])
def test_identifier_that_cannot_be_made_valid_raises(name: str) -> None:
    with pytest.raises(InvalidInputError):
        rapid_identifier(name)
    with pytest.raises(InvalidInputError):
        rapid_module(make_program(module_name=name))


def test_sanitized_names_pass_the_checker() -> None:
    program = make_program(
        module_name="1st groove (pump)", tool=make_tool("Ø6 ball cutter"), wobj=make_wobj("x" * 50)
    )
    info = check_rapid_module(rapid_module(program))
    assert info.module_name == "m_1st_groove__pump_"
    assert info.data_types["t_6_ball_cutter"] == "tooldata"
    assert info.data_types["x" * 32] == "wobjdata"


@pytest.mark.parametrize(
    "overrides",
    [
        {"tool": make_tool("P1")},  # RAPID names ignore case
        {"tool": make_tool("v_air")},
        {"tool": make_tool("part"), "wobj": make_wobj("PART")},
        {"wobj": make_wobj("wobj0")},
        {"module_name": "main"},
    ],
)
def test_name_collisions_raise(overrides: dict[str, object]) -> None:
    with pytest.raises(InvalidInputError, match="collides"):
        rapid_module(make_program(**overrides))


# -------------------------------------------------------------------------------------------------
# Input validation


def _bad_rotation() -> np.ndarray:
    T = np.eye(4)
    T[0, 1] = 0.1
    return T


def _reflection() -> np.ndarray:
    T = np.eye(4)
    T[2, 2] = -1.0
    return T


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: make_program(targets=[]), "at least one target"),
        (lambda: RapidTarget(_bad_rotation(), JOINTS, 5.0), "not orthonormal"),
        (lambda: RapidTarget(_reflection(), JOINTS, 5.0), "reflection"),
        (lambda: RapidTarget(np.full((4, 4), np.nan), JOINTS, 5.0), "non-finite"),
        (lambda: RapidTarget(np.eye(3), JOINTS, 5.0), "shape"),
        (lambda: RapidTarget(np.eye(4), JOINTS[:5], 5.0), "shape"),
        (lambda: RapidTarget(np.eye(4), [0, 0, np.inf, 0, 0, 0], 5.0), "finite"),
        (lambda: RapidTarget(np.eye(4), JOINTS, 0.0), "speed_mm_s must be > 0"),
        (lambda: RapidTarget(np.eye(4), JOINTS, -3.0), "speed_mm_s must be > 0"),
        (lambda: RapidTarget(np.eye(4), JOINTS, math.nan), "finite"),
        (lambda: RapidTarget(np.eye(4), JOINTS, 5.0, cfx=8), "cfx"),
        (
            lambda: rapid_module(make_program(targets=[RapidTarget(np.eye(4), JOINTS, 0.004)])),
            "rounds to 0",
        ),
        (lambda: RapidTool("t", np.eye(4), 0.0, np.zeros(3)), "mass_kg must be > 0"),
        (lambda: RapidTool("t", np.eye(4), 1.0, np.zeros(3), np.array([1, -1, 1])), ">= 0"),
        (lambda: RapidWorkObject("w", _bad_rotation()), "not orthonormal"),
        (lambda: ForceControlSettings(0.0), "force_N must be > 0"),
        (lambda: ForceControlSettings(10.0, "w"), "force_direction"),
        (lambda: ForceControlSettings(10.0, force_threshold_percent=150), "threshold"),
        (lambda: SpeedChangeSettings(20.0, speed_levels=1), "speed_levels"),
        (lambda: SpeedChangeSettings(20.0, min_speed_ratio=1.0), "min_speed_ratio"),
        (lambda: make_program(zone_mm=-1.0), "zone_mm"),
        (lambda: make_program(max_moves_per_proc=0), "max_moves_per_proc"),
        (lambda: make_program(approach_speed_mm_s=math.inf), "finite"),
    ],
)
def test_bad_input_raises_clear_error(build: Callable[[], object], match: str) -> None:
    with pytest.raises(InvalidInputError, match=match):
        build()


# -------------------------------------------------------------------------------------------------
# Checker


def _mutate(old: str, new: str, text: str | None = None) -> str:
    text = rapid_module(make_program()) if text is None else text
    assert old in text, old
    return text.replace(old, new, 1)


@pytest.mark.parametrize(
    ("broken", "match"),
    [
        (lambda: _mutate("  ENDPROC\n", ""), "PROC main .* has no ENDPROC"),
        (lambda: _mutate("ENDMODULE\n", ""), "has no ENDMODULE"),
        (lambda: _mutate("MoveL p2,", "MoveL p9,"), "undeclared robtarget 'p9'"),
        (lambda: _mutate("MoveL p2, vp5,", "MoveL p2, vp99,"), "undeclared speeddata 'vp99'"),
        (lambda: _mutate(", z_path,", ", z_nowhere,"), "undeclared zonedata"),
        (lambda: _mutate("z_path, spindle\\WObj", "z_path, spindel\\WObj"), "undeclared tooldata"),
        (
            lambda: _mutate("spindle\\WObj:=pump_housing;", "spindle\\WObj:=table;"),
            "undeclared wobjdata 'table'",
        ),
        (lambda: _mutate("MoveL p2, vp5,", "MoveL vp5, vp5,"), "'vp5' is a speeddata, expected"),
        (
            lambda: _mutate(
                "[0.0000000,1.0000000,0.0000000,0.0000000],[0,-2,0,5]",
                "[0.0000000,0.9900000,0.0000000,0.0000000],[0,-2,0,5]",
            ),
            "quaternion is not normalized",
        ),
        (lambda: _mutate("CONST robtarget p1", "CONST robtarget p" + "1" * 32), "max 32"),
        (lambda: _mutate("PERS wobjdata pump_housing", "PERS wobjdata " + "w" * 33), "max 32"),
        (lambda: _mutate("[0,-2,0,5],[9E9", "[0,-2,0],[9E9"), "wrong arity.*got 3"),
        (lambda: _mutate(":= [5,500,5000,1000];", ":= [5,500,5000];"), "wrong arity"),
        (lambda: _mutate('[FALSE,TRUE,"",', '[FALSE,"",'), "wrong arity"),
        (lambda: _mutate(":= [FALSE,0.5,", ":= [0.5,"), "wrong arity"),
        (
            lambda: _mutate("[[0.0000,20.0000,0.0000]", "[[0.0000,20.0000,0.0000"),
            "unbalanced brackets",
        ),
        (lambda: _mutate("MoveL p2, vp5, z_path", "MoveL p2, vp5), z_path"), "unbalanced brackets"),
        (
            lambda: _mutate("MoveL p2, vp5, z_path, spindle", "MoveL p2, vp5, spindle"),
            "takes 4 positional",
        ),
        (
            lambda: _mutate("    MoveL p2,", "    path_7;\n    MoveL p2,"),
            "PROC 'path_7' is called but not defined",
        ),
        (lambda: _mutate("CONST robtarget p2", "CONST robtarget P1"), "declared twice"),
        (lambda: _mutate("CONST robtarget p2", "CONST robtarget 2p"), "must start with a letter"),
        (lambda: _mutate("CONST robtarget p2", "CONST robtarget _p2"), "must start with a letter"),
        (lambda: _mutate("ENDMODULE\n", "ENDMODULE\nMoveL;\n"), "text after ENDMODULE"),
        (
            lambda: _mutate(
                "MoveL p2, vp5, z_path, spindle\\WObj:=pump_housing;",
                "MoveL p2, vp5, z_path, spindle\\WObj:=pump_housing",
            ),
            "expected ',' or ';'",
        ),
        (lambda: _mutate("CONST robtarget p2", "CONST robtarget PROC"), "reserved word"),
        (lambda: _mutate("[TRUE,[[", "[1,[["), "expected a bool"),
    ],
)
def test_checker_rejects_broken_module(broken: Callable[[], str], match: str) -> None:
    with pytest.raises(RapidSyntaxError, match=match) as info:
        check_rapid_module(broken())
    assert info.value.line >= 1
    assert str(info.value).startswith(f"line {info.value.line}: ")


def test_checker_reports_the_right_line() -> None:
    text = _mutate("MoveL p2,", "MoveL p9,")
    line = next(i for i, s in enumerate(text.splitlines(), 1) if "MoveL p9" in s)
    with pytest.raises(RapidSyntaxError) as info:
        check_rapid_module(text)
    assert info.value.line == line


HAND_WRITTEN = """\
module Deburr(SYSMODULE)
  ! a hand-written variant: lower-case keywords, CRLF, predefined data, control flow
  LOCAL CONST robtarget pHome := [[500,0,600],[0.7071068,0,0.7071068,0],[0,0,0,0],
                                  [9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  PERS tooldata tSpindle := [TRUE,[[0,0,150],[1,0,0,0]],[2.5,[0,0,70],[1,0,0,0],0,0,0]];
  VAR num nPasses := 3;
  CONST string sMsg := "say ""hi"" ! not a comment";

  PROC Main()
    VAR num i;
    ConfJ \\On;
    MoveJ pHome, v1000, z50, tool0;
    FOR i FROM 1 TO nPasses DO
      MoveL Offs(pHome, 0, 0, -10 * i), v100, fine, tSpindle \\WObj:=wobj0;
      IF i = 2 THEN
        TPWrite sMsg;
      ELSEIF i > 2 AND NOT (nPasses < 1) THEN
        Retreat 20;
      ELSE
        WaitTime 0.1;
      ENDIF
    ENDFOR
    WHILE nPasses > 0 DO
      nPasses := nPasses - 1;
    ENDWHILE
    MoveL [[500,0,700],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;
  endproc

  PROC Retreat(num dist_mm)
    MoveL Offs(pHome, 0, 0, dist_mm), v200, z10, tool0;
  ENDPROC
ENDMODULE
"""


def test_checker_accepts_hand_written_variant() -> None:
    info = check_rapid_module(HAND_WRITTEN.replace("\n", "\r\n"))
    assert info.module_name == "Deburr"
    assert info.proc_names == ("Main", "Retreat")
    pos, quat, conf = info.robtargets["pHome"]
    np.testing.assert_allclose(pos, [500, 0, 600])
    np.testing.assert_allclose(quat, [0.7071068, 0, 0.7071068, 0])
    assert conf.tolist() == [0, 0, 0, 0]
    assert info.data_types == {
        "pHome": "robtarget",
        "tSpindle": "tooldata",
        "nPasses": "num",
        "sMsg": "string",
    }


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("MoveJ pHome, v1000", "MoveJ pHom, v1000", "undeclared robtarget 'pHom'"),
        ("Retreat 20;", "Retract 20;", "PROC 'Retract' is called but not defined"),
        ("    ENDFOR\n", "", "unexpected endproc: expected ENDFOR"),
        ("[0.7071068,0,0.7071068,0]", "[0.7,0,0.7,0]", "not normalized"),
        ("FROM 1 TO nPasses", "FROM 1 TO nPass", "undeclared identifier 'nPass'"),
        ("tSpindle \\WObj:=wobj0", "pHome \\WObj:=wobj0", "'pHome' is a robtarget, expected"),
    ],
)
def test_checker_rejects_broken_hand_written(old: str, new: str, match: str) -> None:
    assert old in HAND_WRITTEN
    with pytest.raises(RapidSyntaxError, match=match):
        check_rapid_module(HAND_WRITTEN.replace(old, new, 1))


# -------------------------------------------------------------------------------------------------
# Property: random valid poses and joints


_unit = st.floats(-1.0, 1.0, allow_nan=False)
_coord = st.floats(-2.0, 2.0, allow_nan=False)
_joint = st.floats(-2 * math.pi, 2 * math.pi, allow_nan=False)
_target = st.tuples(
    st.tuples(_unit, _unit, _unit, _unit).filter(lambda q: sum(v * v for v in q) > 1e-2),
    st.tuples(_coord, _coord, _coord),
    st.lists(_joint, min_size=6, max_size=6),
    st.floats(0.06, 500.0, allow_nan=False),
)


@pytest.mark.slow  # 40+ generated modules, the first 10 through rapidchecker (~50 ms per line)
@settings(max_examples=40, deadline=None)
@given(
    raw=st.lists(_target, min_size=1, max_size=6),
    split=st.integers(1, 4),
    with_fc=st.booleans(),
    with_sc=st.booleans(),
)
def test_property_random_targets_pass_and_round_trip(
    raw: list, split: int, with_fc: bool, with_sc: bool
) -> None:
    targets = [
        RapidTarget(pose(matrix_from_quaternion(np.array(q)), p), np.array(j), v)
        for q, p, j, v in raw
    ]
    program = make_program(
        targets=targets,
        max_moves_per_proc=split,
        force_control=ForceControlSettings(15.0) if with_fc else None,
        speed_change=SpeedChangeSettings(40.0) if with_sc else None,
    )
    assert_round_trip(program)


# -------------------------------------------------------------------------------------------------
# Circular moves and the third-party checker


def test_rapidchecker_sees_a_broken_module() -> None:
    """The independent checker is not a rubber stamp: a missing ENDPROC fails it."""
    text = original_text = rapid_export.rapid_module(make_program())
    assert rapidchecker_errors(original_text) == []
    broken = text.replace("  ENDPROC\n", "", 1)
    assert rapidchecker_errors(broken)


def test_robtargets_past_the_grammars_share_are_held_to_their_exact_shape() -> None:
    """tests/rapid_grammar.py gives the grammar the first robtargets only; a later one with a
    number the grammar never saw (nan) or a missing element still fails."""
    text = rapid_export.rapid_module(make_program(targets=make_arc_targets(12)))
    assert rapidchecker_errors(text) == []
    lines = text.splitlines(keepends=True)
    late = [k for k, line in enumerate(lines) if "CONST robtarget" in line][GRAMMAR_ROBTARGETS + 1]
    for broken in (re.sub(r"\[\[-?[\d.]+", "[[nan", lines[late], count=1),
                   lines[late].replace("],[", ",", 1)):  # fmt: skip
        assert broken != lines[late]
        errors = rapidchecker_errors("".join(lines[:late] + [broken] + lines[late + 1 :]))
        assert errors and "expected shape" in errors[0], errors


def make_arc_targets(n: int = 5) -> list[RapidTarget]:
    """Targets on a 20 mm circle in the wobj x-y plane, tool down."""
    down = rot((1, 0, 0), math.pi)
    return [
        RapidTarget(
            pose(down, (0.02 * math.cos(a), 0.02 * math.sin(a), 0.0)), JOINTS + 0.01 * k, 5.0
        )
        for k, a in enumerate(np.linspace(0.0, math.pi, n))
    ]


@pytest.mark.parametrize("force", [None, ForceControlSettings(force_N=12.0)])
def test_circular_moves_emit_movec_and_pass_both_checkers(force) -> None:
    moves = (Move("linear", 0), Move("circular", 2, 1), Move("circular", 4, 3))
    program = make_program(targets=make_arc_targets(), moves=moves, force_control=force)
    text = rapid_module(program)
    info = check_rapid_module(text)
    assert len(info.robtargets) == 5 + 2
    word = "MoveC" if force is None else "FCPressC"
    circular = [line.strip() for line in text.splitlines() if line.strip().startswith(word)]
    assert circular[0].startswith(f"{word} p2, p3, vp5, ")
    assert circular[1].startswith(f"{word} p4, p5, vp5, ")
    assert len(circular) == 2
    if force is not None:
        assert ", 12, z_path," in circular[0]
    assert "7 moves" not in text and "3 moves, 2 of them circular" in text


def test_circular_moves_split_over_procs_in_order() -> None:
    moves = (Move("linear", 0), Move("circular", 2, 1), Move("linear", 3), Move("linear", 4))
    text = rapid_module(make_program(targets=make_arc_targets(), moves=moves, max_moves_per_proc=2))
    check_rapid_module(text)
    motion = [
        line.split()[1].rstrip(",") + ("C" if "MoveC" in line else "")
        for line in text.splitlines()
        if re.match(r"\s*(MoveL|MoveC) p\d", line)
    ]
    assert motion == ["p1", "p2C", "p4", "p5"]
    assert "PROC path_2()" in text


@pytest.mark.parametrize(
    ("moves", "match"),
    [
        ((Move("linear", 1),), "first move must be a linear move to target 0"),
        ((Move("linear", 0), Move("linear", 3), Move("linear", 2)), "targets must advance"),
        ((Move("linear", 0), Move("circular", 2, 2)), "not between"),
        ((Move("linear", 0), Move("linear", 9)), "targets must advance"),
    ],
)
def test_bad_move_sequence_is_a_clear_error(moves: tuple, match: str) -> None:
    with pytest.raises(InvalidInputError, match=match):
        make_program(targets=make_arc_targets(), moves=moves)


def test_move_needs_a_via_exactly_when_circular() -> None:
    with pytest.raises(InvalidInputError, match="via"):
        Move("circular", 2)
    with pytest.raises(InvalidInputError, match="via"):
        Move("linear", 2, 1)


def test_confdata_follows_the_arm_and_unknown_arms_are_refused() -> None:
    """On an ABB arm the wrist geometry gives cfx: IRB 4400 calibration pose -> [0,0,0,0]."""
    target = RapidTarget(make_targets(1)[0].T_wobj_target, np.zeros(6), 5.0)
    info = check_rapid_module(rapid_module(make_program(targets=[target], arm="irb4400")))
    assert tuple(info.robtargets["p1"][2]) == (0, 0, 0, 0)
    assert confdata_from_joints(np.zeros(6))[3] == 4  # the UR rule calls the same joints 4
    with pytest.raises(InvalidInputError, match="unknown arm 'kuka'"):
        make_program(arm="kuka")
