"""Fixtures shared by the run-log tests: a kinematic run stopped half-way along its task."""

from __future__ import annotations

import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim import KinematicDriver, run_loop
from dqcontrol.trajectories import Circle

#: The period of the stopped run [s].
STOPPED_PERIOD_S = 0.05


@pytest.fixture(scope="module")
def stopped(lbr4p):
    """A run stopped at σ = 0.5 (its log has task and stop samples)."""
    ctrl = LocalController(lbr4p, Circle(1.0), STOPPED_PERIOD_S)

    def request(_k, _driver, result) -> None:
        if result.sigma_next >= 0.5 and not ctrl.stopping:
            ctrl.request_stop()

    return ctrl, run_loop(
        ctrl, KinematicDriver(lbr4p, STOPPED_PERIOD_S), q0=LBR4P_Q0, on_sample=request
    )
