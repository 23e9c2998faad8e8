"""Client-side helpers shared by the tests of the process bridge (tests/sim/test_bridge.py)
and of ``dqcontrol sim-server`` (tests/cli/test_sim_server_cmd.py), not a test module: both
transports, a free loopback port, a packet header and one request answered. No pyzmq here:
the command's tests that need no server run without it."""

from __future__ import annotations

import pytest

from dqcontrol.sim.bridge import HEADER

#: Both transports, for the tests that hold for either.
TRANSPORTS = pytest.mark.parametrize("transport", ["tcp", "udp"])


def exchange(link, packet: bytes) -> bytes:
    """Send ``packet`` on a client endpoint and return the answer (within 2 s)."""
    link.send(packet)
    answer = link.receive(2.0)
    assert answer is not None
    return answer


def header(kind, seq, n, status=0, version=1, magic=b"DQ"):
    return HEADER.pack(magic, version, kind, seq, n, status)


class socket_port:
    """A free TCP (or UDP) port on the loopback address."""

    def __init__(self, transport: str = "tcp") -> None:
        self.transport = transport

    def __enter__(self) -> int:
        import socket

        kind = socket.SOCK_DGRAM if self.transport == "udp" else socket.SOCK_STREAM
        self.sock = socket.socket(socket.AF_INET, kind)
        self.sock.bind(("127.0.0.1", 0))
        return self.sock.getsockname()[1]

    def __exit__(self, *exc) -> None:
        self.sock.close()
