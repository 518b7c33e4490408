"""The CSV tables are the text ``np.savetxt`` writes for them, byte for byte (``export.tables``
formats blocks of rows at once, savetxt formats row by row)."""

from __future__ import annotations

import io

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.export.tables import CSV_BLOCK_ROWS, _csv_text

FORMATS = ["%.3f", "%.5f", "%.7f", "%d", "%.2f"]


def _savetxt(table: np.ndarray, fmt: list[str], columns: list[str]) -> str:
    buf = io.StringIO()
    np.savetxt(buf, table, fmt=fmt, delimiter=",", header=",".join(columns), comments="")
    return buf.getvalue()


@settings(max_examples=25, deadline=None)
@given(
    rows=st.sampled_from([0, 1, 2, CSV_BLOCK_ROWS - 1, CSV_BLOCK_ROWS, CSV_BLOCK_ROWS + 3]),
    fmt=st.lists(st.sampled_from(FORMATS), min_size=1, max_size=8),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_csv_text_is_savetxts(rows: int, fmt: list[str], seed: int) -> None:
    rng = np.random.default_rng(seed)
    table = rng.normal(0.0, 10.0 ** rng.uniform(-6, 4), (rows, len(fmt)))
    table[rng.random(table.shape) < 0.05] = 0.5  # a tie of the rounding
    table[rng.random(table.shape) < 0.05] = -0.0
    for j, f in enumerate(fmt):
        if f != "%d" and rows:  # "%d" truncates a float alike; it refuses nan in both
            table[rng.integers(rows), j] = rng.choice([np.nan, np.inf, -np.inf, -1e-9])
    columns = [f"c{j}" for j in range(len(fmt))]
    assert _csv_text(table, fmt, columns) == _savetxt(table, fmt, columns)
