"""Bad numbers and bad output folders on the command line: one line and exit 2, never a
traceback, and nothing run before the check (issue 10, items 3 and 10).

The generated values come from outside each argument's range in ``robomach_core.limits``, so
validation must refuse every one of them before any simulation starts: a value that slipped
through would run a whole pipeline (slow) and then fail the assertion.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from app.cli import main
from robomach_core import limits
from robomach_core.limits import Range

EXTREMES = (math.nan, math.inf, -math.inf, 1e308, 1e200, 1e-300, 1e-6, 1.4e-45, -1.0, 0.0)

# (command, flag, range, fixed arguments)
NUMERIC_ARGUMENTS = (
    ("demo", "--tolerance", limits.TOLERANCE_MM, ()),
    ("demo", "--force", limits.LEARNING_FORCE_N, ()),
    ("demo", "--speed", limits.LEARNING_SPEED_MM_S, ()),
    ("demo", "--seed", limits.SEED, ()),
    ("cmrr", "--seed", limits.SEED, ("--scenario", "lund-df")),
    ("cmrr", "--reference-force-N", limits.CMRR_REFERENCE_FORCE_N, ("--scenario", "lund-df")),
    ("cmrr", "--command-speed-mm-s", limits.CMRR_COMMAND_SPEED_MM_S, ("--scenario", "lund-df")),
    ("compensate", "--seed", limits.SEED, ("--quick",)),
    ("compensate", "--cmm-noise", limits.CMM_NOISE_UM, ("--quick",)),
    ("compensate", "--poses", limits.IDENTIFICATION_POSES, ("--quick",)),
    ("compensate", "--iterations", limits.ILC_ITERATIONS, ("--quick",)),
    ("serve", "--port", limits.PORT, ()),
    ("serve", "--viser-port", limits.PORT, ()),
    ("demo", "--wobj", limits.WOBJ_POSITION_MM, ()),  # x of x,y,z
)
FAST = settings(
    max_examples=80,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def outside(rng: Range) -> st.SearchStrategy[str]:
    """Command-line spellings of numbers outside ``rng`` (ints for integer ranges)."""
    if rng.integer:
        low, high = int(rng.min), int(rng.max)
        numbers = st.one_of(
            st.integers(min_value=-(10**30), max_value=low - 1),
            st.integers(min_value=high + 1, max_value=10**30),
        )
        return numbers.map(str)
    numbers = st.one_of(
        st.sampled_from(EXTREMES),
        st.floats(max_value=rng.min, exclude_max=True),
        st.floats(min_value=rng.max, exclude_min=True),
    ).filter(lambda v: v not in rng)
    return numbers.map(repr)


def _one_line_error(capsys: pytest.CaptureFixture, code: int, command: str, *words: str) -> str:
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"robomach {command}: error:"), lines[0]
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


@FAST
@given(data=st.data())
@example(data=None)  # the issue's own cases first (see below)
def test_every_numeric_argument_outside_its_range_is_one_line(data, tmp_path, capsys):
    if data is None:
        cases = [
            ("demo", "--tolerance", limits.TOLERANCE_MM, (), "1e+308"),
            ("demo", "--tolerance", limits.TOLERANCE_MM, (), "1e+200"),
            ("demo", "--seed", limits.SEED, (), "-1"),
            ("cmrr", "--seed", limits.SEED, ("--scenario", "lund-df"), "-1"),
            ("compensate", "--seed", limits.SEED, ("--quick",), "-1"),
            ("cmrr", "--reference-force-N", limits.CMRR_REFERENCE_FORCE_N,
             ("--scenario", "lund-df"), "1e+308"),
            ("cmrr", "--reference-force-N", limits.CMRR_REFERENCE_FORCE_N,
             ("--scenario", "lund-df"), "1e-300"),
            ("cmrr", "--command-speed-mm-s", limits.CMRR_COMMAND_SPEED_MM_S,
             ("--scenario", "lund-df"), "1e-06"),
        ]  # fmt: skip
    else:
        command, flag, rng, fixed = data.draw(st.sampled_from(NUMERIC_ARGUMENTS))
        value = data.draw(outside(rng))
        cases = [(command, flag, rng, fixed, f"{value},160,0" if flag == "--wobj" else value)]
    out = tmp_path / "out"
    for command, flag, rng, fixed, value in cases:
        where = [] if command == "serve" else ["--out", str(out)]
        code = main([command, *fixed, *where, f"{flag}={value}"])
        _one_line_error(capsys, code, command, flag, rng.text())
        assert not (out / "summary.json").exists() and not (out / "cmrr.csv").exists()


CMRR_SETTINGS = {
    "format": "robomach-cmrr-settings",
    "version": 1,
    "controller": "adaptive-lq",
    "reference_force_N": 20.0,
    "command_speed_mm_s": 40.0,
    "min_speed_ratio": 0.05,
    "feedback": "force",
}


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        ("reference_force_N", 1e308, ["reference_force_N", "1-1000 N"]),
        ("reference_force_N", 1e-300, ["reference_force_N", "1-1000 N"]),
        ("command_speed_mm_s", 1e-6, ["command_speed_mm_s", "1-500 mm/s"]),
        ("command_speed_mm_s", 1e308, ["command_speed_mm_s", "1-500 mm/s"]),
        ("min_speed_ratio", 1.4e-45, ["min_speed_ratio", "0.01-0.99"]),
        ("reference_force_N", 10**400, ["reference_force_N"]),
    ],
)
def test_cmrr_settings_file_out_of_range_is_one_line(tmp_path, capsys, key, value, words):
    path = tmp_path / "cmrr_settings.json"
    path.write_text(json.dumps({**CMRR_SETTINGS, key: value}))
    code = main(["cmrr", "--scenario", "lund-df", "--settings", str(path), "--out", str(tmp_path)])
    _one_line_error(capsys, code, "cmrr", *words)


def test_cmrr_study_too_long_to_simulate_is_refused_before_it_runs(tmp_path, capsys):
    # 1 mm/s is a valid feed, but all six controllers on the Lund cut at 5 % of it would
    # simulate ~15 M samples.
    code = main(
        ["cmrr", "--scenario", "lund-df", "--controller", "all", "--command-speed-mm-s", "1",
         "--out", str(tmp_path / "o")]
    )  # fmt: skip
    _one_line_error(capsys, code, "cmrr", "control samples", "3,000,000")
    assert not (tmp_path / "o").exists()


def _a_file(tmp_path: Path) -> Path:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    return blocker


@pytest.mark.parametrize(
    ("command", "fixed"),
    [("demo", ()), ("compensate", ("--quick",)), ("cmrr", ("--scenario", "milling-steps"))],
)
@pytest.mark.parametrize("where", ["under-a-file", "the-file", "proc"])
def test_out_that_cannot_be_written_is_refused_before_any_work(
    tmp_path, capsys, command, fixed, where
):
    out = {
        "under-a-file": _a_file(tmp_path) / "out",
        "the-file": _a_file(tmp_path),
        "proc": Path("/proc/robomach-out"),
    }[where]
    code = main([command, *fixed, "--out", str(out)])
    _one_line_error(capsys, code, command, "--out", str(out))


def test_compensate_unknown_robot_is_one_line(tmp_path, capsys):
    code = main(["compensate", "--quick", "--robot", "kuka", "--out", str(tmp_path / "o")])
    _one_line_error(capsys, code, "compensate", "unknown robot", "ur10")


def test_an_arm_too_small_for_the_part_says_to_place_it_nearer(tmp_path: Path, capsys) -> None:
    """The UR3 (500 mm reach) cannot reach the water pump where the UR10 has it: one line that
    names the limit and the way out (--wobj), exit 2, no traceback, no files."""
    code = main(["demo", "--robot", "ur3", "--out", str(tmp_path / "out"), "--no-plot"])
    err = capsys.readouterr().err
    assert code == 2
    assert "edge of reach" in err and "--wobj" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "program.mod").exists()
