"""Fixtures shared by the tests of ``dqcontrol.viz``: a short MuJoCo run to draw."""

from __future__ import annotations

import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.model import LBR4P_Q0
from dqcontrol.trajectories import Circle


@pytest.fixture(scope="session")
def mujoco_run(lbr4p):
    """A short MuJoCo run of the local controller on the circle (T_tot = 1 s)."""
    from dqcontrol.sim import run_mujoco

    controller = LocalController(lbr4p, Circle(1.0), 0.05)
    result = run_mujoco(controller, LBR4P_Q0, meta={"velocity_limits": 3.0})
    return result, controller.trajectory
