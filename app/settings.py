"""Settings of ``robomach serve``: command-line flags over environment variables over defaults.

A pydantic-settings model: every field reads the ``ROBOMACH_``-prefixed variable of its name,
typed and checked by pydantic (``ROBOMACH_HOST``, ``ROBOMACH_PORT``, ``ROBOMACH_VISER_PORT``,
``ROBOMACH_TOKEN``, ``ROBOMACH_TOKEN_READS`` (1/0: reads need the token too; default on when
binding beyond loopback), ``ROBOMACH_REAL_TIME``, and the upload limits
``ROBOMACH_MAX_UPLOAD_BYTES`` and ``ROBOMACH_MAX_TRIANGLES`` (at most the mesh reader's);
the data folder is ``ROBOMACH_DATA``, or ``ROBOMACH_DATA_DIR``). An empty variable is unset.
"""

from __future__ import annotations

import ipaddress
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationError
from pydantic_settings import BaseSettings, SettingsConfigDict

from robomach_core.errors import InvalidInputError
from robomach_core.limits import MAX_MESH_BYTES, MAX_MESH_TRIANGLES

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


class ServerSettings(BaseSettings):
    """How the workbench serves. Built with no arguments it reads the ``ROBOMACH_*`` variables
    too (pydantic-settings); arguments win over them.

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

    model_config = SettingsConfigDict(
        env_prefix="ROBOMACH_", env_ignore_empty=True, frozen=True, populate_by_name=True
    )

    host: str = DEFAULT_HOST
    port: int = DEFAULT_PORT
    viser_port: int | None = DEFAULT_VISER_PORT
    data_dir: Path = Field(DEFAULT_DATA_DIR, validation_alias="ROBOMACH_DATA")
    token: str | None = None
    max_upload_bytes: int = MAX_MESH_BYTES
    max_triangles: int = MAX_MESH_TRIANGLES
    static_dir: Path = STATIC_DIR
    real_time: bool = True
    token_reads: bool | None = None
    refuse_foreign_hosts: bool = False

    @classmethod
    def from_env(cls, **overrides: Any) -> ServerSettings:
        """Defaults, then ``ROBOMACH_*`` variables, then the non-None ``overrides``; foreign
        hosts refused; checked (``check``). A variable pydantic cannot read as its field's
        type is an ``InvalidInputError`` naming it."""
        values: dict[str, Any] = {"refuse_foreign_hosts": True}
        values |= {k: v for k, v in overrides.items() if v is not None}
        try:
            settings = cls(**values)
        except ValidationError as exc:
            err = exc.errors()[0]
            field = str(err["loc"][0])
            name = field if field.startswith("ROBOMACH_") else f"ROBOMACH_{field.upper()}"
            raise InvalidInputError(f"{name}: {err['msg']}, not {err['input']!r}") from None
        settings.check()
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

    def check(self) -> None:
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
