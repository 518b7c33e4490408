"""Long work and many readers: a project holding a dense recording, written into a data folder
before ``robomach serve`` starts on it, and concurrent HTTP readers that time every answer (for
tests/api/test_reads_during_work.py and benchmarks/bench_reads_during_postprocess.py).

A recording learned at 0.5 mm/s (the lowest learning speed; ~311k samples on the water pump)
takes minutes to simulate. The same path learned at 5 or 10 mm/s (seconds) and resampled
``factor`` times denser is what a run at speed/``factor`` records: the same contour, samples
4 ms apart, ``factor`` times closer along the path.
"""

from __future__ import annotations

import asyncio
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np

from app.session import Session
from app.session.persistence import save_kwargs
from app.store import Store
from robomach_core.learning.run import Recording
from tests.jobs import done

CONTROL_PERIOD_S = 0.004
LEARNING_FORCE_N = 10.0
JOB_TIMEOUT_S = 300.0


def densify(recording: Recording, factor: int) -> Recording:
    """``recording`` with ``factor`` times as many samples, 4 ms apart: the same path traversed
    ``factor`` times slower. Measured values are interpolated linearly between the samples
    (orientations and Yp renormalized); flags and segment indexes are held from the previous
    sample."""
    n = len(recording)
    m = (n - 1) * factor + 1
    s = np.arange(m) / factor  # fractional index into the original samples
    i0 = np.minimum(np.floor(s).astype(int), n - 2)
    w = (s - i0)[:, None]

    def lerp(a: np.ndarray) -> np.ndarray:
        a2 = a.reshape(n, -1).astype(float)
        return (a2[i0] * (1.0 - w) + a2[i0 + 1] * w).reshape((m, *a.shape[1:]))

    def unit(a: np.ndarray) -> np.ndarray:
        return a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-12)

    held = np.floor(s).astype(int)
    return replace(
        recording,
        time_s=np.arange(m) * CONTROL_PERIOD_S,
        joints_rad=lerp(recording.joints_rad),
        position_m=lerp(recording.position_m),
        quaternion_wxyz=unit(lerp(recording.quaternion_wxyz)),
        wrench_sensor=lerp(recording.wrench_sensor),
        wrench_tool=lerp(recording.wrench_tool),
        force_normal_N=lerp(recording.force_normal_N),
        force_reference_N=lerp(recording.force_reference_N),
        in_contact=recording.in_contact[held],
        yp=unit(lerp(recording.yp)),
        segment=recording.segment[held],
    )


def write_dense_project(data_dir: Path, *, speed_mm_s: float = 5.0, factor: int = 10) -> int:
    """Make the project ``robomach serve`` opens in ``data_dir`` (default cell: UR10 + water
    pump) hold the example guide points and a recording learned at ``speed_mm_s``, ``factor``
    times densified (as if learned at speed/``factor``), not post-processed yet. Returns its
    number of samples (~31k x ``factor`` at 5 mm/s, ~15.6k x ``factor`` at 10 mm/s)."""
    data_dir.mkdir(parents=True, exist_ok=True)
    session = Session(Store.in_data_dir(data_dir), data_dir=data_dir)
    try:
        done(session, session.learning.start_example(), JOB_TIMEOUT_S)
        done(
            session,
            session.learning.start_path_learning(LEARNING_FORCE_N, speed_mm_s * 1e-3),
            JOB_TIMEOUT_S,
        )
        project = session.project()
        learned = project.learned
        dense = replace(
            learned,
            recording=densify(learned.recording, factor),
            settings=replace(learned.settings, speed_m_s=learned.settings.speed_m_s / factor),
        )
        project = replace(project, learned=dense, processed=None)
        session.store.save(
            session.current_project().id, **save_kwargs(project, "recording", "post")
        )
        return len(dense.recording)
    finally:
        session.close()


@dataclass(frozen=True)
class Answer:
    """One timed GET: its path, HTTP status, and when it was sent and answered
    (``time.perf_counter`` [s])."""

    path: str
    status: int
    sent_s: float
    answered_s: float

    @property
    def latency_ms(self) -> float:
        return (self.answered_s - self.sent_s) * 1e3


class Readers:
    """``clients`` keep-alive connections, each sending GET ``paths`` in turn every
    ``period_s`` (0: back to back, so ``clients`` requests are always in flight), their starts
    spread over one period, until the context exits. One asyncio loop in a thread serves them
    all (no client thread waits for the interpreter lock before it can stop its clock); every
    answer lands in ``answers``."""

    def __init__(
        self, base_url: str, paths: tuple[str, ...], *, clients: int, period_s: float = 0.0
    ) -> None:
        parts = urlsplit(base_url)
        self.host, self.port = parts.hostname, parts.port
        self.paths, self.clients, self.period_s = paths, clients, period_s
        self.answers: list[Answer] = []
        self.failures: list[str] = []
        self._stop = False
        self._ready = threading.Event()
        self._connected = 0
        self._thread = threading.Thread(target=lambda: asyncio.run(self._main()), daemon=True)

    def __enter__(self) -> Readers:
        self._thread.start()
        if not self._ready.wait(30):
            raise RuntimeError(f"the readers did not connect: {self.failures[:3]}")
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop = True
        self._thread.join(60)

    def between(self, start_s: float, end_s: float, path: str) -> list[Answer]:
        """The answers to ``path`` sent at or after ``start_s`` and answered by ``end_s``."""
        return [
            a
            for a in list(self.answers)
            if a.path == path and a.sent_s >= start_s and a.answered_s <= end_s
        ]

    async def _main(self) -> None:
        await asyncio.gather(*(self._client(k) for k in range(self.clients)))

    async def _get(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, path: str):
        writer.write(f"GET {path} HTTP/1.1\r\nHost: {self.host}:{self.port}\r\n\r\n".encode())
        head = await reader.readuntil(b"\r\n\r\n")
        status = int(head.split(b" ", 2)[1])
        length = 0
        for line in head.split(b"\r\n"):
            if line.lower().startswith(b"content-length:"):
                length = int(line.split(b":", 1)[1])
        return status, await reader.readexactly(length)

    async def _client(self, k: int) -> None:
        try:
            reader, writer = await asyncio.open_connection(self.host, self.port)
        except OSError as exc:
            self.failures.append(f"connect: {exc}")
            return
        self._connected += 1
        if self._connected == self.clients:
            self._ready.set()
        await asyncio.sleep(self.period_s * k / self.clients)
        loop = asyncio.get_running_loop()
        next_s = loop.time()
        try:
            while not self._stop:
                for path in self.paths:
                    t = time.perf_counter()
                    status, body = await self._get(reader, writer, path)
                    self.answers.append(Answer(path, status, t, time.perf_counter()))
                    if status != 200:
                        self.failures.append(f"{path}: {status} {body[:200]!r}")
                next_s += self.period_s
                await asyncio.sleep(max(0.0, next_s - loop.time()))
        except (OSError, ValueError, asyncio.IncompleteReadError) as exc:
            self.failures.append(f"connection lost or bad answer: {exc!r}")
        finally:
            writer.close()


def percentiles_ms(answers: list[Answer]) -> tuple[float, float, float]:
    """p50, p99 and max latency [ms] of ``answers`` (NaN when there are none)."""
    if not answers:
        return float("nan"), float("nan"), float("nan")
    ms = [a.latency_ms for a in answers]
    p50, p99 = np.percentile(ms, [50, 99])
    return float(p50), float(p99), max(ms)


def longest_silence_s(answers: list[Answer], start_s: float, end_s: float) -> float:
    """The longest stretch of [start_s, end_s] in which none of ``answers`` came back [s]."""
    times = sorted([start_s, *(a.answered_s for a in answers), end_s])
    return max(np.diff(times)) if len(times) > 1 else end_s - start_s
