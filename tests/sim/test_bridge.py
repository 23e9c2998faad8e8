"""The process bridge on the loopback address: equal to the in-process run, wall-clock pacing,
and bad, dropped, repeated, reordered and late packets, and a server that disappears."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from sim.bridge_links import TRANSPORTS, exchange, header, socket_port

import dqcontrol
from dqcontrol.controllers import LocalController
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim import (
    KinematicDriver,
    MujocoDriver,
    PayloadDriver,
    TorqueLimitDriver,
    run_loop,
)
from dqcontrol.sim.bridge import (
    COMMAND,
    DESCRIBE,
    DESCRIPTION,
    HEADER,
    BridgeDriver,
    BridgeError,
    SimServer,
    decode,
    encode_command,
    run_origin,
)
from dqcontrol.sim.bridge_transport import client_endpoint
from dqcontrol.trajectories import Circle

zmq = pytest.importorskip("zmq")


def _at(transport: str) -> str:
    """The loopback address of a server on ``transport``, at a free port."""
    return f"{transport}://127.0.0.1:0"


class Served:
    """A server in a thread, stopped and closed on exit."""

    def __init__(self, server: SimServer) -> None:
        self.server = server
        self.thread = threading.Thread(target=server.serve, daemon=True)

    def __enter__(self) -> SimServer:
        self.thread.start()
        return self.server

    def __exit__(self, *exc) -> None:
        self.server.stop()
        self.thread.join(timeout=5.0)
        self.server.close()


@TRANSPORTS
def test_a_stepped_run_over_the_socket_equals_the_in_process_run(lbr4p, transport):
    ref = run_loop(
        LocalController(lbr4p, Circle(1.0), 0.05), MujocoDriver(lbr4p, 0.05), q0=LBR4P_Q0
    )
    with Served(SimServer(MujocoDriver(lbr4p, 0.05), _at(transport))) as server:
        client = BridgeDriver(server.address)
        res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), client, q0=LBR4P_Q0)
        client.close()
    assert len(res.log) == len(ref.log) and res.metrics.completed
    for name in ("t_s", "q", "qd_measured", "qd_command", "torque", "torque_peak", "sigma"):
        np.testing.assert_allclose(getattr(res.log, name), getattr(ref.log, name), atol=1e-12)
    assert res.log.meta["simulator"] == "bridge"
    assert res.log.meta["driver_report"] == {"rejected": {}, "timeouts": 0}


#: A separate process that says "ready", sleeps to absolute targets every millisecond for
#: ``argv[1]`` seconds and prints how late it woke up [ms]: the host's own scheduling
#: latency, measured while the loop runs.
CANARY = """
import json, sys, time
duration = float(sys.argv[1])
print("ready", flush=True)
late, start, k = [], time.perf_counter(), 0
while k * 1e-3 < duration:
    k += 1
    target = start + k * 1e-3
    left = target - time.perf_counter()
    if left > 0:
        time.sleep(left)
    late.append(1e3 * (time.perf_counter() - target))
late.sort()
print(json.dumps({"median_ms": late[len(late) // 2], "p99_ms": late[int(0.99 * (len(late) - 1))],
                  "max_ms": late[-1]}))
"""
#: The host is "not quiet" when the canary woke up this late [ms] during the run: a quarter
#: of the 10 ms period, for one thread, where a sample waits on five in sequence (the loop,
#: the two ZMQ I/O threads, the server, the loop again).
HOST_STALL_MS = 2.5


def _sim_server(transport: str, port: int, period_s: float, messages: int) -> subprocess.Popen:
    """``dqcontrol sim-server`` in its own process, from this dqcontrol (bounded by
    ``--max-messages``): a server thread here would share the interpreter lock with the
    loop and add its own stalls to the round trip."""
    code = "from dqcontrol.cli import main; raise SystemExit(main())"
    root = str(Path(dqcontrol.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen(
        [sys.executable, "-c", code, "sim-server", "--port", str(port), "--period",
         str(period_s), "--max-messages", str(messages), "--transport", transport],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
    )  # fmt: skip


@TRANSPORTS
def test_at_100_hz_on_the_wall_clock_no_deadline_is_missed(lbr4p, transport):
    with socket_port(transport) as port:
        pass
    server = _sim_server(transport, port, 0.01, 400)
    try:
        client = BridgeDriver(f"{transport}://127.0.0.1:{port}", hello_timeout_s=60.0)
        canary = subprocess.Popen(
            [sys.executable, "-c", CANARY, "2.5"], stdout=subprocess.PIPE, text=True
        )
        assert canary.stdout.readline() == "ready\n"  # started: its start-up is not the run's
        start = time.perf_counter()
        res = run_loop(
            LocalController(lbr4p, Circle(2.0), 0.01), client, q0=LBR4P_Q0, realtime=True
        )
        wall = time.perf_counter() - start
        client.close()
        host = json.loads(canary.communicate(timeout=30.0)[0])  # bounded: 2.5 s of sleeps
    finally:
        server.kill()
        server.wait(timeout=10.0)
    stop = res.log.meta["stop"]
    report = (
        f"100 Hz over the bridge, {len(res.log)} samples: start jitter median "
        f"{stop['jitter_median_ms']:.3f} / p99 {stop['jitter_p99_ms']:.3f} / max "
        f"{stop['jitter_max_ms']:.3f} ms, lateness max {stop['lateness_max_ms']:.2f} ms, "
        f"missed deadlines {stop['missed_deadlines']}; host wake-up latency median "
        f"{host['median_ms']:.3f} / p99 {host['p99_ms']:.3f} / max {host['max_ms']:.3f} ms"
    )
    print(report)
    if res.reason == "deadline" and host["max_ms"] >= HOST_STALL_MS:
        pytest.skip(f"the host stalled a sleeping thread {host['max_ms']:.1f} ms: {report}")
    assert stop["missed_deadlines"] == 0 and stop["reason"] == "end", report
    assert res.metrics.completed and wall >= 0.01 * (len(res.log) - 1)
    assert stop["lateness_max_ms"] < 0.0 and stop["stop_periods"] >= 1  # the stop on the clock too
    assert stop["jitter_max_ms"] >= 0.0  # a sample never starts before its time


@TRANSPORTS
def test_the_server_counts_bad_packets_and_keeps_serving(lbr4p, transport):
    nan_cmd = encode_command(1, np.full(7, np.nan), 1.0, 0.0)
    bad = {
        "short packet": b"DQ",
        "bad magic": header(COMMAND, 1, 7, magic=b"XX") + bytes(72),
        "wrong version": header(COMMAND, 1, 7, version=9) + bytes(72),
        "unknown kind": header(77, 1, 7) + bytes(72),
        "wrong length": header(COMMAND, 1, 7) + bytes(40),
        "wrong joint count": encode_command(1, np.zeros(6), 1.0, 0.0),
        "non-finite value": nan_cmd,
    }
    with Served(SimServer(KinematicDriver(lbr4p, 0.05), _at(transport))) as server:
        link = client_endpoint(server.address)
        for packet in bad.values():
            kind, _, _, reason = decode(exchange(link, packet))
            assert kind == 6 and reason in bad
        link.close()
        if transport == "tcp":  # a ZMQ message of two frames; a datagram is one packet
            sock = zmq.Context.instance().socket(zmq.DEALER)
            sock.connect(server.address)
            sock.send_multipart([b"two", b"frames"])
            sock.close(linger=1000)
        client = BridgeDriver(server.address)
        res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), client, q0=LBR4P_Q0)
        client.close()
        assert res.metrics.completed
        time.sleep(0.1)
        assert {k: server.rejected[k] for k in bad} == dict.fromkeys(bad, 1)
        assert server.rejected["bad framing"] == (transport == "tcp")


@TRANSPORTS
def test_a_repeated_command_is_answered_without_stepping_again(lbr4p, transport):
    with Served(SimServer(KinematicDriver(lbr4p, 0.05), _at(transport))) as server:
        client = BridgeDriver(server.address)
        client.reset(LBR4P_Q0)
        link = client_endpoint(server.address)
        exchange(link, header(3, 1, 7) + np.asarray(LBR4P_Q0, "<f8").tobytes())
        cmd = encode_command(5, np.full(7, 0.1), 1.0, 0.0)
        states = [decode(exchange(link, cmd), 7)[3] for _ in range(2)]
        link.close()
        client.close()
        np.testing.assert_array_equal(states[0], states[1])
        assert states[0][0] == pytest.approx(0.05) and server.rejected["duplicate"] == 1


class Chaos(SimServer):
    """A server whose answers are corrupted, repeated, reordered, delayed or dropped by a
    plan keyed by the command count; it records every command it receives."""

    def __init__(self, driver, plan, transport: str = "tcp") -> None:
        super().__init__(driver, _at(transport))
        self.plan = plan
        self.commands: list[np.ndarray] = []
        self._held: bytes | None = None

    def answers(self, packet: bytes) -> list[bytes]:
        kind = HEADER.unpack_from(packet)[2] if len(packet) >= HEADER.size else 0
        answer = self.handle(packet)
        if kind != COMMAND:
            return [answer]
        self.commands.append(decode(packet, self.n)[3][: self.n].copy())
        action = self.plan(len(self.commands))
        n = self.n
        if action == "garbage":
            nan = bytearray(answer)
            struct.pack_into("<d", nan, HEADER.size + 8, float("nan"))  # q[0]
            wrong_version = bytearray(answer)
            wrong_version[2] = 2
            return [answer[:-8], bytes(wrong_version), bytes(nan), answer[:8] + b"\x00" * 4, answer]
        if action == "joints":
            seq = HEADER.unpack_from(answer)[3]
            return [HEADER.pack(b"DQ", 1, 5, seq, n - 1, 0) + bytes(8 * (1 + 4 * (n - 1))), answer]
        if action == "repeat":
            return [answer, answer]
        if action == "hold back":  # answered late, after the next command's answer
            self._held = answer
            return []
        if action == "release":
            late, self._held = self._held, None
            return [answer, late]
        if action == "drop":
            return []
        return [answer]


@TRANSPORTS
def test_the_client_rejects_bad_late_and_repeated_packets_with_reasons(lbr4p, transport):
    plan = {3: "garbage", 5: "joints", 7: "repeat", 9: "hold back", 10: "release"}.get
    with Served(Chaos(KinematicDriver(lbr4p, 0.05), plan, transport)) as server:
        client = BridgeDriver(server.address, timeout_s=0.2)
        res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), client, q0=LBR4P_Q0)
        client.close()
    report = res.log.meta["driver_report"]
    assert report["rejected"] == {
        "wrong length": 1,
        "wrong version": 1,
        "non-finite value": 1,
        "wrong joint count": 2,  # a header with n = 6, and one truncated to n = 0
        "stale sequence": 2,  # the repeated answer of command 7 and the late one of 9
    }
    assert report["timeouts"] == 1  # command 9: its answer came too late
    assert res.metrics.completed and not res.interrupted
    _assert_safe(server.commands, lbr4p)


def _assert_safe(commands, lbr4p, a_max=10.0, period=0.05):
    u = np.array(commands)
    assert np.isfinite(u).all()
    assert (np.abs(u) <= lbr4p.limits.qd_max + 1e-9).all()
    assert np.abs(np.diff(u, axis=0)).max() <= a_max * period + 1e-9


@TRANSPORTS
def test_dropped_answers_make_the_loop_brake_and_hold(lbr4p, transport):
    plan = lambda k: "drop" if k >= 8 else None  # noqa: E731
    with Served(Chaos(KinematicDriver(lbr4p, 0.05), plan, transport)) as server:
        client = BridgeDriver(server.address, timeout_s=0.05)
        start = time.perf_counter()
        res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), client, q0=LBR4P_Q0)
        took = time.perf_counter() - start
        client.close()
    assert res.reason == "stale" and res.log.meta["stop"]["reason"] == "stale"
    assert "not renewed for 3 periods" in res.note and took < 5.0
    task = int(np.count_nonzero(~res.log.stopping))
    assert task == 8 + 2  # the last two samples from a measurement 1-2 periods old
    stop = res.log.meta["stop"]
    assert stop["at_rest"] and stop["stop_periods"] == len(res.log) - task >= 1
    # every sample's command (the stop's too, from dead reckoning), then the hold
    assert len(server.commands) == len(res.log) + stop["brake_periods"] + 1
    assert not server.commands[-1].any() and not server.commands[-2].any()
    _assert_safe(server.commands, lbr4p)


@TRANSPORTS
def test_a_server_that_disappears(lbr4p, transport):
    served = Served(SimServer(KinematicDriver(lbr4p, 0.05), _at(transport)))
    with served as server:
        client = BridgeDriver(server.address, timeout_s=0.05)

        def vanish(k, _driver, _result):
            if k == 5:
                server.stop()
                served.thread.join(timeout=5.0)

        res = run_loop(
            LocalController(lbr4p, Circle(1.0), 0.05), client, q0=LBR4P_Q0, on_sample=vanish
        )
        client.close()
    assert res.reason == "stale" and np.count_nonzero(~res.log.stopping) <= 9
    assert res.log.meta["driver_report"]["timeouts"] >= 3


class Silent(SimServer):
    """A server that does not know ``DESCRIBE`` (or answers it with a broken description)."""

    def __init__(self, driver, answer: str) -> None:
        super().__init__(driver)
        self.answer = answer

    def handle(self, packet: bytes) -> bytes:
        if len(packet) >= HEADER.size and HEADER.unpack_from(packet)[2] == DESCRIBE:
            if self.answer == "unknown":
                return header(6, 0, 0, 1) + b"unknown kind"
            return header(DESCRIPTION, HEADER.unpack_from(packet)[3], self.n) + b"[1, 2]"
        return super().handle(packet)


@TRANSPORTS
def test_the_server_describes_what_it_serves(lbr4p, transport):
    drv = TorqueLimitDriver(PayloadDriver(MujocoDriver(lbr4p, 0.01), 3.0), 0.5)
    with Served(SimServer(drv, _at(transport), description={"robot": "lbr4p"})) as server:
        client = BridgeDriver(server.address)
        client.close()
    described = client.server
    assert described["robot"] == "lbr4p" and described["joint_names"] == list(lbr4p.joint_names)
    assert described["period_s"] == 0.01 and described["simulator"] == "mujoco"
    assert described["motor"] == "velocity" and described["physics_dt_s"] == 0.001
    assert described["payload_kg"] == 3.0 and described["effort_scale"] == 0.5
    assert client.meta["server"] == described and client.report()["timeouts"] == 0
    origin = run_origin(client.meta)
    assert origin.startswith("dqcontrol sim-server ") and server.address in origin
    assert "lbr4p, mujoco, velocity drive, T = 0.01 s, unknown payload 3 kg" in origin
    assert "torque limits × 0.5" in origin
    assert run_origin({"simulator": "kinematic"}) == "kinematic in this process"


@pytest.mark.parametrize(
    ("answer", "reason"),
    [("unknown", "server error: unknown kind"), ("not an object", "bad description")],
)
def test_a_server_without_a_description(lbr4p, answer, reason):
    with Served(Silent(KinematicDriver(lbr4p, 0.05), answer)) as server:
        start = time.perf_counter()
        client = BridgeDriver(server.address, timeout_s=0.2, hello_timeout_s=1.0)
        took = time.perf_counter() - start
        res = run_loop(LocalController(lbr4p, Circle(0.5), 0.05), client, q0=LBR4P_Q0)
        client.close()
    assert res.log.meta["server"] == {} and res.metrics.completed
    assert res.log.meta["driver_report"]["rejected"] == {reason: 1}
    assert took < (0.9 if answer == "unknown" else 2.0)  # an error ends the wait at once
    assert "(it gave no description)" in run_origin(res.log.meta)


def test_a_description_must_be_json(lbr4p):
    with pytest.raises(ParameterError, match="description must be JSON values"):
        SimServer(KinematicDriver(lbr4p, 0.05), description={"robot": object()})


@TRANSPORTS
def test_no_server_is_a_clear_error(transport):
    with pytest.raises(BridgeError, match="no answer from a dqcontrol sim-server"):
        BridgeDriver(f"{transport}://127.0.0.1:9", hello_timeout_s=0.2)


def test_a_udp_client_started_before_its_server_repeats_its_hello(lbr4p):
    """A datagram sent before the server is up is lost (ZMQ would queue it): the client
    repeats ``HELLO`` until an answer comes, and the repeats leave no trace."""
    with socket_port("udp") as port:
        pass
    found: list = []
    thread = threading.Thread(
        target=lambda: found.append(BridgeDriver(f"udp://127.0.0.1:{port}", hello_timeout_s=10)),
        daemon=True,
    )
    thread.start()
    time.sleep(0.3)  # several HELLOs lost
    with Served(SimServer(KinematicDriver(lbr4p, 0.05), f"udp://127.0.0.1:{port}")):
        thread.join(timeout=10.0)
        (client,) = found
        res = run_loop(LocalController(lbr4p, Circle(0.5), 0.05), client, q0=LBR4P_Q0)
        client.close()
    assert res.metrics.completed and client.server["joint_names"] == list(lbr4p.joint_names)
    assert res.log.meta["driver_report"] == {"rejected": {}, "timeouts": 0}
