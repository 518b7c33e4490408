"""The ``robomach`` command line: one sub-command per module in ``app/commands``.

Each command module exposes ``add_parser(subparsers)`` (which sets ``func`` on its parser) and
keeps its imports of heavy libraries inside its ``run`` function, so ``robomach --help`` is fast.
Errors a user can cause (``RobomachError``, bad files, bad arguments) print one line and exit 2;
a fault no check foresaw prints one line too and exits 1 (``ROBOMACH_DEBUG=1`` shows its
traceback).
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import signal
import sys
import tempfile
import threading
from pathlib import Path

# The command modules in app/commands, in the order `robomach --help` lists them.
COMMANDS: tuple[str, ...] = ("demo", "serve", "cmrr", "compensate", "machine")


def writable_folder(path: Path, option: str = "--out") -> Path:
    """Create ``path`` if missing and prove it takes a file, before any work is done.

    Raises:
        InvalidInputError: ``path`` is under a file, in a read-only or virtual file system
            (``/proc``), or not writable; the message names ``option``.
    """
    from robomach_core.errors import InvalidInputError

    try:
        path.mkdir(parents=True, exist_ok=True)
        handle, probe = tempfile.mkstemp(dir=path, prefix=".robomach-write-check-")
        os.close(handle)
        os.unlink(probe)
    except OSError as exc:
        reason = exc.strerror or exc.__class__.__name__
        raise InvalidInputError(f"{option} {path}: cannot write files there ({reason})") from None
    return path


MAX_SETTINGS_FILE_BYTES = 10_000_000  # a settings file is a few kB of JSON


def settings_file(path: Path, option: str) -> Path:
    """``path`` once it is a readable UTF-8 text file of at most 10 MB (a settings file).

    Raises:
        InvalidInputError: missing, too large, or binary; the message names ``option``.
    """
    from robomach_core.errors import InvalidInputError

    try:
        size = path.stat().st_size
        if size > MAX_SETTINGS_FILE_BYTES:
            raise InvalidInputError(
                f"{option} {path}: {size / 1e6:.1f} MB is not a settings file (JSON of a few kB)"
            )
        path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise InvalidInputError(f"{option} {path}: the file does not exist") from None
    except UnicodeDecodeError as exc:
        raise InvalidInputError(
            f"{option} {path}: not a text file (byte {exc.start} is not UTF-8); give the JSON "
            "settings file the workbench or a study wrote"
        ) from None
    except OSError as exc:
        raise InvalidInputError(f"{option} {path}: cannot read it ({exc.strerror})") from None
    return path


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="robomach",
        description="Programming robotic machining by demonstration on a simulated cell.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers.required = True
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"app.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"app.commands.{name}":
                continue  # command not built yet
            raise
        module.add_parser(subparsers)
    return parser


def _interrupted(exc: BaseException) -> bool:
    """Whether Ctrl-C caused ``exc``: an interrupt inside a compiled (numba) kernel comes out
    as a ``SystemError`` ("returned a result with an exception set") caused by it."""
    seen: set[int] = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        if isinstance(link, KeyboardInterrupt):
            return True
        seen.add(id(link))
        link = link.__cause__ or link.__context__
    return False


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is, as Ctrl-C's ``KeyboardInterrupt`` is."""


def _terminate(signum: int, frame: object) -> None:
    raise _Terminated


def _interrupted_code(exc: BaseException) -> int:
    """130 after Ctrl-C, 143 after SIGTERM (128 + the signal, as a shell reports it)."""
    seen: set[int] = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        if isinstance(link, _Terminated):
            return 128 + signal.SIGTERM
        seen.add(id(link))
        link = link.__cause__ or link.__context__
    return 130


def main(argv: list[str] | None = None) -> int:
    # SIGTERM stops a command as Ctrl-C does: its cleanup runs (the machining pool's workers
    # are stopped) instead of the process vanishing and leaving them computing (issue 32).
    # ``serve`` hands both signals to uvicorn while it runs.
    if threading.current_thread() is not threading.main_thread():
        return _main(argv)
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        return _main(argv)
    finally:
        signal.signal(signal.SIGTERM, previous)


# Options whose value is a list of numbers, and how many at most: a value a person types as
# "-12.5,3,4" (argparse takes it for an option), "-12.5 3 4" or "(-12.5, 3, 4)" is joined into
# one "--option=..." before parsing (issue 31).
NUMBER_LIST_OPTIONS = {"--propose-guide-points": 3, "--wobj": 6}
# nan and inf read as numbers, so that the option's range check names the range
_NUMBER = re.compile(r"^[+-]?((\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|nan|inf|infinity)$", re.I)


def number_parts(text: str) -> list[str]:
    """The numbers of a value as typed: separated by commas, semicolons or spaces, in
    brackets or not; [] when any part is not a number."""
    parts = [p for p in re.split(r"[,;\s]+", text.strip().strip("()[]").strip()) if p]
    return parts if parts and all(_NUMBER.match(p) for p in parts) else []


def join_number_values(argv: list[str]) -> list[str]:
    """``argv`` with each ``NUMBER_LIST_OPTIONS`` value as one ``--option=a,b,c`` token."""
    out, i = [], 0
    while i < len(argv):
        token = argv[i]
        most = NUMBER_LIST_OPTIONS.get(token)
        if most is None:
            out.append(token)
            i += 1
            continue
        numbers: list[str] = []
        j = i + 1
        while j < len(argv) and len(numbers) < most:
            parts = number_parts(argv[j])
            if not parts or len(numbers) + len(parts) > most:
                break
            numbers += parts
            j += 1
        if numbers:
            out.append(f"{token}={','.join(numbers)}")
            i = j
        else:
            out.append(token)
            i += 1
    return out


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(join_number_values(sys.argv[1:] if argv is None else list(argv)))
    from robomach_core.errors import RobomachError

    try:
        return int(args.func(args) or 0)
    except RobomachError as exc:
        print(f"robomach {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"robomach {args.command}: interrupted", file=sys.stderr)
        return _interrupted_code(exc)
    except Exception as exc:  # a fault no check foresaw: one line, the traceback on request
        if _interrupted(exc):
            print(f"robomach {args.command}: interrupted", file=sys.stderr)
            return _interrupted_code(exc)
        if os.environ.get("ROBOMACH_DEBUG"):
            raise
        from app.session.jobs import describe_unexpected

        print(
            f"robomach {args.command}: error: {describe_unexpected(exc)} "
            "(set ROBOMACH_DEBUG=1 for the traceback)",
            file=sys.stderr,
        )
        return 1


if __name__ == "__main__":
    sys.exit(main())
