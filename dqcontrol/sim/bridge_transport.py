r"""The bridge's two transports: ZMQ over TCP (``tcp://HOST:PORT``) and UDP datagrams
(``udp://HOST:PORT``).

Both carry the same packets (:mod:`dqcontrol.sim.bridge`), one message per packet. ZMQ
queues a message sent before the server is up and never loses one on a live connection;
every message passes through its I/O threads, a hand-off in each process (about a tenth
of a millisecond more per round trip than UDP on a two-core machine). UDP hands a
datagram straight to the blocked reader and, like a real arm's 1 kHz link, may lose or
reorder one: the protocol's sequence numbers reject
stale answers, a lost answer is a timeout the loop's watchdog counts, and the client
repeats only the idempotent ``HELLO`` and ``DESCRIBE`` (docs/theory.md §12.5).

:func:`server_endpoint` and :func:`client_endpoint` give the endpoint for an address.
"""

from __future__ import annotations

import socket
from typing import Protocol, cast

from dqcontrol.errors import ParameterError

__all__ = [
    "UDP_MAX_PACKET",
    "ClientEndpoint",
    "ServerEndpoint",
    "client_endpoint",
    "parse_address",
    "server_endpoint",
]

#: The largest datagram UDP over IPv4 carries [bytes].
UDP_MAX_PACKET = 65507
_SCHEMES = ("tcp", "udp")


class BadFraming(Exception):
    """A message that is not one packet (ZMQ: not the identity and one frame)."""


class ServerEndpoint(Protocol):
    """The server's end: receives a packet with its sender, answers the sender."""

    address: str

    def receive(self, timeout_s: float) -> tuple[object, bytes] | None:
        """``(peer, packet)``, or ``None`` after ``timeout_s`` [s]; raises
        :class:`BadFraming` on a message that is not one packet."""
        ...

    def send(self, peer: object, packet: bytes) -> None:
        """Send ``packet`` to ``peer``."""
        ...

    def close(self) -> None:
        """Close the socket (idempotent)."""
        ...


class ClientEndpoint(Protocol):
    """The client's end, connected to one server."""

    #: Whether a message may be lost (the client then repeats idempotent requests).
    lossy: bool

    def send(self, packet: bytes) -> None:
        """Send ``packet`` to the server (a lost one is not an error)."""
        ...

    def receive(self, timeout_s: float) -> bytes | None:
        """The next packet, or ``None`` after at most ``timeout_s`` [s]."""
        ...

    def close(self) -> None:
        """Close the socket (idempotent)."""
        ...


def parse_address(address: str) -> tuple[str, str, int]:
    """``(scheme, host, port)`` of ``tcp://HOST:PORT`` or ``udp://HOST:PORT``.

    Raises:
        ParameterError: any other form (the message shows the two that are accepted).
    """
    scheme, sep, rest = address.partition("://") if isinstance(address, str) else ("", "", "")
    host, colon, port = rest.rpartition(":")
    if not sep or scheme not in _SCHEMES or not colon or not host or not port.isdigit():
        raise ParameterError(
            "address must be 'tcp://HOST:PORT' (ZMQ) or 'udp://HOST:PORT' (datagrams), "
            f"got {address!r}"
        )
    if int(port) > 65535:
        raise ParameterError(f"port must be 0..65535, got {port} in {address!r}")
    return scheme, host, int(port)


def _zmq():
    try:
        import zmq
    except ImportError as exc:  # pragma: no cover - pyzmq comes with meshcat
        from dqcontrol.sim.bridge import BridgeError

        raise BridgeError("the tcp:// bridge needs pyzmq (pip install pyzmq)") from exc
    return zmq


class _ZmqServer:
    def __init__(self, host: str, port: int) -> None:
        self._zmq = zmq = _zmq()
        self._sock = zmq.Context.instance().socket(zmq.ROUTER)
        self._sock.setsockopt(zmq.LINGER, 0)
        if port == 0:
            port = self._sock.bind_to_random_port(f"tcp://{host}")
        else:
            self._sock.bind(f"tcp://{host}:{port}")
        self.address = f"tcp://{host}:{port}"

    def receive(self, timeout_s: float) -> tuple[object, bytes] | None:
        if not self._sock.poll(max(0, round(1e3 * timeout_s)), self._zmq.POLLIN):
            return None
        frames = self._sock.recv_multipart()
        if len(frames) != 2:
            raise BadFraming
        return frames[0], frames[1]

    def send(self, peer: object, packet: bytes) -> None:
        self._sock.send_multipart([peer, packet])

    def close(self) -> None:
        self._sock.close(0)


class _ZmqClient:
    lossy = False

    def __init__(self, host: str, port: int) -> None:
        self._zmq = zmq = _zmq()
        self._sock = zmq.Context.instance().socket(zmq.DEALER)
        self._sock.setsockopt(zmq.LINGER, 0)
        self._sock.connect(f"tcp://{host}:{port}")

    def send(self, packet: bytes) -> None:
        self._sock.send(packet)

    def receive(self, timeout_s: float) -> bytes | None:
        if not self._sock.poll(max(1, round(1e3 * timeout_s)), self._zmq.POLLIN):
            return None
        return self._sock.recv()

    def close(self) -> None:
        self._sock.close(0)


def _udp_socket() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    return sock


class _UdpServer:
    def __init__(self, host: str, port: int) -> None:
        self._sock = _udp_socket()
        self._sock.bind((host, port))
        self.address = f"udp://{host}:{self._sock.getsockname()[1]}"

    def receive(self, timeout_s: float) -> tuple[object, bytes] | None:
        self._sock.settimeout(max(timeout_s, 1e-6))
        try:
            packet, peer = self._sock.recvfrom(UDP_MAX_PACKET)
        except (TimeoutError, ConnectionError):
            return None
        return peer, packet

    def send(self, peer: object, packet: bytes) -> None:
        try:
            self._sock.sendto(packet, cast("tuple[str, int]", peer))
        except ConnectionError:
            pass  # the client is gone: its datagram is lost, as any other

    def close(self) -> None:
        self._sock.close()


class _UdpClient:
    lossy = True

    def __init__(self, host: str, port: int) -> None:
        self._sock = _udp_socket()
        self._sock.connect((host, port))

    def send(self, packet: bytes) -> None:
        try:
            self._sock.send(packet)
        except ConnectionError:
            pass  # the last datagram found no server: this one is lost too

    def receive(self, timeout_s: float) -> bytes | None:
        self._sock.settimeout(max(timeout_s, 1e-6))
        try:
            return self._sock.recv(UDP_MAX_PACKET)
        except (TimeoutError, ConnectionError):
            return None

    def close(self) -> None:
        self._sock.close()


def server_endpoint(address: str) -> ServerEndpoint:
    """The server's endpoint bound to ``address``; port 0 picks a free port (the endpoint's
    ``address`` says which)."""
    scheme, host, port = parse_address(address)
    return _ZmqServer(host, port) if scheme == "tcp" else _UdpServer(host, port)


def client_endpoint(address: str) -> ClientEndpoint:
    """A client's endpoint connected to the server at ``address``."""
    scheme, host, port = parse_address(address)
    return _ZmqClient(host, port) if scheme == "tcp" else _UdpClient(host, port)
