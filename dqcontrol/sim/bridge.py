r"""A process bridge: a joint driver served on a socket, and the driver that talks to it.

:class:`SimServer` serves any simulated driver (e.g. :class:`~dqcontrol.sim.MujocoDriver`)
at an address, ``tcp://HOST:PORT`` (a ZMQ ROUTER socket) or ``udp://HOST:PORT`` (UDP
datagrams, the transport for periods of a few milliseconds:
:mod:`~dqcontrol.sim.bridge_transport`); :class:`BridgeDriver` is a
:class:`~dqcontrol.sim.driver.JointDriver` that connects to it, so that
:func:`~dqcontrol.sim.run_loop` runs the controller in another process exactly as
in-process. The server steps its simulation by
one period per command (stepped, simulated time); the client may pace itself on the wall
clock (``run_loop(..., realtime=True)``).

Wire format, version 1 (every number little-endian; docs/drivers.md has the table):

- header, 12 bytes: ``b"DQ"``, version ``u8`` (1), kind ``u8``, sequence number ``u32``,
  joint count ``n`` ``u16``, status ``u16``;
- ``HELLO`` (1, client → server): the header only; answered by ``WELCOME`` (2): the
  period ``f64`` [s] and the joint names, UTF-8, separated by ``\0``;
- ``RESET`` (3): ``q0[n]`` ``f64`` [rad]; answered by ``STATE``;
- ``COMMAND`` (4): ``qd[n]`` [rad/s], ``s``, ``σ`` [s], all ``f64``; status 0 = track,
  1 = brake, 2 = hold (zero velocity); answered by ``STATE``;
- ``STATE`` (5, server → client): ``t`` [s], ``q[n]``, ``qd[n]``, ``torque[n]``,
  ``torque_peak[n]``, all ``f64``; its sequence number is that of the message it answers;
- ``ERROR`` (6, server → client): the reason, UTF-8; status: the reason's code (1: a bad
  packet, 2: the driver failed, 3: a reflex — the command was refused, the arm is stopped,
  motion is refused until ``RESET``; its sequence number is that of the command);
- ``DESCRIBE`` (7, client → server): the header only; answered by ``DESCRIPTION`` (8): a
  JSON object, UTF-8, describing what is served (:meth:`SimServer.describe`: robot, joints,
  period, simulator, drive, faults, server and protocol versions). A server that does not
  know ``DESCRIBE`` answers ``ERROR``; the client then records no description.

Both ends reject a packet of the wrong length, magic, version, kind or joint count, with a
non-finite number, or (client) with a sequence number other than the one awaited (a
duplicate, a reordered or a late reply), and count it by reason; neither ever raises on
one. The server answers a repeated command (same sequence number as the last executed)
with the same state, without stepping again. A server with reflexes
(:class:`~dqcontrol.sim.reflexes.Reflexes`) checks every command like a real arm; the
client raises :class:`ReflexError` at a reflex (from the read, hold or send that follows
the refused command, since a command's answer is awaited there).
"""

from __future__ import annotations

import json
import struct
import threading
import time
from collections import Counter
from typing import Any

import numpy as np

from dqcontrol._blas import single_blas_thread
from dqcontrol._gc import young_gc_only
from dqcontrol.errors import DQControlError, ParameterError
from dqcontrol.sim.bridge_transport import (
    BadFraming,
    client_endpoint,
    parse_address,
    server_endpoint,
)
from dqcontrol.sim.mujoco_sim import Measurement
from dqcontrol.sim.reflexes import ReflexDriver, ReflexError, Reflexes

__all__ = [
    "HEADER",
    "PROTOCOL_VERSION",
    "BridgeDriver",
    "BridgeError",
    "ReflexError",
    "SimServer",
    "decode",
    "encode_command",
    "encode_state",
    "run_origin",
]

PROTOCOL_VERSION = 1
MAGIC = b"DQ"
#: magic, version, kind, sequence number, joint count, status.
HEADER = struct.Struct("<2sBBIHH")
HELLO, WELCOME, RESET, COMMAND, STATE, ERROR, DESCRIBE, DESCRIPTION = 1, 2, 3, 4, 5, 6, 7, 8
TRACK, BRAKE, HOLD = 0, 1, 2
#: ``ERROR`` status of a reflex (a refused command; the arm stopped until ``RESET``).
REFLEX = 3
#: How often a lossy link repeats an unanswered ``HELLO`` or ``DESCRIBE`` [s].
REPEAT_S = 0.05
_KINDS = {HELLO, WELCOME, RESET, COMMAND, STATE, ERROR, DESCRIBE, DESCRIPTION}


class BridgeError(DQControlError):
    """The bridge could not be set up (no server, no answer to ``HELLO``, a bad address)."""


class PacketError(ValueError):
    """A packet that is rejected; ``reason`` names why (the counters' key)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def _header(kind: int, seq: int, n: int, status: int = 0) -> bytes:
    return HEADER.pack(MAGIC, PROTOCOL_VERSION, kind, seq & 0xFFFFFFFF, n, status)


def _floats(*arrays) -> bytes:
    return np.concatenate([np.atleast_1d(np.asarray(a, dtype="<f8")) for a in arrays]).tobytes()


def encode_command(seq: int, qd: np.ndarray, s: float, sigma: float, status: int = TRACK) -> bytes:
    """A ``COMMAND`` packet."""
    return _header(COMMAND, seq, len(qd), status) + _floats(qd, s, sigma)


def encode_state(seq: int, m: Measurement, status: int = 0) -> bytes:
    """A ``STATE`` packet answering message ``seq``."""
    return _header(STATE, seq, len(m.q), status) + _floats(
        m.t_s, m.q, m.qd, m.torque, m.torque_peak
    )


def _body_size(kind: int, n: int) -> int | None:
    return {
        HELLO: 0,
        DESCRIBE: 0,
        RESET: 8 * n,
        COMMAND: 8 * (n + 2),
        STATE: 8 * (1 + 4 * n),
    }.get(kind)


def decode(packet: bytes, n_expected: int | None = None) -> tuple[int, int, int, object]:
    """``(kind, seq, status, body)`` of a packet; ``body``: the float array (``RESET``,
    ``COMMAND``, ``STATE``), ``(period, names)`` (``WELCOME``), the text (``ERROR``), a dict
    (``DESCRIPTION``) or ``None`` (``HELLO``, ``DESCRIBE``).

    Raises:
        PacketError: the packet is malformed (its ``reason`` says how).
    """
    if len(packet) < HEADER.size:
        raise PacketError("short packet")
    magic, version, kind, seq, n, status = HEADER.unpack_from(packet)
    if magic != MAGIC:
        raise PacketError("bad magic")
    if version != PROTOCOL_VERSION:
        raise PacketError("wrong version")
    if kind not in _KINDS:
        raise PacketError("unknown kind")
    body = packet[HEADER.size :]
    if kind == ERROR:
        return kind, seq, status, body.decode("utf-8", "replace")
    if kind == WELCOME:
        if len(body) < 8:
            raise PacketError("wrong length")
        period = struct.unpack_from("<d", body)[0]
        names = tuple(body[8:].decode("utf-8", "replace").split("\0")) if n else ()
        if len(names) != n or not (np.isfinite(period) and period > 0):
            raise PacketError("bad welcome")
        return kind, seq, status, (period, names)
    if kind == DESCRIPTION:
        return kind, seq, status, _description(body)
    if n_expected is not None and kind != HELLO and n != n_expected:
        raise PacketError("wrong joint count")
    size = _body_size(kind, n)
    if size is None or len(body) != size:
        raise PacketError("wrong length")
    if kind in (HELLO, DESCRIBE):
        return kind, seq, status, None
    values = np.frombuffer(body, dtype="<f8").astype(float)
    if not np.isfinite(values[: None if kind != STATE else 1 + 2 * n]).all():
        raise PacketError("non-finite value")
    return kind, seq, status, values


def _description(body: bytes) -> dict:
    """A ``DESCRIPTION`` body: a JSON object (PacketError ``"bad description"`` if not)."""
    try:
        value = json.loads(body.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise PacketError("bad description") from None
    if not isinstance(value, dict):
        raise PacketError("bad description")
    return value


class SimServer:
    """Serves a simulated driver on ``address``.

    Args:
        driver: a simulated driver (``reset``, ``write``, ``hold``, ``read``, ``period_s``).
        address: ``tcp://HOST:PORT`` (ZMQ) or ``udp://HOST:PORT`` (datagrams); port 0
            picks a free port (:attr:`address` says which).
        description: entries added to :meth:`describe` (e.g. the robot's name); JSON
            values.
        reflexes: check every command like a real arm
            (:class:`~dqcontrol.sim.reflexes.Reflexes`); ``None``: execute any command.

    Raises:
        ParameterError: a description that JSON cannot carry.

    :meth:`serve` answers messages until :meth:`stop` (or ``max_messages``); every
    rejected packet is counted in :attr:`rejected` by reason and answered with ``ERROR``.
    """

    def __init__(
        self,
        driver,
        address: str = "tcp://127.0.0.1:0",
        description: dict | None = None,
        reflexes: Reflexes | None = None,
    ) -> None:
        self.driver: Any = driver if reflexes is None else ReflexDriver(driver, reflexes)
        self.joint_names = tuple(driver.joint_names)
        self.n = len(self.joint_names)
        self.reflexes = reflexes
        self._description = dict(description or {})
        self._described = self._encode_description()
        self._endpoint = server_endpoint(address)
        #: The address the server listens on.
        self.address = self._endpoint.address
        self.rejected: Counter[str] = Counter()
        self.served = 0
        self._stop = threading.Event()
        self._last_seq: int | None = None
        self._last_state: bytes | None = None

    def describe(self) -> dict:
        """What is served, for the client's run log: ``server``, ``dqcontrol_version``,
        ``protocol_version``, ``period_s``, ``joint_names``, the driver's ``meta``
        (``simulator``, ``physics_dt_s``, ``motor``, fault settings ...) and the entries
        given as ``description``."""
        from dqcontrol import __version__

        return {
            "server": "dqcontrol sim-server",
            "dqcontrol_version": __version__,
            "protocol_version": PROTOCOL_VERSION,
            "period_s": float(self.driver.period_s),
            "joint_names": list(self.joint_names),
            **dict(getattr(self.driver, "meta", {})),
            **self._description,
        }

    def _encode_description(self) -> bytes:
        description = self.describe()
        try:
            text = json.dumps(description, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise ParameterError(
                f"the server's description must be JSON values: {exc} (in {description!r})"
            ) from None
        return _header(DESCRIPTION, 0, self.n) + text.encode("utf-8")

    def stop(self) -> None:
        """Ask :meth:`serve` to return (from another thread)."""
        self._stop.set()

    def close(self) -> None:
        """Stop serving and close the socket (idempotent)."""
        self._endpoint.close()

    def serve(self, *, max_messages: int | None = None, poll_ms: int = 50) -> None:
        """Answer messages until :meth:`stop` or ``max_messages`` have been handled, with one
        BLAS thread (a pool of them, spinning after each call, would take the cores the
        client and its planner run on) and the garbage collector kept to the objects made
        while serving (a full collection would hold an answer for milliseconds)."""
        with single_blas_thread(), young_gc_only():
            self._serve(max_messages, poll_ms)

    def _serve(self, max_messages: int | None, poll_ms: int) -> None:
        handled = 0
        while not self._stop.is_set() and (max_messages is None or handled < max_messages):
            try:
                message = self._endpoint.receive(1e-3 * poll_ms)
            except BadFraming:
                handled += 1
                self.rejected["bad framing"] += 1
                continue
            if message is None:
                continue
            handled += 1
            peer, packet = message
            for answer in self.answers(packet):
                self._endpoint.send(peer, answer)

    def answers(self, packet: bytes) -> list[bytes]:
        """The packets sent back for ``packet``: :meth:`handle`'s one answer (a subclass may
        drop, repeat or delay answers to test a client)."""
        return [self.handle(packet)]

    def handle(self, packet: bytes) -> bytes:
        """The answer to one packet (never raises)."""
        try:
            kind, seq, status, body = decode(packet, self.n)
            if kind == HELLO:
                names = "\0".join(self.joint_names).encode()
                return (
                    _header(WELCOME, seq, self.n) + struct.pack("<d", self.driver.period_s) + names
                )
            if kind == DESCRIBE:
                return _header(DESCRIPTION, seq, self.n) + self._described[HEADER.size :]
            if kind == RESET:
                m = self.driver.reset(body)
            elif kind == COMMAND:
                if seq == self._last_seq and self._last_state is not None:
                    self.rejected["duplicate"] += 1
                    return self._last_state
                if status == HOLD:
                    self.driver.hold()
                else:
                    assert isinstance(body, np.ndarray), "decode gives a command's floats"
                    self.driver.write(body[: self.n])
                m = self.driver.read()
            else:
                raise PacketError("unexpected kind")
        except PacketError as exc:
            self.rejected[exc.reason] += 1
            return _header(ERROR, 0, 0, 1) + exc.reason.encode()
        except ReflexError as exc:
            self.rejected["reflex"] += 1
            return _header(ERROR, seq, 0, REFLEX) + str(exc).encode()
        except Exception as exc:  # noqa: BLE001 - the server reports, it does not stop
            self.rejected["driver error"] += 1
            return _header(ERROR, 0, 0, 2) + f"{type(exc).__name__}: {exc}".encode()
        self.served += 1
        self._last_seq, self._last_state = seq, encode_state(seq, m)
        return self._last_state

    def __enter__(self) -> SimServer:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
        self.close()


class BridgeDriver:
    """A joint driver whose arm is a :class:`SimServer` in another process or thread.

    Args:
        address: the server's ``tcp://HOST:PORT`` or ``udp://HOST:PORT``.
        timeout_s: how long ``read``/``reset``/``hold`` wait for the state answering the
            last message [s]; without it the measurement is not renewed (the loop's
            watchdog counts that). ``write`` only sends: the server steps while the loop
            waits for its period, as a real arm moves while its controller waits.
        hello_timeout_s: how long the first contact may take [s].

    Raises:
        BridgeError: no ``WELCOME`` within ``hello_timeout_s``.

    Attributes:
        server: the server's description (:meth:`SimServer.describe`), ``{}`` if it gave
            none; the run log's ``meta["server"]``.
        rejected: received packets rejected, by reason (``"stale sequence"`` for
            duplicated, reordered or late replies, ``"wrong length"``, ``"wrong version"``,
            ``"non-finite value"``, ``"wrong joint count"``, ``"server error: …"`` ...).
        timeouts: commands whose state did not arrive within ``timeout_s``.
        reflex: the server's message when its reflex fired (``""``: it did not); a
            command it refuses raises :class:`ReflexError` from the next read, hold or
            send.
    """

    def __init__(
        self, address: str, *, timeout_s: float = 0.5, hello_timeout_s: float = 5.0
    ) -> None:
        parse_address(address)
        self.address = address
        self.timeout_s = float(timeout_s)
        self._link = client_endpoint(address)
        self.rejected: Counter[str] = Counter()
        self.timeouts = 0
        self.reflex = ""
        self._seq = 0
        self._last: Measurement | None = None
        #: the command (or reset) whose answering state has not been read yet
        self._pending: bytes | None = None
        self.n = 0
        body = self._request(_header(HELLO, 0, 0), WELCOME, hello_timeout_s)
        if body is None:
            self.close()
            raise BridgeError(f"no answer from a dqcontrol sim-server at {self.address}")
        self.period_s, self.joint_names = body
        self.n = len(self.joint_names)
        self.server = self._describe(hello_timeout_s)

    def _describe(self, timeout_s: float) -> dict:
        """The server's ``DESCRIPTION`` (``{}`` if it answers ``ERROR`` or nothing)."""
        packet = _header(DESCRIBE, self._next(), self.n)
        body = self._request(packet, DESCRIPTION, timeout_s, error_ends=True)
        return {} if body is None else body

    @property
    def meta(self) -> dict:
        """``simulator`` (``"bridge"``), ``address`` and the server's description."""
        return {"simulator": "bridge", "address": self.address, "server": dict(self.server)}

    def report(self) -> dict:
        """Counters for the run log: rejected packets by reason, timeouts, and the server's
        reflex (``"reflex"``, only when one fired)."""
        report: dict = {"rejected": dict(self.rejected), "timeouts": self.timeouts}
        if self.reflex:
            report["reflex"] = self.reflex
        return report

    def close(self) -> None:
        """Close the connection (idempotent)."""
        self._link.close()

    def _request(self, packet: bytes, want: int, timeout_s: float, error_ends: bool = False) -> Any:
        """Send ``packet`` and wait for its answer (:meth:`_answer`)."""
        self._link.send(packet)
        return self._answer(packet, want, timeout_s, error_ends)

    def _answer(self, packet: bytes, want: int, timeout_s: float, error_ends: bool = False) -> Any:
        """Wait for the answer to ``packet`` (sent): the kind ``want`` carrying its
        sequence number; returns its body, or ``None`` after ``timeout_s`` (or at an
        ``ERROR`` if ``error_ends``). On a lossy link an idempotent request (``HELLO``,
        ``DESCRIBE``) is sent again every :data:`REPEAT_S` while no answer comes."""
        header = HEADER.unpack_from(packet)
        seq = header[3]
        repeat = self._link.lossy and header[2] in (HELLO, DESCRIBE)
        now = time.perf_counter()
        deadline, again = now + timeout_s, now + REPEAT_S
        while (left := deadline - time.perf_counter()) > 0:
            raw = self._link.receive(min(left, again - time.perf_counter()) if repeat else left)
            if raw is None:
                if repeat and time.perf_counter() >= again:
                    self._link.send(packet)
                    again += REPEAT_S
                continue
            try:
                kind, got, status, body = decode(raw, self.n or None)
            except PacketError as exc:
                self.rejected[exc.reason] += 1
                continue
            if kind == ERROR and status == REFLEX and got == seq:
                self.reflex = str(body)
                raise ReflexError(f"the sim-server's {body}")
            if kind == ERROR:
                self.rejected[f"server error: {body}"] += 1
                if error_ends:
                    return None
                continue
            if kind in (WELCOME, DESCRIPTION) and kind != want:
                continue  # a repeated request's second answer
            if kind != want:
                self.rejected["unexpected kind"] += 1
                continue
            if got != seq:
                self.rejected["stale sequence"] += 1
                continue
            return body
        self.timeouts += 1
        return None

    def _send(self, packet: bytes) -> None:
        """Send a command; its state is awaited by the next :meth:`read` (or send)."""
        self._settle()
        self._link.send(packet)
        self._pending = packet

    def _settle(self) -> None:
        """Wait (at most ``timeout_s``) for the state answering the command in flight."""
        packet, self._pending = self._pending, None
        if packet is None:
            return
        values = self._answer(packet, STATE, self.timeout_s)
        if values is None:
            return
        n = self.n
        self._last = Measurement(
            t_s=float(values[0]),
            q=values[1 : 1 + n],
            qd=values[1 + n : 1 + 2 * n],
            torque=values[1 + 2 * n : 1 + 3 * n],
            torque_peak=values[1 + 3 * n :],
        )

    def _next(self) -> int:
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        return self._seq

    def reset(self, q0: np.ndarray) -> Measurement:
        """Reset the served simulation at ``q0`` [rad] (server's joint order)."""
        self.reflex = ""
        self._send(_header(RESET, self._next(), self.n) + _floats(q0))
        self._settle()
        if self._last is None:
            raise BridgeError(f"no answer to reset from {self.address}")
        return self._last

    def read(self) -> Measurement:
        """The state answering the last command (waited for, at most ``timeout_s``; after a
        timeout the latest state that came)."""
        self._settle()
        if self._last is None:
            raise BridgeError(f"no measurement from {self.address} yet (reset first)")
        return self._last

    def write(self, qd_command: np.ndarray) -> None:
        """Send the joint-velocity command [rad/s] and return: the server steps while the
        caller waits for its period, and :meth:`read` takes the state that answers it."""
        self._send(encode_command(self._next(), qd_command, 1.0, 0.0))

    def hold(self) -> None:
        """Ask the server to hold the present position (and wait for its answer)."""
        self._send(encode_command(self._next(), np.zeros(self.n), 0.0, 0.0, HOLD))
        self._settle()

    def __repr__(self) -> str:
        return f"BridgeDriver({self.address!r}, n={self.n})"


def run_origin(meta: dict) -> str:
    """Where a run's states came from, in one line, from its log's ``meta``: the simulator
    in this process, or the sim-server (address, version, robot, drive, period, payload)
    of a bridged run."""
    if meta.get("simulator") != "bridge":
        return f"{meta.get('simulator', 'an unknown simulator')} in this process"
    address = meta.get("address", "an unknown address")
    server = meta.get("server") or {}
    if not server:
        return f"a sim-server at {address} (it gave no description)"
    details = [str(server[key]) for key in ("robot", "simulator") if server.get(key) is not None]
    if server.get("motor"):
        details.append(f"{server['motor']} drive")
    if server.get("period_s"):
        details.append(f"T = {server['period_s']:g} s")
    if server.get("payload_kg"):
        details.append(f"unknown payload {server['payload_kg']:g} kg")
    if server.get("effort_scale", 1.0) != 1.0:
        details.append(f"torque limits × {server['effort_scale']:g}")
    name = f"{server.get('server', 'a sim-server')} {server.get('dqcontrol_version', '')}"
    return f"{name.strip()} at {address}: {', '.join(details) or 'no details'}"
