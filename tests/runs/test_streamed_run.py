"""dqcontrol/runs/streamed_run.py: a streamed run loaded back equal to the in-memory run
(every field, meta, joint names), and decimated for display."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers import LocalController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.storage import load_run
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle

TIMING = ("solve_time_s", "step_time_s")


def _streamed(lbr4p, path, duration_s=1.0, **kwargs):
    controller = LocalController(lbr4p, Circle(duration_s), 0.01)
    return controller, run_kinematic(controller, LBR4P_Q0, log_file=path, **kwargs)


def test_every_field_meta_and_joint_names_round_trip(lbr4p, tmp_path):
    memory = run_kinematic(LocalController(lbr4p, Circle(3.0), 0.01), LBR4P_Q0)
    _, streamed = _streamed(lbr4p, tmp_path / "run.mcap", 3.0)
    log, record = load_run(streamed.log_file)
    assert record["complete"] and not record["interrupted"] and record["samples"] == len(log)
    assert len(log) == len(memory.log) > 200 >= len(streamed.log)  # a window of <= 2 s
    for name, x in memory.log.arrays().items():
        y = log.arrays()[name]
        assert y.dtype == x.dtype, name
        if name not in TIMING:
            np.testing.assert_array_equal(y, x, err_msg=name)
    assert log.meta["joint_names"] == list(lbr4p.joint_names)
    assert log.meta["stop"]["reason"] == "end" and log.meta["period_s"] == 0.01
    np.testing.assert_array_equal(streamed.log.t_s, log.t_s[-len(streamed.log) :])


def test_a_long_run_loads_decimated_for_display(lbr4p, tmp_path):
    _, streamed = _streamed(lbr4p, tmp_path / "run.mcap", max_time_s=0.5)
    full, _ = load_run(streamed.log_file)
    small, record = load_run(streamed.log_file, max_samples=10)
    assert record["stride"] == 5 and len(small) <= 11
    np.testing.assert_array_equal(small.t_s[:-1], full.t_s[::5][: len(small) - 1])
    assert small.t_s[-1] == full.t_s[-1]
