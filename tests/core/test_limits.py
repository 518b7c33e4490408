"""The ranges of robomach_core.limits: membership, messages, odd inputs."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robomach_core import limits
from robomach_core.errors import InvalidInputError
from robomach_core.limits import Range

RANGES = [v for v in vars(limits).values() if isinstance(v, Range)]


@given(rng=st.sampled_from(RANGES), value=st.one_of(st.floats(), st.integers()))
def test_check_accepts_exactly_the_members(rng: Range, value: float) -> None:
    inside = (
        not (isinstance(value, float) and math.isnan(value))
        and rng.min <= value <= rng.max
        and (not rng.integer or float(value).is_integer())
    )
    assert (value in rng) == inside
    if inside:
        assert rng.check(value) == value
    else:
        with pytest.raises(InvalidInputError, match=re.escape(f"within {rng.text()}")):
            rng.check(value)


@pytest.mark.parametrize("odd", [None, "5", True, [1], 10**400, -(10**400), math.inf, math.nan])
def test_odd_values_are_refused_with_the_range(odd: object) -> None:
    with pytest.raises(InvalidInputError, match="--seed must be an integer within 0-4294967295"):
        limits.SEED.check(odd, "--seed")


def test_numpy_numbers_count_and_come_back_as_python_numbers() -> None:
    assert type(limits.SEED.check(np.int64(7))) is int
    assert type(limits.TOLERANCE_MM.check(np.float64(0.2))) is float


def test_texts() -> None:
    assert limits.LEARNING_FORCE_N.text() == "1-50 N"
    assert limits.WOBJ_ROTATION_DEG.text() == "-360 to 360 deg"
    assert limits.PORT.text() == "1-65535"
