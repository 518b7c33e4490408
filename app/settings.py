"""Settings of ``robomach serve``: command-line flags over environment variables over defaults.

pydantic-settings is not a dependency, so this is a frozen dataclass with a ``from_env``
constructor. Environment variables: ``ROBOMACH_HOST``, ``ROBOMACH_PORT``,
``ROBOMACH_VISER_PORT``, ``ROBOMACH_DATA``, ``ROBOMACH_TOKEN``, ``ROBOMACH_TOKEN_READS``
(1/0: reads need the token too; default on when binding beyond loopback), and the upload
limits ``ROBOMACH_MAX_UPLOAD_BYTES`` and ``ROBOMACH_MAX_TRIANGLES`` (at most the mesh reader's).
"""

from __future__ import annotations

import ipaddress
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from robomach_core.errors import InvalidInputError
from robomach_core.workpiece import MAX_MESH_BYTES, MAX_MESH_TRIANGLES

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8000
DEFAULT_VISER_PORT = 8080
DEFAULT_DATA_DIR = Path("robomach-data")
TOKEN_MIN_LENGTH = 16
MAX_JSON_BODY_BYTES = 1024 * 1024  # every JSON body the API takes is far smaller
STATIC_DIR = Path(__file__).resolve().parent.parent / "static"


def is_loopback_name(host: str) -> bool:
    """True for a name only this machine answers to: localhost, *.localhost, 127.0.0.0/8, ::1
    (a hostname from a ``Host`` header or a bind address, without a port)."""
    host = host.strip().lower().rstrip(".")
    if host == "localhost" or host.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@dataclass(frozen=True)
class ServerSettings:
    """How the workbench serves.

    Attributes:
        host: Interface of the REST API and the viser scene. Anything but a loopback address
            needs ``token``.
        port: REST API and pendant page port.
        viser_port: viser 3D workbench port; None runs no viser server (tests).
        data_dir: Folder of the project database and saved exports.
        token: When set, every mutating REST call must send it (``Authorization: Bearer ...``
            or ``X-Robomach-Token``).
        max_upload_bytes: Largest mesh upload [bytes].
        max_triangles: Most triangles of an uploaded mesh.
        static_dir: Folder served at ``/pendant/`` when it exists.
        real_time: Pace lead-through pushes and jogs to the wall clock, as for a person at a
            pendant (``ROBOMACH_REAL_TIME=0`` turns it off for scripted rigs and test suites
            that drive the robot by REST and want it as fast as the simulation allows).
        token_reads: Reads (GET) of /api/ need the token too (the project file holds the
            customer's part and robot); None: on when the server binds beyond loopback.
            ``/api/health`` stays open.
        refuse_foreign_hosts: On loopback, refuse every request whose ``Host`` is not a
            loopback name (a page under a name rebound to 127.0.0.1: DNS rebinding).
            ``from_env`` (the CLI) turns it on; off by default for in-process clients.
    """

    host: str = DEFAULT_HOST
    port: int = DEFAULT_PORT
    viser_port: int | None = DEFAULT_VISER_PORT
    data_dir: Path = DEFAULT_DATA_DIR
    token: str | None = None
    max_upload_bytes: int = MAX_MESH_BYTES
    max_triangles: int = MAX_MESH_TRIANGLES
    static_dir: Path = field(default=STATIC_DIR)
    real_time: bool = True
    token_reads: bool | None = None
    refuse_foreign_hosts: bool = False

    @classmethod
    def from_env(cls, env: dict[str, str] | None = None, **overrides: Any) -> ServerSettings:
        """Defaults, then ``ROBOMACH_*`` variables, then the non-None ``overrides``."""
        env = os.environ if env is None else env
        values: dict[str, Any] = {}
        if env.get("ROBOMACH_HOST"):
            values["host"] = env["ROBOMACH_HOST"]
        for key, name in (
            ("port", "ROBOMACH_PORT"),
            ("viser_port", "ROBOMACH_VISER_PORT"),
            ("max_upload_bytes", "ROBOMACH_MAX_UPLOAD_BYTES"),
            ("max_triangles", "ROBOMACH_MAX_TRIANGLES"),
        ):
            if env.get(name):
                try:
                    values[key] = int(env[name])
                except ValueError:
                    raise InvalidInputError(
                        f"{name} must be an integer, not {env[name]!r}"
                    ) from None
        if env.get("ROBOMACH_DATA"):
            values["data_dir"] = Path(env["ROBOMACH_DATA"])
        if env.get("ROBOMACH_TOKEN"):
            values["token"] = env["ROBOMACH_TOKEN"]
        for key, name in (
            ("real_time", "ROBOMACH_REAL_TIME"),
            ("token_reads", "ROBOMACH_TOKEN_READS"),
        ):
            if env.get(name):
                flag = env[name].strip().lower()
                if flag not in ("0", "1", "on", "off", "true", "false"):
                    raise InvalidInputError(
                        f"{name} must be 1/on/true or 0/off/false, not {flag!r}"
                    )
                values[key] = flag in ("1", "on", "true")
        values["refuse_foreign_hosts"] = True
        values.update({k: v for k, v in overrides.items() if v is not None})
        settings = replace(cls(), **values)
        settings.validate()
        return settings

    @property
    def loopback(self) -> bool:
        """True when only this machine can reach the server."""
        return is_loopback_name(self.host)

    @property
    def reads_need_token(self) -> bool:
        """GETs of /api/ need the token: ``token_reads``, by default beyond loopback."""
        if not self.token:
            return False
        return self.token_reads if self.token_reads is not None else not self.loopback

    def validate(self) -> None:
        """Raise ``InvalidInputError`` for settings that must not serve."""
        for name, port in (("port", self.port), ("viser port", self.viser_port)):
            if port is not None and not (1 <= port <= 65535):
                raise InvalidInputError(f"the {name} must be within 1-65535, got {port}")
        if self.viser_port is not None and self.viser_port == self.port:
            raise InvalidInputError("the REST port and the viser port must differ")
        if not self.loopback and not self.token:
            raise InvalidInputError(
                f"binding to {self.host} makes the workbench reachable from other machines: "
                "set ROBOMACH_TOKEN (at least 16 characters) so mutating calls need it"
            )
        if self.token_reads and not self.token:
            raise InvalidInputError("reads can need the token only when ROBOMACH_TOKEN is set")
        if self.token is not None and len(self.token) < TOKEN_MIN_LENGTH:
            raise InvalidInputError(
                f"ROBOMACH_TOKEN must be at least {TOKEN_MIN_LENGTH} characters"
            )
        if not (0 < self.max_upload_bytes <= MAX_MESH_BYTES):
            raise InvalidInputError(
                f"the upload limit must be within 1-{MAX_MESH_BYTES} bytes (the mesh reader's)"
            )
        if not (0 < self.max_triangles <= MAX_MESH_TRIANGLES):
            raise InvalidInputError(f"the triangle limit must be within 1-{MAX_MESH_TRIANGLES}")
