"""Fuzzing: schemathesis against the live app's own OpenAPI schema (issue 10, "In CI").

A real ``robomach serve`` on a fresh data folder gets requests generated from
``/openapi.json``, valid ones (positive) and invalid ones (negative: wrong types, values out of
range, missing fields), for every operation. Each response is checked for a server error (any
status >= 500) and against the response schema the route declares. Jobs that a request starts
are cancelled at once, so the run stays short and the next request finds the robot free. The
requests are drawn from a fresh seed each run, named on a failure (``ROBOMACH_SEED`` replays
it).
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

schemathesis = pytest.importorskip("schemathesis")  # in the "test" extra
requests = pytest.importorskip("requests")  # a dependency of schemathesis

from hypothesis import HealthCheck, Phase, Verbosity, given, seed, settings  # noqa: E402
from hypothesis.errors import Unsatisfiable  # noqa: E402
from schemathesis import GenerationMode  # noqa: E402
from schemathesis.checks import not_a_server_error  # noqa: E402
from schemathesis.core.failures import FailureGroup  # noqa: E402
from schemathesis.specs.openapi.checks import response_schema_conformance  # noqa: E402

from tests.api.server_process import POLL_S, ServerProcess, start_server  # noqa: E402
from tests.envelope import replay, run_seed  # noqa: E402

pytestmark = pytest.mark.slow

MIN_REQUESTS = 1000
EXAMPLES_PER_MODE = 15  # an operation with parameters gets up to this many of each mode
REQUEST_TIMEOUT_S = 30.0
CHECKS = [not_a_server_error, response_schema_conformance]
EVENT_STREAM = "/api/events"
SEED = run_seed()


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServerProcess]:
    data: Path = tmp_path_factory.mktemp("fuzz") / "data"
    # Unpaced: a generated push or touch-off of seconds would otherwise take those seconds.
    proc = start_server(data, env={"ROBOMACH_REAL_TIME": "0"})
    yield proc
    code = proc.stop(kill_on_timeout=True)
    assert code in (0, 130), proc.log()[-5000:]


def cancel_started_job(http: requests.Session, base_url: str, response: requests.Response):
    """A 202 starts a job: cancel it and wait until it ends (the robot is free again)."""
    if response.status_code != 202:
        return
    job_id = response.json().get("job_id")
    if not job_id:
        return
    http.post(f"{base_url}/api/jobs/{job_id}/cancel", timeout=REQUEST_TIMEOUT_S)
    deadline = time.monotonic() + REQUEST_TIMEOUT_S
    while time.monotonic() < deadline:
        job = http.get(f"{base_url}/api/jobs/{job_id}", timeout=REQUEST_TIMEOUT_S).json()
        if job.get("status") not in ("queued", "running"):
            return
        time.sleep(POLL_S)


def check_event_stream(base_url: str, http: requests.Session) -> int:
    """``GET /api/events`` answers with a stream that starts with its retry and hello events.
    Read whole as the fuzzer reads every answer, it waited 30 s for the read timeout."""
    with http.get(f"{base_url}{EVENT_STREAM}", stream=True, timeout=REQUEST_TIMEOUT_S) as r:
        assert r.status_code == 200, r.text
        assert r.headers["content-type"].startswith("text/event-stream"), r.headers
        lines = r.iter_lines(decode_unicode=True)
        assert next(lines).startswith("retry:")
        assert "hello" in "".join(next(lines) for _ in range(3))
        return r.status_code


def fuzz_operation(
    operation, mode: GenerationMode, base_url: str, http: requests.Session
) -> tuple[Counter[int], list[str]]:
    """Send ``EXAMPLES_PER_MODE`` generated requests of ``mode``; returns the statuses seen
    and the failed checks."""
    label = f"{operation.method.upper()} {operation.path} ({mode.value})"
    statuses: Counter[int] = Counter()
    failures: list[str] = []

    @settings(
        max_examples=EXAMPLES_PER_MODE,
        deadline=None,
        database=None,
        phases=[Phase.explicit, Phase.generate],
        suppress_health_check=list(HealthCheck),
        verbosity=Verbosity.quiet,
    )
    @seed(SEED)
    @given(case=operation.as_strategy(generation_mode=mode))
    def call(case) -> None:
        response = case.call(base_url=base_url, session=http, timeout=REQUEST_TIMEOUT_S)
        statuses[response.status_code] += 1
        try:
            case.validate_response(response, checks=CHECKS)
        except (AssertionError, FailureGroup) as exc:
            failures.append(f"{label} -> {response.status_code}: {exc}")
        cancel_started_job(http, base_url, response)

    try:
        call()
    except Unsatisfiable:
        pass  # no invalid request exists (an operation without parameters)
    return statuses, failures


def test_generated_requests_get_no_server_error_and_match_the_schema(server):
    schema = schemathesis.openapi.from_url(f"{server.base_url}/openapi.json")
    http = requests.Session()
    statuses: Counter[int] = Counter()
    failures: list[str] = []
    operations = [result.ok() for result in schema.get_all_operations()]
    for operation in operations:
        if operation.path == EVENT_STREAM:  # no parameters to fuzz, and a body that never ends
            statuses[check_event_stream(server.base_url, http)] += 1
            continue
        for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE):
            seen, failed = fuzz_operation(operation, mode, server.base_url, http)
            statuses += seen
            failures += failed

    total = sum(statuses.values())
    summary = (
        f"{replay(SEED)}: {total} requests over {len(operations)} operations, "
        f"statuses {dict(statuses)}"
    )
    print(summary)
    assert total >= MIN_REQUESTS, summary
    assert not failures, f"{len(failures)} failures ({summary}):\n" + "\n\n".join(failures[:10])
    assert "Traceback" not in server.log(), server.log()[-5000:]
