"""``dqcontrol sim-server`` (dqcontrol/cli/sim_server_cmd.py): its options and defaults, the
period a limit profile's robot accepts and the payload, checked before a server starts (exit
code 2), and the command serving a client over both transports. The server itself is tested
in tests/sim/test_bridge.py."""

from __future__ import annotations

import importlib.util
import threading

import pytest
from sim.bridge_links import TRANSPORTS, header, socket_port

from dqcontrol.cli import build_parser, main
from dqcontrol.cli.sim_server_cmd import _check_period
from dqcontrol.controllers import LocalController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim import run_loop
from dqcontrol.sim.bridge import BridgeDriver
from dqcontrol.sim.bridge_transport import client_endpoint
from dqcontrol.trajectories import Circle


def _args(*argv: str):
    return build_parser().parse_args(["sim-server", *argv])


def test_the_defaults_serve_the_lbr4p_on_the_loopback():
    args = _args()
    assert (args.host, args.port, args.transport) == ("127.0.0.1", 5555, "tcp")
    assert (args.period, args.motor, args.payload) == (0.05, "velocity", 0.0)
    assert args.max_messages is None and args.limits is None and args.robot == "lbr4p"
    args = _args("--transport", "udp", "--port", "0", "--motor", "torque", "--payload", "3")
    assert (args.transport, args.port, args.motor, args.payload) == ("udp", 0, "torque", 3.0)


def test_a_period_the_profiles_robot_accepts_passes():
    _check_period(_args("--limits", "franka_panda", "--period", "0.001"))
    _check_period(_args("--period", "0.0123"))  # no profile: any period


def test_a_period_the_profiles_robot_refuses_exits_2(capsys):
    with pytest.raises(SystemExit) as exc:
        _check_period(_args("--limits", "franka_panda", "--period", "0.05"))
    assert exc.value.code == 2
    assert (
        "--period 0.05: the robot of limit profile 'franka_panda' accepts control periods of "
        "0.001 s"
    ) in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "message"),
    [(["--transport", "ipc"], "invalid choice: 'ipc'"), (["--port", "x"], "invalid int")],
)
def test_bad_options_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        _args(*argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


# ---------------------------------------------------------------------- the server started
needs_zmq = pytest.mark.skipif(
    importlib.util.find_spec("zmq") is None, reason="the sim-server bridge needs pyzmq"
)


@needs_zmq
@TRANSPORTS
def test_the_sim_server_command_serves_a_client(lbr4p, capsys, transport):
    with socket_port(transport) as port:
        pass
    done = threading.Event()
    codes = []

    def serve():
        codes.append(
            main(
                [
                    "sim-server",
                    "--port",
                    str(port),
                    "--max-messages",
                    "80",
                    "--payload",
                    "3",
                    "--transport",
                    transport,
                ]
            )  # fmt: skip
        )
        done.set()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    client = BridgeDriver(f"{transport}://127.0.0.1:{port}", hello_timeout_s=10.0)
    res = run_loop(LocalController(lbr4p, Circle(1.0), 0.05), client, q0=LBR4P_Q0)
    client.close()
    server = res.log.meta["server"]
    assert server["robot"] == "lbr4p" and server["robot_spec"] == "lbr4p"
    assert server["motor"] == "velocity" and server["simulator"] == "mujoco"
    assert server["payload_kg"] == 3.0  # through PayloadDriver
    # hello, describe, reset, the samples (the stop's too), the ramp, hold
    sent = 3 + len(res.log) + res.log.meta["stop"]["brake_periods"] + 1
    assert res.metrics.completed and sent < 80
    link = client_endpoint(f"{transport}://127.0.0.1:{port}")
    answered = 0
    for _ in range(80 - sent):  # the server stops after its 80th message
        link.send(header(1, 0, 0))
        if link.receive(2.0) is None:
            break
        answered += 1
    link.close()
    thread.join(timeout=20.0)
    assert done.is_set() and codes == [0]
    # over UDP the HELLOs the client repeated while the server was starting count too
    assert answered == 80 - sent if transport == "tcp" else 0 < answered <= 80 - sent
    assert f"on {transport}://127.0.0.1:" in capsys.readouterr().out


@needs_zmq
def test_the_sim_server_refuses_a_negative_payload(capsys):
    with pytest.raises(SystemExit) as info:
        main(["sim-server", "--port", "0", "--payload", "-1", "--max-messages", "1"])
    assert info.value.code == 2 and "--payload must be >= 0 kg" in capsys.readouterr().err


@needs_zmq
def test_the_cli_refuses_a_period_the_profiles_robot_does_not_accept(capsys):
    with pytest.raises(SystemExit) as info:
        main(["sim-server", "--robot", "panda", "--limits", "franka_panda", "--period", "0.05"])
    assert info.value.code == 2
    assert "accepts control periods of 0.001 s" in capsys.readouterr().err
