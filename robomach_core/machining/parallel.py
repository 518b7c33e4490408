"""Run many machining cuts at once: a process pool on the local cores, or a Dask cluster.

PROBLEM   A sweep over the stock's variation is hundreds of independent cuts of a second or
          two each (embarrassingly parallel); a thread cannot run two (the cut is Python).
STRATEGY  One task is one controller on one stock: its compensation modes in order (off,
          then offline rehearsed from the off run, then online), so a task needs nothing from
          another. Tasks carry only plain values (the arm's name and TCP, targets, stock,
          settings, identified stiffness), each worker builds the arm once. Locally they go to
          a ``ProcessPoolExecutor`` (workers forked from a forkserver that imported the cut's
          modules once: safe beside the server's threads, and quick to start); with a
          cluster address to a Dask ``distributed.Client`` (Dask rather than Ray: a pure-Python
          wheel, a LocalCluster that starts in a second or two on two cores, and futures that
          map one to one onto ``concurrent.futures``). The same task function runs in both, so
          the results are the same numbers.
SOLUTION  ``run_tasks`` returns the tasks' results in order; progress counts finished tasks,
          cancel stops the pool (or the cluster's futures) and raises ``CancelledError``; an
          interrupt stops the workers too, and each worker ends with the process that started
          the pool (``lifetime.end_with``), even when that one is killed.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import socket
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import CancelledError, InvalidInputError
from ..postprocess import Targets
from .settings import MachiningSettings
from .stock import Stock

# Seconds between two looks at the cancel flag while tasks run.
POLL_S = 0.2
# What a Dask scheduler's address has to answer within, and its handshake's largest length.
CLUSTER_TIMEOUT_S = 10.0
MAX_HANDSHAKE_BYTES = 1 << 20
_ROBOTS: dict[tuple[str, bytes], Any] = {}


@dataclass(frozen=True, eq=False)
class CutTask:
    """One controller's compensation modes on one stock (picklable).

    Attributes:
        robot_name: The arm; ``T_flange_tcp`` (4, 4) its tool.
        targets, wall_normals_m, stock, settings: as ``run_machining`` takes them.
        controller: The controller; ``compensations`` its modes, run in order.
        model: The identified stiffness (``JointCompliance``) or None.
        keep_runs: Return the ``MachiningRun`` values (traces) too, not only the summaries.
        program_frame: The work object the program files write positions in (``run_machining``).
        corrected: (program, its nominal targets, its feed ``run.FeedSource``) of an offline
            correction planned on another stock: the offline mode cuts it instead of
            rehearsing (a sweep over castings).
    """

    robot_name: str
    T_flange_tcp: np.ndarray
    targets: Targets
    wall_normals_m: np.ndarray | None
    stock: Stock
    settings: MachiningSettings
    controller: str
    compensations: tuple[str, ...]
    model: Any = None
    keep_runs: bool = False
    program_frame: np.ndarray | None = None
    corrected: Any = None


def _robot(name: str, T: np.ndarray):
    from ..cell import Robot

    key = (name, np.asarray(T, dtype=float).tobytes())
    robot = _ROBOTS.get(key)
    if robot is None:
        robot = _ROBOTS[key] = Robot(name, np.asarray(T, dtype=float))
    return robot


def run_cut_task(
    task: CutTask, cancel: Any = None
) -> list[tuple[Any, dict[str, Any] | None, str | None]]:
    """The task's cuts: per compensation (run or None, summary or None, refusal or None)."""
    from .compare import run_configuration

    robot = _robot(task.robot_name, task.T_flange_tcp)
    out: list[tuple[Any, dict[str, Any] | None, str | None]] = []
    for mode in task.compensations:
        try:
            run = run_configuration(
                robot, task.targets, task.wall_normals_m, task.stock, task.settings,
                task.controller, mode, compensation_model=task.model, cancel=cancel,
                program_frame=task.program_frame,
                corrected=task.corrected if mode == "offline" else None,
            )  # fmt: skip
        except InvalidInputError as exc:
            out.append((None, None, str(exc)))
            continue
        out.append((run if task.keep_runs else None, run.summary, None))
    return out


def _end_with(pid: int) -> None:
    """A worker's initializer: end it when the process that started the pool ends (a server
    killed with SIGKILL left its workers and the forkserver idle under init; issue 32)."""
    from ..lifetime import end_with

    end_with(pid)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Stop a pool now: its queued tasks are dropped and its running workers terminated (a
    cancel, Ctrl-C or SIGTERM must not wait for cuts that nobody will read)."""
    # Workers first, then the pool: a worker still starting would read its queues' semaphores
    # after the pool's shutdown removed them, and print a traceback. The thread feeding the
    # task queue may be blocked writing a task (a stock is larger than a pipe) that no worker
    # will read: the shutdown must not wait for it (CPython's pool joined it forever).
    calls = getattr(pool, "_call_queue", None)
    if calls is not None:
        calls.cancel_join_thread()
    processes = list((getattr(pool, "_processes", None) or {}).values())
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(5.0)
        if process.is_alive():
            process.kill()
    pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def _interrupts_deferred() -> Iterator[None]:
    """Ctrl-C and SIGTERM wait until the block ends (main thread; elsewhere no signal handler
    runs anyway). The pool starts a worker on ``submit`` and lists it only once started: an
    interrupt in between left a worker nobody stopped, reading semaphores already removed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    kinds = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.signal(sig, lambda signum, frame: caught.append(signum))
                for sig in kinds}  # fmt: skip
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for signum in dict.fromkeys(caught):
            signal.raise_signal(signum)  # now, to the handlers the program had


def _submitted(pool: ProcessPoolExecutor, tasks: Sequence[CutTask], cancel) -> list:
    """The tasks submitted to ``pool``. A pool's first submit waits for its forkserver to start
    and load the kernels (compiling them when numba's cache is cold: a minute on a loaded
    machine), so off the main thread (a server's job) it runs beside a loop that keeps
    looking at the cancel flag: a cancel ends the job at once, and the pool is stopped when
    its start is over. On the main thread (the CLI), interrupts wait for the submits."""
    if threading.current_thread() is threading.main_thread() or cancel is None:
        with _interrupts_deferred():  # every worker started is one the pool knows, to stop
            return [pool.submit(run_cut_task, task) for task in tasks]
    futures: list = []
    starter = threading.Thread(
        target=lambda: futures.extend(pool.submit(run_cut_task, task) for task in tasks),
        name="machining-pool-start",
        daemon=True,
    )
    starter.start()
    while starter.is_alive():
        starter.join(POLL_S)
        if starter.is_alive() and cancel():

            def stop_when_started() -> None:
                starter.join()
                _stop_workers(pool)

            # Stop the pool once it has started; the job ends now.
            threading.Thread(target=stop_when_started, daemon=True).start()
            raise _Abandoned("machining cancelled")
    return futures


class _Abandoned(CancelledError):
    """Cancelled while the pool was starting: another thread stops the pool."""


def _pool_context() -> multiprocessing.context.BaseContext:
    """Workers forked from one forkserver that imported the cut's modules once: a spawned
    worker imported them itself (about 3 s of CPU each, for each comparison). Like spawn, and
    unlike fork, the forkserver holds no thread of the server's. It lives as long as this
    process and serves every later pool: the second comparison's workers start at once."""
    context = multiprocessing.get_context("forkserver")
    # ``_warm`` loads the compiled kernels once, for every worker forked afterwards.
    context.set_forkserver_preload(
        [__name__, "robomach_core.machining.compare", "robomach_core.machining._warm"]
    )
    return context


def default_workers() -> int:
    """All local cores."""
    return max(
        1,
        len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1),
    )


def run_tasks(
    tasks: Sequence[CutTask],
    *,
    workers: int | None = None,
    cluster: str | None = None,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> list[list[tuple[Any, dict[str, Any] | None, str | None]]]:
    """Each task's results, in order (module docstring).

    Args:
        workers: Local processes; None: every core; 1: in this process.
        cluster: A Dask scheduler address (``tcp://host:8786``): run there instead.
        progress: Called with the share of tasks finished.
        cancel: Polled while tasks run; true stops them with ``CancelledError``.
    """
    if cluster:
        return _run_on_dask(tasks, cluster, progress, cancel)
    n = default_workers() if workers is None else int(workers)
    if n < 1:
        raise InvalidInputError(f"workers must be at least 1, got {workers}")
    if n == 1 or len(tasks) <= 1:
        results = []
        for i, task in enumerate(tasks):
            if cancel is not None and cancel():
                raise CancelledError("machining cancelled")
            results.append(run_cut_task(task, cancel))
            if progress is not None:
                progress((i + 1) / len(tasks))
        return results
    context = _pool_context()
    pool = ProcessPoolExecutor(
        max_workers=min(n, len(tasks)),
        mp_context=context,
        initializer=_end_with,
        initargs=(os.getpid(),),
    )
    try:
        futures = _submitted(pool, tasks, cancel)
        pending = set(futures)
        while pending:
            done, pending = wait(pending, timeout=POLL_S, return_when=FIRST_COMPLETED)
            if cancel is not None and cancel():
                raise CancelledError("machining cancelled")
            if progress is not None and done:
                progress(1.0 - len(pending) / len(futures))
        results = [f.result() for f in futures]
    except _Abandoned:
        raise CancelledError("machining cancelled") from None
    except CancelledError:
        # The job ends now; another thread stops the pool. A cancelled comparison stayed
        # "running" for good in two full runs of the suite (the API's cancel test), and the
        # one wait without a bound on this path is the pool's shutdown, which joins its
        # manager thread after the workers are terminated.
        threading.Thread(target=_stop_workers, args=(pool,), daemon=True).start()
        raise
    except BaseException:  # interrupted (Ctrl-C, SIGTERM) or a task failed
        _stop_workers(pool)
        raise
    pool.shutdown(wait=True)
    return results


def _probe_scheduler(address: str) -> None:
    """``InvalidInputError`` unless a ``tcp://`` address answers as a Dask scheduler does: it
    speaks first (its handshake), a frame whose 8-byte length is a handshake's. An address
    that answered with something else was reported as "not enough memory" (distributed took
    an HTTP status line for a length of 3 EiB), and a server that says nothing hung the
    client for ever (issue 32)."""
    scheme, _, rest = address.rpartition("://")
    if scheme not in ("", "tcp"):
        return  # tls://, ucx://: the client's own checks
    host, _, port = rest.rpartition(":")
    try:
        port_number = int(port)
    except ValueError:
        raise InvalidInputError(f"cluster address {address!r}: expected tcp://host:port") from None
    what = f"the Dask cluster at {address}"
    try:
        with socket.create_connection(
            (host.strip("[]") or "127.0.0.1", port_number), CLUSTER_TIMEOUT_S
        ) as probe:
            probe.settimeout(CLUSTER_TIMEOUT_S)
            head = b""
            while len(head) < 8:
                chunk = probe.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
    except TimeoutError:
        raise InvalidInputError(
            f"{what} said nothing within {CLUSTER_TIMEOUT_S:g} s: it is not a Dask scheduler"
        ) from None
    except OSError as exc:
        raise InvalidInputError(f"cannot reach {what}: {exc.strerror or exc}") from None
    if len(head) < 8 or int.from_bytes(head, "little") > MAX_HANDSHAKE_BYTES:
        raise InvalidInputError(
            f"{what} answered with something else than a Dask scheduler "
            f"({head[:8]!r}...): check the address and its port"
        )


def _run_on_dask(tasks, address: str, progress, cancel):
    try:
        from distributed import Client, as_completed
    except ImportError:  # pragma: no cover - the [cluster] extra
        raise InvalidInputError(
            "a cluster address needs Dask: pip install 'robomach[cluster]'"
        ) from None
    _probe_scheduler(address)
    try:
        client = Client(address, timeout=f"{CLUSTER_TIMEOUT_S:g}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise InvalidInputError(f"cannot reach the Dask cluster at {address}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - whatever the peer made distributed do
        raise InvalidInputError(
            f"the Dask cluster at {address} did not answer as a Dask scheduler "
            f"({exc.__class__.__name__})"
        ) from None
    try:
        futures = client.map(run_cut_task, list(tasks), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        results: list[Any] = [None] * len(futures)
        finished = 0
        for future in as_completed(futures):
            if cancel is not None and cancel():
                client.cancel(futures)
                raise CancelledError("machining cancelled")
            results[index[future.key]] = future.result()
            finished += 1
            if progress is not None:
                progress(finished / len(futures))
        return results
    finally:
        client.close()
