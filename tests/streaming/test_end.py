"""dqcontrol/streaming/end.py: the streamed end at rest of a task that ends at speed (the
thesis's controllers), stepped (deterministic) and on the wall clock (docs/theory.md §8.10).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.dq.algebra import translation
from dqcontrol.model import PANDA_Q0
from dqcontrol.runs.check import check_run
from dqcontrol.sim import KinematicDriver, run_loop
from dqcontrol.streaming.end import end_plan_period_s, end_stream
from dqcontrol.trajectories import Circle

T = 1e-3
PLAN_PERIODS = 7
END_GOAL_M = 1e-4


def _run(robot, streamed_end: bool, brake: bool = True, realtime: bool = False):
    controller = LocalController(robot, Circle(1.0), T)
    if streamed_end:
        controller.reset(PANDA_Q0)
        controller.end_stream = end_stream(controller, PANDA_Q0, PLAN_PERIODS * T, False)
    driver = KinematicDriver(robot, T)
    options = {"max_lateness_s": 0.1} if realtime else {}
    result = run_loop(controller, driver, q0=PANDA_Q0, brake=brake, realtime=realtime, **options)
    return result, controller


def _to_end_m(controller, log) -> float:
    end = translation(controller.trajectory.target(1.0)[None])[0]
    return float(np.linalg.norm(translation(log.pose[-1]) - end))


@pytest.fixture(scope="module")
def franka(panda):
    return panda.with_limits("franka_panda")


@pytest.fixture(scope="module")
def stepped(franka):
    return _run(franka, streamed_end=True)


def test_a_streamed_end_brings_a_thesis_task_to_rest_at_the_paths_end(franka, stepped):
    result, controller = stepped
    log, stop = result.log, result.log.meta["stop"]
    assert check_run(log, franka.limits, period_s=T) == []
    assert stop["at_rest"] and stop["ramp"] == "" and np.all(log.qd_command[-1] == 0.0)
    assert _to_end_m(controller, log) <= END_GOAL_M
    stream = log.meta["end_stream"]
    assert stream["plans_used"] > 0 and stream["plans_refused"] == 0
    assert controller.end_stream is None  # closed and dropped by the loop
    handed = stop["end_at_rest_from"]["sample"]
    deviation = controller.trajectory.path_deviation(translation(log.pose))
    assert np.max(deviation[handed:]) <= deviation[handed] + 1e-6  # back onto the path


def test_the_task_commands_until_the_first_plan_starts(franka, stepped):
    """The handover waits for the plan (solved from the state one plan period on): the
    local controller's own commands until then, the stream's from its start."""
    result, _ = stepped
    free, _ = _run(franka, streamed_end=False, brake=False)
    handed = result.log.meta["stop"]["end_at_rest_from"]["sample"]
    own = handed + PLAN_PERIODS  # the handover's first sample, then the plan's lead
    assert np.array_equal(result.log.qd_command[:own], free.log.qd_command[:own])
    assert not np.array_equal(result.log.qd_command[own], free.log.qd_command[own])


def test_a_stepped_streamed_end_is_deterministic(franka, stepped):
    again, _ = _run(franka, streamed_end=True)
    assert np.array_equal(again.log.qd_command, stepped[0].log.qd_command)
    assert np.array_equal(again.log.sigma, stepped[0].log.sigma)


def test_on_the_wall_clock_a_thesis_task_ends_at_rest_through_a_streamed_end(franka):
    """At 1 kHz the end's first step (milliseconds) cannot be stepped in the loop: the
    loop prepares a streamed end before the clock and hands over to it."""
    result, controller = _run(franka, streamed_end=False, realtime=True)
    log, stop = result.log, result.log.meta["stop"]
    assert log.meta["end_at_rest"].startswith("streamed on the wall clock")
    assert "end_at_rest_from" in stop and stop["at_rest"] and stop["ramp"] == ""
    assert check_run(log, franka.limits, period_s=T) == []
    assert np.all(log.qd_command[-1] == 0.0)
    assert _to_end_m(controller, log) <= END_GOAL_M


def test_the_plan_period_follows_the_measured_first_step():
    assert end_plan_period_s(3.3e-3, 1e-3) == pytest.approx(7e-3)
    assert end_plan_period_s(1e-3, 1e-2) == pytest.approx(1e-2)
    assert math.isinf(end_plan_period_s(math.inf, 1e-3))


def _stop_at_half(controller):
    def on_sample(k, driver, result) -> None:
        if result.sigma_next >= 0.5 * controller.trajectory.duration and not controller.stopping:
            controller.request_stop()

    return on_sample


def test_a_thesis_controllers_stop_is_streamed_where_its_end_is(franka):
    """A stop requested mid-task goes to the prepared stream too (the planner's stop), the
    task's controller commanding until the first stop plan starts: at rest on the path,
    every limit kept, no synchronous solve in the loop."""
    controller = LocalController(franka, Circle(2.0), T)
    controller.reset(PANDA_Q0)
    controller.end_stream = end_stream(controller, PANDA_Q0, PLAN_PERIODS * T, False)
    driver = KinematicDriver(franka, T)
    result = run_loop(controller, driver, q0=PANDA_Q0, on_sample=_stop_at_half(controller))
    log, stop = result.log, result.log.meta["stop"]
    assert stop["reason"] == "request" and stop["at_rest"] and stop["ramp"] == ""
    assert check_run(log, franka.limits, period_s=T) == []
    assert np.all(log.qd_command[-1] == 0.0) and log.meta["end_stream"]["plans_used"] > 0
    deviation = controller.trajectory.path_deviation(translation(log.pose))
    assert np.max(deviation[log.stopping]) <= np.max(deviation[~log.stopping]) + 1e-6


def test_a_streamed_controllers_stop_is_its_planners(franka):
    """A streamed path-following controller stops through its planner's stop plans, not a
    controller built and solved in the loop at the stop."""
    from dqcontrol.controllers.path_following.controller import PathFollowingController
    from dqcontrol.streaming.streamed import streamed

    controller = streamed(PathFollowingController(franka, Circle(2.0), PLAN_PERIODS * T), T)
    driver = KinematicDriver(franka, T)
    result = run_loop(controller, driver, q0=PANDA_Q0, on_sample=_stop_at_half(controller))
    log, stop = result.log, result.log.meta["stop"]
    assert controller._delegate is None and controller.planner_controller.stopping
    assert stop["at_rest"] and stop["ramp"] == "" and np.all(log.qd_command[-1] == 0.0)
    assert check_run(log, franka.limits, period_s=T) == []
    deviation = controller.trajectory.path_deviation(translation(log.pose[log.stopping]))
    assert np.max(deviation) <= END_GOAL_M


def test_a_streamed_end_that_cannot_be_prepared_leaves_the_task_ending_at_speed(
    franka, monkeypatch
):
    import dqcontrol.sim.loop as loop

    def broken(*args, **kwargs):
        raise OSError("no process for the planner")

    monkeypatch.setattr(loop, "end_stream", broken)
    controller = LocalController(franka, Circle(1.0), 1e-2)
    result = run_loop(controller, KinematicDriver(franka, 1e-2), q0=PANDA_Q0, realtime=True)
    assert "could not be prepared (OSError: no process" in result.log.meta["end_at_rest"]
    assert result.metrics.completed and "end_at_rest_from" not in result.log.meta["stop"]
