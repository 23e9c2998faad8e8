"""``dqcontrol.experiments.runner``: a short kinematic run's deviation between samples against brute
force, the per-thread robot, and the cached, never-raising time-optimal bound (stubbed)."""

from __future__ import annotations

import math
import threading
from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.dq import translation
from dqcontrol.errors import DQControlError, ParameterError
from dqcontrol.experiments import runner, time_optimal
from dqcontrol.model import LBR4P_Q0
from dqcontrol.trajectories import Circle, trajectory_from_metadata


@pytest.fixture(scope="module")
def kinematic_case(lbr4p):
    controller = LocalController(lbr4p, Circle(0.5), 0.05)
    return runner.simulate(controller, LBR4P_Q0, "kinematic", between_samples=True)


def test_the_deviation_between_samples_is_the_largest_over_every_state(kinematic_case):
    """Against the deviation of every state between the samples, joints moving in straight
    lines over a period (the kinematic loop), evaluated without the pruning."""
    controller, result = kinematic_case.controller, kinematic_case.result
    intervals = result.metrics.samples - 1
    assert intervals > 5
    log = result.log
    fractions = np.linspace(0.0, 1.0, runner.KINEMATIC_SUBSAMPLES + 1)
    states = log.q[:intervals, None] + fractions[None, :, None] * (
        controller.period_s * log.qd_command[:intervals, None]
    )
    points = translation(controller.robot.poses(states.reshape(-1, 7)))
    brute = float(np.max(controller.trajectory.path_deviation(points)))
    assert kinematic_case.between_deviation_max_m == pytest.approx(brute, rel=1e-12, abs=1e-15)
    assert brute >= result.metrics.path_deviation_max_m - 1e-12
    assert kinematic_case.wall_time_s > 0.0


def test_no_states_or_a_nan_state_give_a_nan_deviation(kinematic_case):
    controller = kinematic_case.controller
    assert math.isnan(runner._largest_deviation(controller, np.zeros((0, 1, 7))))
    states = np.tile(LBR4P_Q0, (2, 3, 1))
    states[1, 1, 2] = np.nan
    assert math.isnan(runner._largest_deviation(controller, states))


def test_without_between_samples_the_deviation_is_not_measured(lbr4p):
    run = runner.simulate(LocalController(lbr4p, Circle(0.2), 0.05), LBR4P_Q0, "kinematic")
    assert math.isnan(run.between_deviation_max_m) and run.result.metrics.completed


def test_an_unknown_simulator_is_refused(lbr4p):
    with pytest.raises(
        ParameterError, match="simulator must be one of \\('mujoco', 'kinematic'\\)"
    ):
        runner.simulate(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0, "gazebo")


def test_each_thread_has_its_own_robot():
    mine = runner.lbr4p()
    assert runner.lbr4p() is mine and mine.ee_frame == "lbr4p_flange"
    other = []
    thread = threading.Thread(target=lambda: other.append(runner.lbr4p()))
    thread.start()
    thread.join()
    assert other[0] is not mine and other[0].nq == mine.nq


def test_a_trajectory_is_built_from_its_metadata():
    meta = {"trajectory": "circle", "duration_s": 3.0, "radius_m": 0.2}
    built = runner.build_trajectory(meta)
    assert repr(built) == repr(trajectory_from_metadata(meta))


def test_the_bound_is_computed_once_and_an_error_becomes_a_note(lbr4p, monkeypatch):
    calls = []

    def stub(robot, trajectory, q0, **constraints):
        calls.append(constraints)
        if constraints.get("speed_cap") == 0.5:
            raise DQControlError("the path leaves the workspace")
        return SimpleNamespace(duration_s=1.25)

    monkeypatch.setattr(runner, "_BOUNDS", {})
    monkeypatch.setattr(time_optimal, "time_optimal_bound", stub)
    limits = {"velocity_limits": np.ones(7), "speed_cap": 0.5}
    for _ in range(2):
        duration, note = runner.time_optimal_duration(lbr4p, Circle(1.0), LBR4P_Q0, **limits)
        assert (
            math.isnan(duration) and note == "no time-optimal bound: the path leaves the workspace"
        )
    assert len(calls) == 1
    other = {"velocity_limits": np.ones(7), "speed_cap": 1.0}
    assert runner.time_optimal_duration(lbr4p, Circle(1.0), LBR4P_Q0, **other) == (1.25, "")
    assert runner.time_optimal_duration(lbr4p, Circle(2.0), LBR4P_Q0, **other) == (1.25, "")
    assert len(calls) == 3  # one per task and constraints
