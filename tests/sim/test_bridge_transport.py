"""dqcontrol/sim/bridge_transport.py: the address forms, and both endpoints (ZMQ over TCP,
UDP datagrams) carrying packets both ways on the loopback, timing out and framing."""

from __future__ import annotations

import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.sim.bridge import BridgeDriver
from dqcontrol.sim.bridge_transport import (
    BadFraming,
    client_endpoint,
    parse_address,
    server_endpoint,
)

zmq = pytest.importorskip("zmq")

#: Both transports, for the tests that hold for either.
TRANSPORTS = pytest.mark.parametrize("transport", ["tcp", "udp"])


@pytest.mark.parametrize(
    "address", ["127.0.0.1:5555", "http://127.0.0.1:5555", "udp://127.0.0.1", "udp://:5555",
                "tcp://127.0.0.1:port", "udp://127.0.0.1:70000", 5555],
)  # fmt: skip
def test_a_bad_address_says_which_forms_are_accepted(address):
    with pytest.raises(ParameterError, match=r"tcp://HOST:PORT|port must be 0\.\.65535"):
        parse_address(address)
    with pytest.raises(ParameterError):
        BridgeDriver(address, hello_timeout_s=0.1)


@pytest.mark.parametrize(
    ("address", "parts"),
    [
        ("tcp://127.0.0.1:5555", ("tcp", "127.0.0.1", 5555)),
        ("udp://localhost:0", ("udp", "localhost", 0)),
        ("udp://10.0.0.2:65535", ("udp", "10.0.0.2", 65535)),
    ],
)
def test_the_two_address_forms_are_split_into_scheme_host_and_port(address, parts):
    assert parse_address(address) == parts


@TRANSPORTS
def test_packets_go_both_ways_and_the_server_names_its_port(transport):
    server = server_endpoint(f"{transport}://127.0.0.1:0")
    client = client_endpoint(server.address)
    try:
        scheme, host, port = parse_address(server.address)
        assert (scheme, host) == (transport, "127.0.0.1") and port > 0
        assert client.lossy == (transport == "udp")
        packets = [b"DQ", bytes(range(256)) * 40]  # 2 and 10240 bytes
        for packet in packets:
            client.send(packet)
            got = server.receive(2.0)
            assert got is not None
            peer, data = got
            assert data == packet
            server.send(peer, data[::-1])
            assert client.receive(2.0) == packet[::-1]
    finally:
        client.close()
        server.close()


@TRANSPORTS
def test_nothing_sent_is_a_timeout_not_an_error(transport):
    server = server_endpoint(f"{transport}://127.0.0.1:0")
    client = client_endpoint(server.address)
    try:
        assert server.receive(0.01) is None
        assert client.receive(0.01) is None
    finally:
        client.close()
        server.close()


def test_a_zmq_message_of_two_frames_is_bad_framing():
    server = server_endpoint("tcp://127.0.0.1:0")
    sock = zmq.Context.instance().socket(zmq.DEALER)
    sock.connect(server.address)
    try:
        sock.send_multipart([b"two", b"frames"])
        with pytest.raises(BadFraming):
            server.receive(2.0)
    finally:
        sock.close(linger=0)
        server.close()
