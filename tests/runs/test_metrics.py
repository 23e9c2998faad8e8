"""dqcontrol/runs/metrics.py: the metrics of a run log against hand computations (the stop
figures of a run stopped half-way)."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.dq.algebra import translation
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.log import RunLog
from dqcontrol.runs.metrics import compute_metrics, run_figures

T = 0.05


def test_the_stop_metrics_by_hand(stopped):
    ctrl, result = stopped
    log = result.log
    idx = np.flatnonzero(log.stopping)
    m = compute_metrics(log, ctrl.trajectory, bounds_of(ctrl, log.q), T)
    assert m.stop_samples == idx.size and m.stop_duration_s == pytest.approx(idx.size * T)
    advance = log.sigma[idx[-1]] + T * log.s[idx[-1]] - log.sigma[idx[0]]
    assert m.stop_phase_advance_s == pytest.approx(advance)
    tool = translation(log.pose[idx])
    travel = sum(np.linalg.norm(tool[k + 1] - tool[k]) for k in range(len(tool) - 1))
    assert m.stop_tool_travel_m == pytest.approx(travel)
    assert m.stop_path_deviation_max_m == pytest.approx(
        float(np.max(ctrl.trajectory.path_deviation(tool)))
    )
    # the task's figures stop where the stop begins
    assert not m.completed and m.samples == idx[0]
    assert m.stop_last_command_rad_s == 0.0


def test_the_task_figures_by_hand(stopped):
    ctrl, result = stopped
    log = result.log
    m = compute_metrics(log, ctrl.trajectory, bounds_of(ctrl, log.q), T)
    task = slice(0, m.samples)
    u = log.qd_command[task]
    assert m.u_mean_rad_s == pytest.approx(np.mean(np.linalg.norm(u, axis=1)))
    assert m.s_mean == pytest.approx(np.mean(log.s[task]))
    assert m.solve_time_median_s == pytest.approx(np.median(log.solve_time_s[task]))
    assert m.duration_s == 1.0 and m.fallbacks == int(log.fallback[task].sum())
    assert np.isnan(m.torque_peak_nm)  # the kinematic loop has no torques
    assert m.velocity_violations == m.position_violations == 0


def test_violations_are_counted_beyond_the_bounds(stopped):
    ctrl, result = stopped
    arrays = result.log.arrays()
    bounds = bounds_of(ctrl, arrays["q"])
    arrays["qd_command"] = arrays["qd_command"].copy()
    arrays["q"] = arrays["q"].copy()
    arrays["qd_command"][2, 0] = bounds.qd_max[0] + 0.5
    arrays["qd_command"][3, 0] = -bounds.qd_max[0] - 0.25
    arrays["q"][4, 1] = bounds.q_max[1] + 0.125
    m = compute_metrics(RunLog.from_arrays(arrays), ctrl.trajectory, bounds, T)
    assert m.velocity_violations == 2 and m.velocity_violation_max_rad_s == pytest.approx(0.5)
    assert m.position_violations == 1 and m.position_violation_max_rad == pytest.approx(0.125)


def test_the_loop_and_stream_figures_come_from_the_meta():
    meta = {
        "stop": {"late_commands": 3},
        "stream": {
            "plan_age_median_ms": 4.0,
            "plan_age_max_ms": 9.0,
            "planner_step_median_ms": 2.5,
        },
    }
    assert run_figures(meta) == {
        "late_commands": 3,
        "plan_age_median_s": pytest.approx(0.004),
        "plan_age_max_s": pytest.approx(0.009),
        "planner_step_median_s": pytest.approx(0.0025),
    }
    assert run_figures({}) == {} and run_figures({"stop": None, "stream": None}) == {}
