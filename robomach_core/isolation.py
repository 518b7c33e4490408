"""Native steps that may crash, run where a crash cannot take the caller down.

PROBLEM   coal, qhull and pinocchio are C++: on an input they do not expect they can crash the
          whole process (a segfault on a flat mesh's hull, a stack overflow on a URDF 4,000
          links deep) or allocate without bound. In the workbench that process is the server.
          The checks in ``mesh_check`` and ``urdf_check`` refuse every input known to do this,
          but a check can only refuse what someone thought of.
STRATEGY  Before such an input reaches the native code in this process, the same native steps
          run in a child process: a helper (started at first use, one per process, with numpy,
          coal, pinocchio and trimesh imported once) forks a child per task, lowers the child's
          address-space limit (``RLIMIT_AS``) and runs the task there. A child that dies of a
          signal, runs out of its memory or overruns its time is reported as an ``IsolatedError``
          and the helper lives on; a helper that dies is started again at the next call. The
          answer comes back as JSON, and the numeric arrays a task returns (a parsed mesh) as
          raw bytes described by it, of a plain numeric dtype (a crashed child's output is
          never unpickled).
SOLUTION  ``run_isolated(task, payload, memory_bytes=, timeout_s=, name=) -> dict``; a task is
          a function of ``TASKS`` (``mesh`` builds the part's convex hull and BVH as the
          supervisor and the contact model will; ``urdf`` builds the pinocchio model) or a
          module-level function given itself (pickled by name, its module imported by the
          helper: ``workpiece.parse_mesh_file`` reads a mesh file). A task returns a dict; its
          ``"arrays"`` entry (name -> numpy array) comes back as arrays.
"""

from __future__ import annotations

import json
import os
import pickle
import signal
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from .errors import RobomachError

DEFAULT_MEMORY_BYTES = 1 << 30  # what one task may allocate above the helper's own footprint
DEFAULT_TIMEOUT_S = 60.0
HELPER_START_TIMEOUT_S = 60.0
_HEADER = struct.Struct("<Q")
_MAX_ANSWER_BYTES = 1 << 29  # JSON and arrays (a parsed mesh of 500k triangles: ~20 MB)
_ARRAY_KINDS = "biuf"  # dtypes an answer's arrays may have (no objects, no pickles)


class IsolatedError(RobomachError, ValueError):
    """A native step crashed, ran out of memory or time, or raised in its isolated process.

    Attributes:
        kind: "crash" (a signal), "memory", "timeout", "error" (the task raised) or "helper"
            (the helper process could not run it).
    """

    def __init__(
        self, message: str, *, kind: str = "error", error_type: str = "", detail: str = ""
    ) -> None:
        super().__init__(message)
        self.kind = kind
        self.error_type = error_type  # the class name of what the task raised ("error")
        self.detail = detail  # its message alone


# --- the tasks (they run in the child) -----------------------------------------------------


def _task_mesh(payload: dict[str, Any]) -> dict[str, Any]:
    """The part's convex hull in coal (supervision obstacle), its BVH (contact, clearance) and
    one distance query, as ``supervision.Supervisor`` and ``contact`` build them."""
    import coal
    import numpy as np

    from .part.bvh import bvh_from_mesh, convex_hull_of

    vertices = np.asarray(payload["vertices"], dtype=float)
    faces = np.asarray(payload["faces"], dtype=np.int64)
    hull, _, hull_volume_m3 = convex_hull_of(vertices)
    bvh = bvh_from_mesh(vertices, faces)
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    request.enable_signed_distance = True
    centre = vertices.max(axis=0) + 0.01
    T_sphere = coal.Transform3s(np.eye(3), centre)
    distance = coal.distance(bvh, coal.Transform3s(), coal.Sphere(0.001), T_sphere, request, result)
    hull_distance = coal.distance(hull, coal.Transform3s(), coal.Sphere(0.001), T_sphere, request,
                                  coal.DistanceResult())  # fmt: skip
    return {
        "hull_vertices": int(hull.num_points),
        "hull_volume_m3": hull_volume_m3,
        "distance_m": float(distance),
        "hull_distance_m": float(hull_distance),
    }


def _task_urdf(payload: dict[str, Any]) -> dict[str, Any]:
    """The pinocchio model of a URDF text, as ``robot.Robot`` builds it."""
    import pinocchio as pin

    model = pin.buildModelFromXML(payload["text"])
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    return {"nq": int(model.nq), "njoints": int(model.njoints), "nframes": int(model.nframes)}


def _task_echo(payload: dict[str, Any]) -> dict[str, Any]:
    """For tests: crash, allocate or sleep on request, else answer the payload."""
    if payload.get("crash"):
        os.kill(os.getpid(), signal.SIGSEGV)
    if payload.get("allocate_bytes"):
        block = bytearray(int(payload["allocate_bytes"]))
        return {"allocated": len(block)}
    if payload.get("sleep_s"):
        time.sleep(float(payload["sleep_s"]))
    return {"echo": payload.get("value")}


TASKS: dict[str, Callable[[dict[str, Any]], dict[str, Any]]] = {
    "mesh": _task_mesh,
    "urdf": _task_urdf,
    "echo": _task_echo,
}

# --- the parent's side --------------------------------------------------------------------


class _Helper:
    """The helper process and the lock that gives it one task at a time."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.proc: subprocess.Popen | None = None

    def ensure(self) -> subprocess.Popen:
        if self.proc is not None and self.proc.poll() is None:
            return self.proc
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
               "MKL_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}  # fmt: skip
        self.proc = subprocess.Popen(
            [sys.executable, "-c", "from robomach_core.isolation import serve; serve()"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            env=env,
            close_fds=True,
        )
        return self.proc

    def stop(self) -> None:
        proc, self.proc = self.proc, None
        if proc is not None and proc.poll() is None:
            proc.kill()
            proc.wait(10)


_HELPER = _Helper()


def helper_pid() -> int | None:
    """The helper's process id while it runs (for memory measurements), else None."""
    proc = _HELPER.proc
    return proc.pid if proc is not None and proc.poll() is None else None


Task = str | Callable[[dict[str, Any]], dict[str, Any]]


def _task_function(task: Task) -> Callable[[dict[str, Any]], dict[str, Any]]:
    return TASKS[task] if isinstance(task, str) else task


def _task_name(task: Task) -> str:
    return task if isinstance(task, str) else str(getattr(task, "__name__", "isolated"))


def run_isolated(
    task: Task,
    payload: dict[str, Any],
    *,
    memory_bytes: int = DEFAULT_MEMORY_BYTES,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    name: str | None = None,
) -> dict[str, Any]:
    """The answer of ``TASKS[task](payload)`` (or ``task(payload)``) computed in an isolated
    child process.

    Args:
        task: A key of ``TASKS``, or a module-level function.
        payload: The task's input (pickled to the helper, which this process started).
        memory_bytes: Address space the child may add to the helper's.
        timeout_s: Wall-clock limit of the task.
        name: What the messages call the task ("the <name> check ..."; default its key or
            its function's name).

    Raises:
        IsolatedError: the task crashed (a signal), ran out of memory or time, or raised (the
            message says which, with the exception's class and text).
    """
    if isinstance(task, str) and task not in TASKS:
        raise KeyError(task)
    name = name or _task_name(task)
    request = pickle.dumps((task, name, payload, int(memory_bytes), float(timeout_s)), protocol=5)
    with _HELPER.lock:
        for attempt in (1, 2):  # a helper that died since the last call is started again
            proc = _HELPER.ensure()
            try:
                _write(proc.stdin, request)
                answer = _read(proc.stdout, timeout_s + HELPER_START_TIMEOUT_S)
                break
            except (OSError, EOFError, TimeoutError):
                _HELPER.stop()
                if attempt == 2:
                    raise IsolatedError(
                        f"the isolated {name} check could not run (its helper process stopped)",
                        kind="helper",
                    ) from None
    reply, arrays = answer
    if reply.get("ok"):
        value = reply["value"]
        if arrays:
            value["arrays"] = arrays
        return value
    raise IsolatedError(
        reply.get("error") or f"the isolated {name} check failed",
        kind=str(reply.get("kind", "error")),
        error_type=str(reply.get("type", "")),
        detail=str(reply.get("message", "")),
    )


def _frame(answer: dict[str, Any], arrays: dict[str, Any] | None = None) -> bytes:
    """An answer as sent: the JSON's length, the JSON (describing the arrays), the arrays'
    bytes one after the other."""
    import numpy as np

    blobs, meta, offset = [], [], 0
    for name, array in (arrays or {}).items():
        a = np.ascontiguousarray(array)
        if a.dtype.kind not in _ARRAY_KINDS:
            raise TypeError(f"array {name!r} of dtype {a.dtype} cannot be answered")
        meta.append([str(name), a.dtype.str, list(a.shape), offset, a.nbytes])
        blobs.append(a.tobytes())
        offset += a.nbytes
    head = json.dumps({**answer, "arrays": meta}).encode()
    return _HEADER.pack(len(head)) + head + b"".join(blobs)


def _unframe(data: bytes, *, decode: bool = True) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the JSON answer, its arrays by name: none unless ``decode``) of ``_frame``'s bytes;
    ``ValueError`` when they are not such an answer."""
    import numpy as np

    if len(data) < _HEADER.size:
        raise ValueError("answer too short")
    (size,) = _HEADER.unpack_from(data)
    end = _HEADER.size + size
    if end > len(data):
        raise ValueError("answer cut short")
    answer = json.loads(data[_HEADER.size : end])
    if not isinstance(answer, dict):
        raise ValueError("answer is not an object")
    arrays: dict[str, Any] = {}
    view = memoryview(data)[end:]
    for name, dtype, shape, offset, nbytes in answer.pop("arrays", None) or []:
        kind = np.dtype(dtype)
        if kind.kind not in _ARRAY_KINDS or offset < 0 or offset + nbytes > len(view):
            raise ValueError(f"answer array {name!r} is malformed")
        if not decode:
            continue
        flat = np.frombuffer(view[offset : offset + nbytes], dtype=kind)
        arrays[str(name)] = flat.reshape([int(n) for n in shape]).copy()
    return answer, arrays


def _write(stream: Any, data: bytes) -> None:
    stream.write(_HEADER.pack(len(data)) + data)
    stream.flush()


def _read_exact(stream: Any, n: int) -> bytes:
    chunks, left = [], n
    while left:
        chunk = stream.read(left) if not hasattr(stream, "read1") else stream.read1(left)
        if not chunk:
            raise EOFError("the stream ended")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _read(stream: Any, timeout_s: float) -> tuple[dict[str, Any], dict[str, Any]]:
    import select

    ready, _, _ = select.select([stream], [], [], timeout_s)
    if not ready:
        raise TimeoutError
    (size,) = _HEADER.unpack(_read_exact(stream, _HEADER.size))
    if size > _MAX_ANSWER_BYTES:
        raise EOFError("answer too large")
    try:
        return _unframe(_read_exact(stream, size))
    except ValueError as exc:
        raise EOFError(f"unreadable answer ({exc})") from None


# --- the helper's side --------------------------------------------------------------------


def _address_space_bytes() -> int:
    """This process's virtual memory size (``VmSize``), 0 when /proc cannot tell."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def _describe_exit(status: int, task: str) -> str:
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        try:
            name = signal.Signals(sig).name
        except ValueError:
            name = f"signal {sig}"
        return f"the {task} check crashed ({name}) in its isolated process"
    return f"the {task} check ended with code {os.WEXITSTATUS(status)} without an answer"


def _child(task: Task, name: str, payload: dict[str, Any], memory_bytes: int, out_fd: int) -> None:
    """Run one task under the memory limit and write its JSON answer to ``out_fd``."""
    import resource

    limit = _address_space_bytes() + memory_bytes
    if limit > memory_bytes:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    arrays: dict[str, Any] = {}
    try:
        value = _task_function(task)(payload)
        arrays = value.pop("arrays", None) or {}
        answer = {"ok": True, "value": value}
    except MemoryError:
        answer = {
            "ok": False,
            "kind": "memory",
            "error": f"the {name} check needs more than {memory_bytes / 2**20:.0f} MiB of memory",
        }
    except Exception as exc:  # noqa: BLE001 - reported to the caller as its message
        answer = {
            "ok": False,
            "kind": "error",
            "error": f"{exc.__class__.__name__}: {exc}"[:2000],
            "type": exc.__class__.__name__,
            "message": str(exc)[:2000],
        }
    try:
        data = _frame(answer, arrays)
    except MemoryError:
        too_big = f"the {name} check's answer does not fit in its memory"
        data = _frame({"ok": False, "kind": "memory", "error": too_big})
    with os.fdopen(out_fd, "wb") as out:
        out.write(data)


def _run_forked(
    task: Task, name: str, payload: dict[str, Any], memory_bytes: int, timeout_s: float
) -> bytes:
    import select

    read_fd, write_fd = os.pipe()
    helper = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child
        from .lifetime import die_with_parent

        die_with_parent(helper)  # a helper that ends (its server killed) takes the task along
        os.close(read_fd)
        code = 0
        try:
            _child(task, name, payload, memory_bytes, write_fd)
        except BaseException:  # noqa: BLE001 - the child must always _exit
            code = 1
        os._exit(code)
    os.close(write_fd)
    chunks: list[bytes] = []
    deadline = time.monotonic() + timeout_s
    timed_out = False
    with os.fdopen(read_fd, "rb") as pipe:
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                timed_out = True
                break
            ready, _, _ = select.select([pipe], [], [], left)
            if not ready:
                continue
            chunk = os.read(pipe.fileno(), 1 << 16)
            if not chunk:
                break
            chunks.append(chunk)
    if timed_out:
        os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    if timed_out:
        return _frame({
            "ok": False,
            "kind": "timeout",
            "error": f"the {name} check took longer than {timeout_s:g} s",
        })  # fmt: skip
    data = b"".join(chunks)
    if os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0 and data:
        try:
            _unframe(data, decode=False)
        except ValueError:
            pass
        else:
            return data
    return _frame({"ok": False, "kind": "crash", "error": _describe_exit(status, name)})


def serve() -> None:
    """The helper's loop: read a request from stdin, answer on stdout, until stdin closes or
    the process that started it ends (killed: it never closes stdin while a task runs)."""
    from .lifetime import end_with

    end_with(os.getppid())
    import coal  # noqa: F401 - imported once here, shared by every forked child
    import numpy  # noqa: F401
    import pinocchio  # noqa: F401
    import trimesh  # noqa: F401

    from .part import bvh  # noqa: F401

    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    while True:
        try:
            (size,) = _HEADER.unpack(_read_exact(stdin, _HEADER.size))
            task, name, payload, memory_bytes, timeout_s = pickle.loads(_read_exact(stdin, size))
        except (EOFError, OSError):
            return
        _write(stdout, _run_forked(task, name, payload, memory_bytes, timeout_s))
