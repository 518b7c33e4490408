"""The test servers' ports: two asked for in a row are never the same one."""

from __future__ import annotations

from tests.api.server_process import free_port


def test_free_port_never_answers_a_port_twice() -> None:
    # The kernel hands a just-closed port out again; a server given it for both its REST
    # and viser ports refuses to start ("the REST port and the viser port must differ").
    ports = [free_port() for _ in range(300)]
    assert len(set(ports)) == len(ports)
