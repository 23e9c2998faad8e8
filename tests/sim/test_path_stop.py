"""The closed loop's stop along the path (dqcontrol/sim/path_stop.py): every way a run ends
brings the arm to rest on the path within the limits, the stop's samples flagged.

The Panda with Franka's velocity and acceleration limits, the path-following controller on
a 15 cm circle of 1 s at T = 10 ms in the kinematic loop (a short MuJoCo case at the end).
The checks are independent of the controller: the commands the driver received (their
differences against ``a_max T``, the last one exactly zero) and the tool's distance from
the path at every sample and after the last command (the driver's own state).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.dq import qfrom_axis_angle
from dqcontrol.dq.algebra import translation
from dqcontrol.errors import DQControlError
from dqcontrol.model import PANDA_Q0
from dqcontrol.sim import KinematicDriver, MujocoDriver, run_loop
from dqcontrol.trajectories import Circle, WaypointTrajectory

T = 0.01
VELOCITY = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
ACCELERATION = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
KINEMATIC_GOAL_M = 1e-4
MUJOCO_GOAL_M = 5e-4


class Wrapped:
    """A driver that records what it is sent and can fail: its measurement frozen after
    ``freeze_after`` writes, or one :class:`DQControlError` at write ``fail_at``."""

    def __init__(self, inner, freeze_after: int | None = None, fail_at: int | None = None):
        self.inner, self.joint_names = inner, inner.joint_names
        self.freeze_after, self.fail_at = freeze_after, fail_at
        self.writes: list[np.ndarray] = []
        self.holds = 0
        self._frozen = None

    def reset(self, q0):
        return self.inner.reset(q0)

    def read(self):
        if self._frozen is not None:
            return self._frozen
        m = self.inner.read()
        if self.freeze_after is not None and len(self.writes) >= self.freeze_after:
            self._frozen = m
        return m

    def write(self, u):
        if self.fail_at is not None and len(self.writes) == self.fail_at:
            self.fail_at = None
            raise DQControlError("the link to the arm dropped a packet")
        self.writes.append(np.array(u, dtype=float))
        self.inner.write(u)

    def hold(self):
        self.holds += 1
        self.inner.hold()


def _pf(panda, **kw):
    return PathFollowingController(
        panda, Circle(1.0, radius_m=0.15), T, velocity_limits=VELOCITY,
        acceleration_limit=ACCELERATION, **kw,
    )  # fmt: skip


def _request_at(controller, sigma: float):
    def on_sample(_k, _driver, result) -> None:
        if result.sigma_next >= sigma and not controller.stopping:
            controller.request_stop()

    return on_sample


def _interrupt_at(k_stop: int):
    def on_sample(k, _driver, _result) -> None:
        if k == k_stop:
            raise KeyboardInterrupt

    return on_sample


def _scenario(panda, name: str):
    if name == "local_request":
        ctrl = LocalController(
            panda, Circle(1.0, radius_m=0.15), T, velocity_limits=VELOCITY,
            acceleration_limit=ACCELERATION,
        )  # fmt: skip
    else:
        ctrl = _pf(panda)
    drv = Wrapped(KinematicDriver(panda, T))
    kw: dict = {}
    if name in ("request", "local_request"):
        kw["on_sample"] = _request_at(ctrl, 0.5)
    elif name == "ctrl_c":
        kw["on_sample"] = _interrupt_at(45)
    elif name == "stale":
        drv.freeze_after = 45
    elif name == "driver_error":
        drv.fail_at = 45
    result = run_loop(ctrl, drv, q0=PANDA_Q0, **kw)
    return result, ctrl, drv


SCENARIOS = {
    "end": "end",
    "request": "request",
    "ctrl_c": "user",
    "stale": "stale",
    "driver_error": "simulation",
    "local_request": "request",
}


@pytest.fixture(scope="module")
def runs(panda):
    return {name: _scenario(panda, name) for name in SCENARIOS}


def _tool_deviation(controller, driver, q_rows: np.ndarray) -> np.ndarray:
    poses = controller.robot.fast.poses(np.atleast_2d(q_rows))
    return controller.trajectory.path_deviation(translation(poses))


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_every_stop_ends_at_rest_on_the_path_within_the_limits(runs, name):
    result, ctrl, drv = runs[name]
    log, stop = result.log, result.log.meta["stop"]
    assert stop["reason"] == SCENARIOS[name] and stop["at_rest"] and stop["ramp"] == ""
    assert stop["brake_periods"] == 0 and drv.holds == 1
    writes = np.array(drv.writes)
    assert not writes[-1].any()  # the last command is exactly zero
    steps = np.abs(np.diff(np.vstack([np.zeros(7), writes]), axis=0))
    assert np.all(steps <= ACCELERATION * T * (1 + 1e-9) + 1e-12)
    assert np.all(np.abs(writes) <= VELOCITY + 1e-12)
    # the tool on the path at every logged sample (the local controller's own task may
    # deviate more: its stop does not add to that) and where the arm came to rest
    deviation = _tool_deviation(ctrl, drv, log.q)
    first = int(np.argmax(log.stopping))
    start = deviation[first] if name == "local_request" else 0.0
    assert np.max(deviation[first:]) <= max(start, KINEMATIC_GOAL_M)
    if name != "local_request":
        assert np.max(deviation) <= KINEMATIC_GOAL_M
    assert _tool_deviation(ctrl, drv, drv.inner.read().q)[0] <= KINEMATIC_GOAL_M


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_the_stop_samples_are_flagged_and_counted(runs, name):
    result, _ctrl, drv = runs[name]
    log, m = result.log, result.metrics
    first = int(np.argmax(log.stopping))
    assert log.stopping.any() and log.stopping[first:].all() and not log.stopping[:first].any()
    assert m.stop_samples == log.stopping.sum() == result.log.meta["stop"]["stop_periods"]
    assert m.stop_duration_s == pytest.approx(m.stop_samples * T)
    assert m.stop_limit_violations == 0 and m.stop_last_command_rad_s == 0.0
    if name != "local_request":  # its task's own deviation: see above
        assert m.stop_path_deviation_max_m <= KINEMATIC_GOAL_M
    assert len(drv.writes) == len(log)  # every command sent is logged
    if name != "end":  # mid-task: the phase still advanced while braking
        assert m.stop_phase_advance_s > 0.0 and m.stop_tool_travel_m > 0.0


def test_the_task_ends_at_rest_at_its_end(runs):
    result, ctrl, drv = runs["end"]
    log = result.log
    task = ~log.stopping
    assert result.metrics.completed and not result.interrupted
    # the phase velocity brakes to zero at the end: its last values decrease to 0
    s_task = log.s[task]
    assert np.all(np.diff(s_task[-10:]) <= 1e-12) and s_task[-1] < 0.1
    assert log.sigma[-1] == pytest.approx(1.0, abs=1e-12)
    end = translation(ctrl.trajectory.target(1.0)[None])[0]
    tool = translation(ctrl.robot.fast.poses(drv.inner.read().q[None]))[0]
    assert np.linalg.norm(tool - end) <= KINEMATIC_GOAL_M


def test_the_thesis_convention_ends_at_speed(panda):
    ctrl = _pf(panda, end="at_speed")
    result = run_loop(ctrl, KinematicDriver(panda, T), q0=PANDA_Q0, brake=False)
    assert result.metrics.completed and np.max(np.abs(result.log.qd_command[-1])) > 0.3
    assert not result.log.stopping.any()


def test_without_a_solution_the_joint_ramp_takes_over_and_says_so(panda):
    ctrl = _pf(panda)
    drv = Wrapped(KinematicDriver(panda, T))
    step = ctrl.step

    def failing(q, qd=None):
        result = step(q, qd)
        if ctrl.stopping:
            diag = dataclasses.replace(result.diagnostics, fallback=True)
            return dataclasses.replace(result, diagnostics=diag)
        return result

    ctrl.step = failing  # type: ignore[method-assign]
    result = run_loop(ctrl, drv, q0=PANDA_Q0, on_sample=_request_at(ctrl, 0.5))
    stop = result.log.meta["stop"]
    assert stop["ramp"].startswith("no QP solution") and not stop["at_rest"]
    assert stop["brake_periods"] >= 1 and not drv.writes[-1].any()
    steps = np.abs(np.diff(np.array(drv.writes), axis=0))
    assert np.all(steps <= ACCELERATION * T * (1 + 1e-9) + 1e-12)


def test_a_missed_deadline_stops_along_the_path(panda):
    import threading

    ctrl = _pf(panda)
    drv = Wrapped(KinematicDriver(panda, T))

    def slow(k, _driver, _result) -> None:
        if k == 30:
            threading.Event().wait(3 * T)

    result = run_loop(ctrl, drv, q0=PANDA_Q0, on_sample=slow, realtime=True, max_lateness_s=T)
    assert result.reason == "deadline" and result.log.meta["stop"]["at_rest"]
    assert not drv.writes[-1].any() and result.log.stopping.any()
    assert np.max(_tool_deviation(ctrl, drv, result.log.q)) <= KINEMATIC_GOAL_M


def test_a_stop_in_mujoco_keeps_the_path(panda):
    ctrl = _pf(panda)
    drv = Wrapped(MujocoDriver(panda, T))
    result = run_loop(ctrl, drv, q0=PANDA_Q0, on_sample=_request_at(ctrl, 0.4))
    stop = result.log.meta["stop"]
    assert stop["reason"] == "request" and stop["at_rest"] and not drv.writes[-1].any()
    assert result.metrics.path_deviation_max_m <= MUJOCO_GOAL_M
    assert result.metrics.stop_path_deviation_max_m <= MUJOCO_GOAL_M


def test_rest_to_rest_in_mujoco(panda):
    ctrl = _pf(panda)
    drv = Wrapped(MujocoDriver(panda, T))
    result = run_loop(ctrl, drv, q0=PANDA_Q0)
    m = result.metrics
    assert m.completed and result.log.meta["stop"]["at_rest"] and not drv.writes[-1].any()
    assert m.path_deviation_max_m <= MUJOCO_GOAL_M
    assert m.stop_path_deviation_max_m <= MUJOCO_GOAL_M
    end = translation(ctrl.trajectory.target(1.0)[None])[0]
    tool = translation(result.log.pose[-1:])[0]
    assert np.linalg.norm(tool - end) <= KINEMATIC_GOAL_M


# ------------------------------------------------------------------ under the jerk bound
def _checked_run(panda, controller_class, duration_s: float):
    """A 10 cm circle of ``duration_s`` at T = 1 ms in the kinematic loop on the Panda with the
    ``franka_panda`` profile (velocity, acceleration and jerk), to its end and its stop:
    the checker's violations against the profile, the run and the controller."""
    from dqcontrol.runs.check import check_run

    robot = panda.with_limits("franka_panda")
    period = 1e-3
    controller = controller_class(robot, Circle(duration_s), period)
    result = run_loop(controller, KinematicDriver(robot, period), q0=PANDA_Q0)
    return check_run(result.log, robot.limits, period_s=period), result, controller


def test_a_path_following_stop_keeps_the_jerk_bound_and_the_path_to_rest(panda):
    found, result, controller = _checked_run(panda, PathFollowingController, 1.0)
    assert found == []
    log, m = result.log, result.metrics
    assert log.meta["stop"]["at_rest"]
    assert np.all(log.qd_command[-1] == 0.0)
    trajectory = controller.trajectory
    assert np.max(trajectory.path_deviation(translation(log.pose))) <= KINEMATIC_GOAL_M
    assert m.stop_path_deviation_max_m <= KINEMATIC_GOAL_M
    end = translation(trajectory.target(1.0)[None])[0]
    assert np.linalg.norm(translation(log.pose[-1:])[0] - end) <= KINEMATIC_GOAL_M


def _waypoint_run(robot, period_s: float):
    """The user guide's four waypoints (the tool turning about its z-axis) in 1 s."""
    z = np.array([0.0, 0.0, 1.0])
    path = WaypointTrajectory(
        positions_m=[[0.0, 0.0, 0.0], [0.08, 0.05, 0.0], [0.12, -0.05, 0.03], [0.0, 0.0, 0.0]],
        orientations=[qfrom_axis_angle(z, np.radians(a)) for a in (0.0, 30.0, -20.0, 0.0)],
        duration_s=1.0,
    )
    controller = PathFollowingController(
        robot, path, period_s, velocity_limits=VELOCITY, acceleration_limit=ACCELERATION
    )
    return run_loop(controller, KinematicDriver(robot, period_s), q0=PANDA_Q0), controller


def test_the_jerk_bound_neither_slows_nor_bends_a_waypoint_path(panda):
    """Franka's velocity and acceleration limits with and without the profile's jerk, at
    1 kHz: the jerk-bounded run takes at most 1.1 times as long and keeps the path within
    0.1 mm (a plan that turns an acceleration round faster than the loop can swings it
    between its bounds: several times slower, and off the path)."""
    from dqcontrol.runs.check import check_run

    robot = panda.with_limits("franka_panda")
    bounded, controller = _waypoint_run(robot, 1e-3)
    free, _ = _waypoint_run(panda, 1e-3)
    assert controller.jerk_max is not None
    assert check_run(bounded.log, robot.limits, period_s=1e-3) == []
    ratio = bounded.metrics.execution_time_s / free.metrics.execution_time_s
    assert ratio <= 1.1, f"{ratio:.3f}"
    deviation = controller.trajectory.path_deviation(translation(bounded.log.pose))
    assert np.max(deviation) <= KINEMATIC_GOAL_M


def test_a_thesis_controllers_end_of_task_stop_keeps_the_jerk_bound_to_rest(panda):
    found, result, _ = _checked_run(panda, LocalController, 0.5)
    assert found == []
    assert result.log.meta["stop"]["at_rest"]
    assert result.log.meta["stop"]["ramp"] == ""


@pytest.mark.parametrize("name", ["local", "p10"])
def test_a_task_that_ends_at_speed_ends_at_rest_at_the_paths_end(panda, name):
    """The thesis's controllers end at speed; with the brake their end is handed over
    before it is reached and the tool comes to rest at the path's end, never past it (a
    stop begun at ``σ = T_tot`` overshoots it by 3–5 mm here)."""
    from dqcontrol.controllers import PredictiveController

    def predictive(robot, trajectory, period):
        return PredictiveController(robot, trajectory, period, num_instants=10)

    found, result, controller = _checked_run(
        panda, LocalController if name == "local" else predictive, 1.0
    )
    log, stop = result.log, result.log.meta["stop"]
    assert found == [] and stop["at_rest"] and stop["ramp"] == ""
    assert np.all(log.qd_command[-1] == 0.0) and result.metrics.completed
    handed = stop["end_at_rest_from"]
    assert 0.5 < handed["sigma"] < 0.95 and log.sigma[handed["sample"]] == handed["sigma"]
    trajectory = controller.trajectory
    end = translation(trajectory.target(1.0)[None])[0]
    reached = np.flatnonzero(log.sigma + 1e-3 * log.s >= 1.0 - 1e-12)[0]
    to_end = np.linalg.norm(translation(log.pose[reached:]) - end, axis=1)
    assert np.max(to_end) <= KINEMATIC_GOAL_M


def test_a_stop_at_half_the_task_keeps_the_profile_and_the_path(panda):
    from dqcontrol.runs.check import check_run

    robot = panda.with_limits("franka_panda")
    period = 1e-3
    controller = PathFollowingController(robot, Circle(1.0), period)

    def on_sample(k, driver, result) -> None:
        if result.sigma_next >= 0.5 and not controller.stopping:
            controller.request_stop()

    result = run_loop(controller, KinematicDriver(robot, period), q0=PANDA_Q0, on_sample=on_sample)
    log = result.log
    assert check_run(log, robot.limits, period_s=period) == []
    assert log.meta["stop"]["reason"] == "request" and log.meta["stop"]["at_rest"]
    deviation = controller.trajectory.path_deviation(translation(log.pose[log.stopping]))
    assert np.max(deviation) <= KINEMATIC_GOAL_M
    assert np.all(log.qd_command[-1] == 0.0)
