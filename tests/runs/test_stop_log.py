"""The stop in the run log (dqcontrol/runs/log.py, columns.py, storage.py, metrics.py): the
per-sample ``stopping`` flag through every file format, logs without it, and the ``stop_*``
metrics against a hand computation."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.dq.algebra import translation
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.log import RunLog
from dqcontrol.runs.metrics import compute_metrics
from dqcontrol.runs.storage import load_run, save_run
from dqcontrol.sim import KinematicDriver, run_loop
from dqcontrol.trajectories import Circle

T = 0.05


@pytest.fixture(scope="module")
def stopped(lbr4p):
    """A run stopped at σ = 0.5 (its log has task and stop samples)."""
    ctrl = LocalController(lbr4p, Circle(1.0), T)

    def request(_k, _driver, result) -> None:
        if result.sigma_next >= 0.5 and not ctrl.stopping:
            ctrl.request_stop()

    return ctrl, run_loop(ctrl, KinematicDriver(lbr4p, T), q0=LBR4P_Q0, on_sample=request)


def test_the_flag_survives_npz_and_json(stopped, tmp_path):
    _ctrl, result = stopped
    assert result.log.stopping.any() and not result.log.stopping.all()
    save_run(result, tmp_path, "stopped")
    log, record = load_run(tmp_path / "stopped")
    np.testing.assert_array_equal(log.stopping, result.log.stopping)
    assert record["metrics"]["stop_samples"] == int(result.log.stopping.sum())


def test_the_flag_and_the_metrics_of_a_streamed_log(lbr4p, tmp_path):
    ctrl = LocalController(lbr4p, Circle(1.0), T)

    def request(_k, _driver, result) -> None:
        if result.sigma_next >= 0.5 and not ctrl.stopping:
            ctrl.request_stop()

    streamed = run_loop(
        ctrl, KinematicDriver(lbr4p, T), q0=LBR4P_Q0, log_file=tmp_path / "run.mcap",
        on_sample=request,
    )  # fmt: skip
    log, _ = load_run(streamed.log_file)
    assert log.stopping.dtype == bool and len(log) == len(log.stopping)
    assert log.stopping.sum() == streamed.log.meta["stop"]["stop_periods"] > 0
    assert not log.stopping[: int(np.argmax(log.stopping))].any()
    # the block-by-block metrics (the streamed run's) are the in-memory ones
    whole = compute_metrics(log, ctrl.trajectory, bounds_of(ctrl, log.q), T).as_dict()
    blocks = streamed.metrics.as_dict()
    for key in ("completed", "samples", *(k for k in whole if k.startswith("stop_"))):
        assert blocks[key] == pytest.approx(whole[key], rel=1e-12), key


def test_a_log_without_the_flag_reads_as_no_stop(stopped, tmp_path):
    _ctrl, result = stopped
    arrays = result.log.arrays()
    del arrays["stopping"]
    log = RunLog.from_arrays(arrays)
    assert log.stopping.shape == log.t_s.shape and not log.stopping.any()


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
