"""dqcontrol/runs/stop_totals.py: the ``stop_*`` metrics of a streamed run, taken block by
block, equal those of ``compute_metrics`` over the whole log; the ``stopping`` flag through
the streamed file."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.metrics import compute_metrics
from dqcontrol.runs.storage import load_run
from dqcontrol.sim import KinematicDriver, run_loop
from dqcontrol.trajectories import Circle

T = 0.05


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
