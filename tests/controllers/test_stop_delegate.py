"""The path-maintaining stop of a controller without its own
(dqcontrol/controllers/stop_delegate.py): the path-following delegate takes the stopping
controller's bounds, phase and last commands, and the delegated steps brake the phase to
rest while keeping the path."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.controllers import LocalController, PathFollowingController, ProportionalController
from dqcontrol.controllers.stop_delegate import _acceleration_of, stop_delegate
from dqcontrol.dq import translation
from dqcontrol.model import LBR4P_Q0
from dqcontrol.trajectories import Circle

T = 0.05
THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])


def test_the_acceleration_bound_is_the_constant_one_or_the_dynamics():
    np.testing.assert_array_equal(_acceleration_of(SimpleNamespace(a_const=[2.0, 3.0])), [2, 3])
    by_a_max = _acceleration_of(SimpleNamespace(a_const=None, a_max=np.array([4.0])))
    np.testing.assert_array_equal(by_a_max, [4.0])
    assert _acceleration_of(SimpleNamespace(a_const=None)) == "dynamics"


@pytest.mark.parametrize("cls", [LocalController, ProportionalController])
def test_the_delegate_starts_where_the_controller_is(lbr4p, cls):
    ctrl = cls(
        lbr4p, Circle(2.0), T, velocity_limits=0.8 * THESIS_VEL, acceleration_limit=7.0,
        position_margin_rad=0.01,
    )  # fmt: skip
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    for _ in range(4):
        q = q + T * ctrl.step(q).qd_command
    delegate = stop_delegate(ctrl, q)
    assert isinstance(delegate, PathFollowingController) and delegate.stopping
    assert delegate.trajectory is ctrl.trajectory and delegate.period_s == T
    assert delegate.sigma == ctrl.sigma and delegate.end == "at_speed"
    np.testing.assert_array_equal(delegate.qd_prev, ctrl.qd_prev)
    np.testing.assert_array_equal(delegate.qd_before_prev, ctrl.qd_before_prev)
    np.testing.assert_array_equal(delegate.qd_max, 0.8 * THESIS_VEL)
    np.testing.assert_array_equal(delegate.a_const, np.full(7, 7.0))
    assert delegate.position_margin_rad == 0.01


def test_a_requested_stop_brakes_to_rest_on_the_path(lbr4p):
    ctrl = LocalController(
        lbr4p, Circle(2.0), T, velocity_limits=THESIS_VEL, acceleration_limit=10.0
    )
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    for _ in range(10):
        q = q + T * ctrl.step(q).qd_command
    ctrl.request_stop()
    assert ctrl.stopping and ctrl._stop_delegate is None  # built at the next step
    sigma, qd_prev, scalings = ctrl.sigma, ctrl.qd_prev.copy(), []
    for _ in range(30):
        res = ctrl.step(q)
        assert res.sigma == sigma  # the phase carries on from the controller's
        assert np.all(np.abs(res.qd_command - qd_prev) <= T * 10.0 + 1e-9)
        sigma, qd_prev = res.sigma_next, res.qd_command
        assert ctrl.sigma == sigma and ctrl.qd_prev is res.qd_command
        scalings.append(res.s)
        q = q + T * res.qd_command
    assert isinstance(ctrl._stop_delegate, PathFollowingController)
    assert np.all(np.diff(scalings) <= 1e-9) and scalings[-1] == 0.0  # solver noise: 1e-10
    assert np.max(np.abs(qd_prev)) < 1e-6  # at rest
    tool = translation(lbr4p.pose(q))[None, :]
    assert ctrl.trajectory.path_deviation(tool)[0] <= 0.5e-3
