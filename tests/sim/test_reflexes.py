"""The sim-server's reflexes: a command beyond a limit is answered with an ERROR naming it,
the arm is stopped, later commands are refused until RESET, the client stops and its run
log says so; a clean run passes untouched; without a profile, the URDF's velocity."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.model.library import PANDA_Q0
from dqcontrol.runs.reflexes import CommandMonitor
from dqcontrol.sim import KinematicDriver, run_loop
from dqcontrol.sim.bridge import BridgeDriver, ReflexError, SimServer
from dqcontrol.sim.reflexes import Reflexes
from dqcontrol.trajectories import Circle

pytest.importorskip("zmq")

T = 0.001


class Served:
    """A server in a thread, and a client connected to it; both closed on exit."""

    def __init__(self, server: SimServer) -> None:
        self.server = server
        self.thread = threading.Thread(target=server.serve, daemon=True)

    def __enter__(self) -> tuple[SimServer, BridgeDriver]:
        self.thread.start()
        self.client = BridgeDriver(self.server.address)
        return self.server, self.client

    def __exit__(self, *exc) -> None:
        self.client.close()
        self.server.stop()
        self.thread.join(timeout=5.0)
        self.server.close()


def _served(robot, reflexes: Reflexes | None) -> Served:
    return Served(SimServer(KinematicDriver(robot, T), reflexes=reflexes))


def _profiled(panda):
    robot = panda.with_limits("franka_panda")
    return robot, Reflexes.of_robot(robot, robot.joint_names, T)


def _gentle(n: int, steps: int) -> np.ndarray:
    """Commands from rest and back at 2 rad/s² and 2000 rad/s³ at most (within Franka's)."""
    acc = np.concatenate((np.full(steps, 2.0), np.full(steps, -2.0)))
    acc[0] = 1.0  # the first step from rest: 1000 rad/s³
    acc[-1] = -1.0
    acc[steps - 1], acc[steps] = 1.0, -1.0  # through 0 in two steps
    u = np.cumsum(acc * T)
    return np.outer(u, np.linspace(0.5, 1.0, n))


def test_a_clean_run_passes_untouched(panda):
    robot, reflexes = _profiled(panda)
    commands = _gentle(robot.nq, 50)
    states = []
    for checked in (reflexes, None):
        with _served(robot, checked) as (server, client):
            client.reset(PANDA_Q0)
            for u in commands:
                client.write(u)
            client.hold()
            states.append(np.array(client.read().q))
            assert client.reflex == "" and "reflex" not in server.rejected
    np.testing.assert_array_equal(states[0], states[1])
    assert reflexes.fired is None


def test_a_jerk_beyond_the_profile_fires_the_reflex(panda):
    robot, reflexes = _profiled(panda)
    with _served(robot, reflexes) as (server, client):
        client.reset(PANDA_Q0)
        client.write(np.full(robot.nq, 1e-3))  # 1 rad/s², 1000 rad/s³: accepted
        u = np.full(robot.nq, 1e-3)
        u[1] = 4e-3  # joint 2: 3 rad/s² and (4 - 2)e-3 / T² = 2000 rad/s³: accepted
        client.write(u)
        u = u.copy()
        u[1] = 11e-3  # 7 rad/s² within 7.5, but (11 - 8 + 1)e-3 / T² = 4000 rad/s³ > 3750
        client.write(u)  # sent; the refusal answers it
        with pytest.raises(ReflexError) as info:
            client.read()
        message = str(info.value)
        assert "jerk of panda_joint2" in message and "> 3750 rad/s³" in message
        assert reflexes.fired.kind == "jerk" and reflexes.fired.value == pytest.approx(4000.0)
        stopped = np.array(client.read().q)
        client.write(np.zeros(robot.nq))
        with pytest.raises(ReflexError, match="refused: the reflex fired .*send RESET"):
            client.read()
        client.hold()  # holding a stopped arm is no motion: accepted
        np.testing.assert_array_equal(client.read().q, stopped)
        assert server.rejected["reflex"] == 2
        client.reset(PANDA_Q0)  # re-armed: from rest again
        client.write(np.full(robot.nq, 1e-3))
        assert reflexes.fired is None and client.reflex == ""


def test_without_a_profile_the_urdf_velocity_is_refused(panda):
    reflexes = Reflexes.of_robot(panda, panda.joint_names, T, velocity_only=True)
    with _served(panda, reflexes) as (server, client):
        client.reset(PANDA_Q0)
        client.write(np.full(panda.nq, 2.0))  # a step from rest: no acceleration limit
        u = np.full(panda.nq, 2.0)
        u[0] = 1000.0
        client.write(u)
        with pytest.raises(ReflexError, match=r"velocity of panda_joint1 .*1000 > 2\.175 rad/s"):
            client.read()
        arm = server.driver.read()  # held for a period, not moved at 1000 rad/s
        assert np.all(arm.qd == 0.0) and arm.q[0] == pytest.approx(PANDA_Q0[0] + 2.0 * T)


def test_the_position_of_the_arm_fires_the_reflex(panda):
    names = panda.joint_names
    q_max = np.full(panda.nq, 3.0)
    q_max[2] = PANDA_Q0[2] + 0.5e-3
    monitor = CommandMonitor(names, T, panda.limits.qd_max, q_min=-q_max - 10, q_max=q_max)
    with _served(panda, Reflexes(monitor, "test")) as (_server, client):
        client.reset(PANDA_Q0)
        client.write(np.full(panda.nq, 1.0))  # 1 mm past q_max after one period
        with pytest.raises(ReflexError, match="position of panda_joint3 at sample 0"):
            client.read()


def test_the_client_stops_and_its_run_log_records_the_reflex(panda):
    robot, reflexes = _profiled(panda)
    with _served(robot, reflexes) as (_server, client):
        controller = LocalController(robot, Circle(1.0), T, acceleration_limit=50.0)
        result = run_loop(controller, client, q0=PANDA_Q0, warm_up=False)
    assert result.interrupted and result.reason == "simulation"
    assert "reflex (franka_panda limits)" in result.note
    assert "reflex" in result.log.meta["driver_report"]
    assert reflexes.fired is not None and len(result.log) == reflexes.fired.sample


def test_the_mujoco_driver_in_this_process_with_a_profile(panda):
    from dqcontrol.sim import MujocoDriver
    from dqcontrol.sim.reflexes import ReflexDriver

    robot, reflexes = _profiled(panda)
    driver = ReflexDriver(MujocoDriver(robot, T), reflexes)
    # the controller is given the URDF's limits, not the profile's: no jerk rows, the first
    # step trips the jerk reflex
    controller = LocalController(panda, Circle(1.0), T)
    result = run_loop(controller, driver, q0=PANDA_Q0, warm_up=False)
    assert result.reason == "simulation" and "reflex (franka_panda limits): jerk" in result.note
    assert result.log.meta["driver_report"]["reflex"] in result.note
    assert result.log.meta["reflexes"] == "franka_panda"
    assert reflexes.fired.sample == len(result.log)  # the command of the first unlogged sample
    with pytest.raises(ReflexError, match="send RESET"):
        driver.write(np.zeros(robot.nq))
