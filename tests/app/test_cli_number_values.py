"""A point or a work object typed as a person types it (issue 31, point 8): negative numbers
first ("-12.5,3,4" is an option to argparse), spaces, brackets, with "=" or without, over
generated values (a fresh seed each run; ``ROBOMACH_SEED`` replays one)."""

from __future__ import annotations

import numpy as np
import pytest

from app.cli import build_parser, join_number_values
from app.commands.demo import _point_mm
from robomach_core.errors import InvalidInputError
from tests.envelope import replay, run_seed

SEED = run_seed()


def _forms(values: list[float], option: str) -> list[list[str]]:
    text = [f"{v:g}" for v in values]
    return [
        [option, ",".join(text)],
        [option, *text],
        [option, f"({', '.join(text)})"],
        [option, f"[{'; '.join(text)}]"],
        [f"{option}={','.join(text)}"],
        [option, " ".join(text)],  # one quoted argument
    ]


def _parsed(argv: list[str]):
    return build_parser().parse_args(
        ["demo", "--out", "x", *join_number_values(argv), "--seed", "3"]
    )


def test_a_point_is_read_in_every_form_a_person_types():
    rng = np.random.default_rng(SEED)
    for _ in range(20):
        point = [round(float(v), int(rng.integers(0, 4))) for v in rng.uniform(-200, 200, 3)]
        point[0] = -abs(point[0]) or -1.0  # a negative first number: argparse's trap
        for argv in _forms(point, "--propose-guide-points"):
            args = _parsed(argv)
            got = np.array(_point_mm(args.propose_guide_points, "--propose-guide-points")) * 1e3
            assert got == pytest.approx(point), f"{replay(SEED)}: {argv}"
            assert args.seed == 3


def test_a_work_object_is_read_in_every_form_with_three_four_or_six_numbers():
    rng = np.random.default_rng([SEED, 1])
    for n in (3, 4, 6):
        wobj = [round(float(v), 2) for v in rng.uniform(-300, 300, n)]
        wobj[0] = -abs(wobj[0])
        for argv in _forms(wobj, "--wobj"):
            got = [float(v) for v in _parsed(argv).wobj.split(",")]
            assert got == pytest.approx(wobj), f"{replay(SEED)}: {argv}"


@pytest.mark.parametrize(
    "text, said",
    [("-12.5,3", "got 2"), ("a,b,c", "expected three numbers"), ("1,,", "got 1")],
)
def test_a_point_that_is_not_three_numbers_says_so(text, said):
    with pytest.raises(InvalidInputError, match=said):
        _point_mm(text, "--propose-guide-points")
