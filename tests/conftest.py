"""Per-test time limits: the default (``timeout`` in pyproject.toml) for every test, a longer
one for tests marked ``slow`` (full demo runs, browsers, paced servers). A test that hangs fails
with its stack instead of holding the suite until CI's own limit; a test's own
``@pytest.mark.timeout`` wins.

Timing asserts do not belong here: speed figures are measured in ``benchmarks/``, and tests
assert behaviour that holds on a loaded machine too.

Also the run's folder of shared ``robomach demo`` outputs (tests/demo_project.py): made when
the run starts, before any pytest-xdist worker (they inherit it), removed when it ends; and the
app fixtures: ``client`` (the app on a fresh Session, in process) and ``app_client`` to build
one with other settings or a project of a test's own.
"""

from __future__ import annotations

import gc
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests import demo_project

# A full demo run takes about a minute on an idle 2-core machine, three on a loaded one; a slow
# test may start a session fixture of several (a server, a browser, a demo folder).
SLOW_TIMEOUT_S = 900
_OWN_DEMOS = pytest.StashKey[object]()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("slow") and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(SLOW_TIMEOUT_S))


def pytest_collection_finish(session: pytest.Session) -> None:
    # The collected modules and items and the libraries they imported live as long as the run:
    # out of the full collections, which walked all of them (250k objects, 0.15 s a
    # collection) at each cell change of an in-process session (``give_back``): 3.0 of
    # test_view_the_part_frames_it_with_the_arm_out_of_the_way's 7 s, 0.8 s once frozen.
    # Collected first: garbage frozen would never be freed. (The app's lifespan freezes a
    # server's startup heap the same way; here it held only once a test had started an app.)
    gc.collect()
    gc.freeze()


def _is_worker(config: pytest.Config) -> bool:
    return hasattr(config, "workerinput")  # a pytest-xdist worker; its controller owns the run


def pytest_configure(config: pytest.Config) -> None:
    if not _is_worker(config) and demo_project.FOLDER_VARIABLE not in os.environ:
        config.stash[_OWN_DEMOS] = demo_project.demos_root()
    if _is_worker(config) and "numba" not in sys.modules:
        # Each worker its own numba cache (its subprocesses share it): two workers compiling
        # the same kernel at once wrote its cache index and data as two files, and a cold run
        # twice read one worker's index with the other's data ("NRT_adapt_ndarray_to_python:
        # 'descr' is NULL" in test_kernels; numba issue 10128). Kept between runs.
        base = Path(os.environ.get("NUMBA_CACHE_DIR") or Path(__file__).parents[1] / ".numba-cache")
        os.environ["NUMBA_CACHE_DIR"] = str(base / config.workerinput["workerid"])


def pytest_unconfigure(config: pytest.Config) -> None:
    if config.stash.get(_OWN_DEMOS, None) is not None:
        demo_project.remove_demos_root()


@pytest.fixture(scope="session", autouse=True)
def _no_server_variables() -> Iterator[None]:
    """The server's ``ROBOMACH_*`` variables of the shell running the tests are not theirs
    (``ServerSettings`` reads them): a test sets the ones it means (``monkeypatch.setenv``)."""
    from app.settings import ServerSettings

    names = ["ROBOMACH_DATA"] + [f"ROBOMACH_{f.upper()}" for f in ServerSettings.model_fields]
    with pytest.MonkeyPatch.context() as mp:
        for name in names:
            mp.delenv(name, raising=False)
        yield


@contextmanager
def app_client(session=None, settings=None, **client_options) -> Iterator:
    """A ``TestClient`` on ``create_app`` over ``session`` (a fresh unpaced one by default) with
    ``settings`` (no viser server by default); the app's lifespan closes the session."""
    from fastapi.testclient import TestClient

    from app.api.app import create_app
    from app.session import Session
    from app.settings import ServerSettings

    app = create_app(
        Session(real_time=False) if session is None else session,
        ServerSettings(viser_port=None) if settings is None else settings,
    )
    with TestClient(app, **client_options) as client:
        yield client


@pytest.fixture
def client() -> Iterator:
    """The app on a fresh, unpaced Session, in process; a server error is a 500 response."""
    with app_client(raise_server_exceptions=False) as c:
        yield c
