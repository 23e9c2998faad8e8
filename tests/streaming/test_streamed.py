"""The streamed path-following controller in the loop (docs/theory.md §12): stepped runs
deterministic and equal to the synchronous controller when ``T_p = T``, a planner that
stops answering played out to rest on the path, bad input refused."""

from __future__ import annotations

import time

import numpy as np
import pytest

from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.controllers.thesis.local import LocalController
from dqcontrol.dq.algebra import translation
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim.kinematic import run_kinematic
from dqcontrol.streaming import streamed
from dqcontrol.trajectories import Circle

QD_MAX = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])


def _pf(robot, period_s: float) -> PathFollowingController:
    return PathFollowingController(
        robot, Circle(2.0), period_s, velocity_limits=QD_MAX, acceleration_limit=10.0
    )


def test_plan_period_equal_to_t_is_the_synchronous_controller(lbr4p):
    sync = run_kinematic(_pf(lbr4p, 0.01), LBR4P_Q0, max_time_s=0.3)
    stream = run_kinematic(streamed(_pf(lbr4p, 0.01), 0.01), LBR4P_Q0, max_time_s=0.3)
    assert len(stream.log) == len(sync.log) == 30
    np.testing.assert_allclose(stream.log.qd_command, sync.log.qd_command, rtol=0, atol=1e-9)
    np.testing.assert_allclose(stream.log.q, sync.log.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(stream.log.sigma, sync.log.sigma, rtol=0, atol=1e-9)


@pytest.mark.parametrize("lead", [0, 10])
def test_stepped_runs_are_deterministic_and_within_the_limits(lbr4p, lead):
    def run():
        c = streamed(_pf(lbr4p, 0.01), 0.001, acceleration_max=10.0, jerk_max=5000.0,
                     lead_periods=lead)  # fmt: skip
        return c, run_kinematic(c, LBR4P_Q0, max_time_s=0.15)

    c, first = run()
    _, second = run()
    assert np.array_equal(first.log.qd_command, second.log.qd_command)
    assert np.array_equal(first.log.q, second.log.q)
    u = np.vstack((np.zeros(7), first.log.qd_command))
    a = np.diff(u, axis=0) / 0.001
    assert np.all(np.abs(u) <= QD_MAX * (1 + 1e-9))
    assert np.all(np.abs(a) <= 10.0 * (1 + 1e-9))
    assert np.all(np.abs(np.diff(a, axis=0)) / 0.001 <= 5000.0 * (1 + 1e-9))
    report = first.log.meta["stream"]
    assert report["plans_used"] == (15 if lead == 0 else 14)  # the last one starts at 0.15 s
    assert report["plans_refused"] == 0
    dev = c.trajectory.path_deviation(translation(first.log.pose))
    assert np.max(dev) < 1e-3


@pytest.mark.parametrize(
    ("planner_in", "how"), [("thread", "pause"), ("process", "pause"), ("process", "kill")]
)
def test_a_planner_that_stops_answering_is_played_out_to_rest_on_the_path(lbr4p, planner_in, how):
    c = streamed(_pf(lbr4p, 0.01), 0.001, acceleration_max=10.0, jerk_max=5000.0,
                 planner_in=planner_in)  # fmt: skip
    q = LBR4P_Q0.copy()
    c.reset(q)
    c.use_wall_clock(True)  # a planner thread or process, clocked here by hand
    try:
        results = []
        for k in range(3000):
            if k == 100:
                if how == "kill":  # the planner's process is killed
                    c._thread._process.kill()
                else:  # the planner blocks from here on
                    c._thread.pause()
            r = c.step(q)
            results.append(r)
            q = q + 0.001 * r.qd_command
            if c.done:
                break
            if k < 100:  # give the planner its time, as the wall clock would
                time.sleep(0.002)
    finally:
        c.close()
    last = results[-1]
    assert last.diagnostics.status == "stopped"
    assert "no new plan" in last.diagnostics.message
    assert np.all(last.qd_command == 0.0) or np.max(np.abs(last.qd_command)) < 1e-9
    u = np.array([r.qd_command for r in results])
    a = np.diff(np.vstack((np.zeros(7), u)), axis=0) / 0.001
    assert np.all(np.abs(a) <= 10.0 * (1 + 1e-9))
    assert np.all(np.abs(np.diff(a, axis=0)) / 0.001 <= 5000.0 * (1 + 1e-9))
    assert np.all(q > lbr4p.limits.q_min) and np.all(q < lbr4p.limits.q_max)
    dev = c.trajectory.path_deviation(translation(lbr4p.pose(q))[None, :])
    assert float(dev[0]) < 1e-3
    report = c.report()
    assert "no new plan" in report["playout"]
    assert report["plans_used"] > 1  # the planner answered before it stopped


@pytest.mark.parametrize(
    ("plan_period", "period", "what"),
    [(0.0005, 0.001, "whole multiple"), (0.0025, 0.001, "whole multiple")],
)
def test_bad_plan_periods_are_refused(lbr4p, plan_period, period, what):
    with pytest.raises(ParameterError, match=what):
        streamed(_pf(lbr4p, plan_period), period)


def test_a_controller_without_a_consistent_plan_is_refused(lbr4p):
    local = LocalController(lbr4p, Circle(2.0), 0.01, velocity_limits=QD_MAX)
    with pytest.raises(ParameterError, match="consistent plan"):
        streamed(local, 0.001)


def test_the_log_records_plan_id_and_age_per_sample(lbr4p, tmp_path):
    from dqcontrol.runs import load_run

    c = streamed(_pf(lbr4p, 0.01), 0.001, acceleration_max=10.0, jerk_max=5000.0)
    memory = run_kinematic(c, LBR4P_Q0, max_time_s=0.05)
    c = streamed(_pf(lbr4p, 0.01), 0.001, acceleration_max=10.0, jerk_max=5000.0)
    streamed_file = run_kinematic(c, LBR4P_Q0, max_time_s=0.05, log_file=tmp_path / "run.mcap")
    loaded, _ = load_run(streamed_file.log_file)
    for log in (memory.log, loaded):
        assert log.plan_id.tolist() == [k // 10 + 1 for k in range(50)]
        np.testing.assert_allclose(log.plan_age_s, [0.001 * (k % 10) for k in range(50)])
        assert np.all(np.isnan(log.lateness_s))  # stepped: no wall clock
    synchronous = run_kinematic(_pf(lbr4p, 0.01), LBR4P_Q0, max_time_s=0.05)
    assert synchronous.log.plan_id is None


def test_a_run_with_its_stop_keeps_the_plan_columns(lbr4p, tmp_path):
    from dqcontrol.runs import load_run
    from dqcontrol.sim import KinematicDriver, run_loop

    def run(**kwargs):
        c = streamed(_pf(lbr4p, 0.01), 0.001, acceleration_max=10.0, jerk_max=5000.0)
        return run_loop(c, KinematicDriver(lbr4p, 0.001), q0=LBR4P_Q0, max_time_s=0.05, **kwargs)

    memory = run()
    loaded, _ = load_run(run(log_file=tmp_path / "run.mcap", log_chunk_s=0.02).log_file)
    for log in (memory.log, loaded):
        assert log.stopping.any() and len(log.plan_id) == len(log) == len(log.lateness_s)
        task = ~log.stopping
        assert np.all(log.plan_id[task] >= 1)
        given = log.plan_id >= 1  # stop samples: a plan's, or -1 where another controller
        assert np.all(log.plan_id[~given] == -1) and np.all(np.isnan(log.plan_age_s[~given]))
    np.testing.assert_array_equal(memory.log.plan_id, loaded.plan_id)


def test_the_metrics_report_plan_ages_and_planner_step_times(lbr4p, tmp_path):
    from dqcontrol.sim import KinematicDriver, run_loop

    def run(controller, **kwargs):
        return run_loop(controller, KinematicDriver(lbr4p, 0.001), q0=LBR4P_Q0, max_time_s=0.05,
                        **kwargs)  # fmt: skip

    plans = streamed(_pf(lbr4p, 0.01), 0.001, acceleration_max=10.0, jerk_max=5000.0)
    memory = run(plans)
    plans = streamed(_pf(lbr4p, 0.01), 0.001, acceleration_max=10.0, jerk_max=5000.0)
    streamed_file = run(plans, log_file=tmp_path / "run.mcap")
    for m in (memory.metrics, streamed_file.metrics):
        ages = memory.log.plan_age_s[memory.log.plan_id >= 1]
        assert m.plan_age_median_s == pytest.approx(np.median(ages), abs=1e-12)
        assert m.plan_age_max_s == pytest.approx(ages.max(), abs=1e-12) and m.plan_age_max_s > 0
        assert 0.0 < m.planner_step_median_s < 1.0 and m.late_commands == 0
    synchronous = run(_pf(lbr4p, 0.01)).metrics
    assert np.isnan(synchronous.plan_age_median_s) and np.isnan(synchronous.planner_step_median_s)


def test_the_stream_settles_on_the_paths_end_before_the_task_is_done(panda):
    """The stream's tracking of the braking plans carries the tool past the path's end
    (0.04–0.09 mm here); the task is done once the stream has settled back on it."""
    from dqcontrol.model import PANDA_Q0
    from dqcontrol.sim import KinematicDriver, run_loop

    robot = panda.with_limits("franka_panda")
    controller = streamed(PathFollowingController(robot, Circle(1.0), 0.007), 1e-3)
    result = run_loop(controller, KinematicDriver(robot, 1e-3), q0=PANDA_Q0)
    end = translation(controller.trajectory.target(1.0)[None])[0]
    task = result.log.pose[~result.log.stopping]
    assert np.linalg.norm(translation(task[-1]) - end) <= 1e-5
    assert result.metrics.completed and result.log.meta["stop"]["at_rest"]
