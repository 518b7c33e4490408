"""Per-test time limits: the default (``timeout`` in pyproject.toml) for every test, a longer
one for tests marked ``slow`` (full demo runs, browsers, paced servers). A test that hangs fails
with its stack instead of holding the suite until CI's own limit; a test's own
``@pytest.mark.timeout`` wins.

Timing asserts do not belong here: speed figures are measured in ``benchmarks/``, and tests
assert behaviour that holds on a loaded machine too.
"""

from __future__ import annotations

import pytest

# A full demo run takes about a minute on an idle 2-core machine, three on a loaded one; a slow
# test may start a session fixture of several (a server, a browser, a demo folder).
SLOW_TIMEOUT_S = 900


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("slow") and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(SLOW_TIMEOUT_S))
