"""The ``robomach`` command line: one sub-command per module in ``app/commands``.

Each command module exposes ``add_parser(subparsers)`` (which sets ``func`` on its parser) and
keeps its imports of heavy libraries inside its ``run`` function, so ``robomach --help`` is fast.
Errors a user can cause (``RobomachError``, bad files, bad arguments) print one line and exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
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


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from robomach_core.errors import RobomachError

    try:
        return int(args.func(args) or 0)
    except RobomachError as exc:
        print(f"robomach {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"robomach {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
