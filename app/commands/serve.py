"""``robomach serve``: the browser workbench (viser 3D scene, REST API, teach pendant page)."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

# One BLAS thread: the server's matrices are small and its parallelism is its own threads
# (requests, jobs, viser). OpenBLAS's threads spin while they wait for work, and on a 2-core
# machine took the CPU from the request threads (GET /api/state p99 129 -> 46 ms while a
# 311k-sample recording is post-processed). Set before numpy loads; a value already set wins.
BLAS_THREADS = {"OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "serve",
        help="serve the workbench: viser 3D scene, REST API (/docs) and pendant page (/pendant/)",
        description=(
            "Start the viser 3D workbench, the REST API (OpenAPI docs at /docs) and the teach "
            "pendant page (/pendant/) in one process, on the last opened project of --data. "
            "Binding to anything but 127.0.0.1/localhost needs the ROBOMACH_TOKEN environment "
            "variable; mutating REST calls must then send it as 'Authorization: Bearer TOKEN', "
            "and reads too (--token-reads, on by default beyond loopback). "
            "Ctrl-C stops it."
        ),
    )
    p.add_argument(
        "--host", default=None, help="interface to bind (default 127.0.0.1, or $ROBOMACH_HOST)"
    )
    p.add_argument(
        "--port",
        type=int,
        default=None,
        help="REST API and pendant port (default 8000, or $ROBOMACH_PORT)",
    )
    p.add_argument(
        "--viser-port",
        type=int,
        default=None,
        help="viser 3D workbench port (default 8080, or $ROBOMACH_VISER_PORT)",
    )
    p.add_argument(
        "--data",
        type=Path,
        default=None,
        metavar="DIR",
        help="project database and exports (default ./robomach-data, or $ROBOMACH_DATA)",
    )
    p.add_argument(
        "--token-reads",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="reads (GET /api/...) need the token too (default: on when --host is beyond "
        "loopback, or $ROBOMACH_TOKEN_READS); /api/health stays open",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    for name, value in BLAS_THREADS.items():
        os.environ.setdefault(name, value)
    import logging

    from app.server import serve
    from app.settings import ServerSettings
    from robomach_core.limits import PORT

    for flag, value in (("--port", args.port), ("--viser-port", args.viser_port)):
        if value is not None:
            PORT.check(value, flag)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s:     %(name)s: %(message)s")
    settings = ServerSettings.from_env(
        host=args.host,
        port=args.port,
        viser_port=args.viser_port,
        data_dir=args.data,
        token_reads=args.token_reads,
    )
    return serve(settings)
