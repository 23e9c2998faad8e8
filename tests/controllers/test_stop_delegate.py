"""The path-maintaining stop of a controller without its own
(dqcontrol/controllers/stop_delegate.py): the path-following delegate takes the stopping
controller's bounds, phase and last commands, and the delegated steps brake the phase to
rest while keeping the path."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.controllers import LocalController, PathFollowingController, ProportionalController
from dqcontrol.controllers.stop_delegate import _acceleration_of, end_lead_s, stop_delegate
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
    assert ctrl.stopping and ctrl._delegate is None  # built at the next step
    sigma, qd_prev, scalings = ctrl.sigma, ctrl.qd_prev.copy(), []
    for _ in range(30):
        res = ctrl.step(q)
        assert res.sigma == sigma  # the phase carries on from the controller's
        assert np.all(np.abs(res.qd_command - qd_prev) <= T * 10.0 + 1e-9)
        sigma, qd_prev = res.sigma_next, res.qd_command
        assert ctrl.sigma == sigma and ctrl.qd_prev is res.qd_command
        scalings.append(res.s)
        q = q + T * res.qd_command
    assert isinstance(ctrl._delegate, PathFollowingController)
    assert np.all(np.diff(scalings) <= 1e-9) and scalings[-1] == 0.0  # solver noise: 1e-10
    assert np.max(np.abs(qd_prev)) < 1e-6  # at rest
    tool = translation(lbr4p.pose(q))[None, :]
    assert ctrl.trajectory.path_deviation(tool)[0] <= 0.5e-3


def test_the_lead_is_two_braking_distances_and_the_jerk_turn():
    """By hand: joint 1 at 2 rad/s under 8 rad/s², s = 0.5, the rest share 0.5: the phase
    brakes at ``0.5 · 0.5 · 8/2 = 1`` 1/s and stops within ``0.5²/2 = 0.125`` s of phase;
    the jerk turn adds ``2 · 0.5 · max(8/4000, 4/1000)``."""
    qd, a_max = np.array([2.0, -0.5]), np.array([8.0, 4.0])
    assert end_lead_s(0.5, qd, a_max, np.full(2, np.inf)) == pytest.approx(2 * 0.125)
    jerk = np.array([4000.0, 1000.0])
    assert end_lead_s(0.5, qd, a_max, jerk) == pytest.approx(0.25 + 2 * 0.5 * 4e-3)
    assert end_lead_s(0.0, qd, a_max, jerk) == 0.0  # at rest: nothing to brake
    # no acceleration bound: the joint brakes at once (no nan, no infinite lead)
    unbounded = np.array([np.inf, 4.0])
    # joint 2 alone (0.5 rad/s under 4 rad/s²): the phase brakes at 0.5 · 0.5 · 4/0.5 = 2 /s and
    # stops within 0.5²/4 = 0.0625 s of phase; twice that
    assert end_lead_s(0.5, qd, unbounded, np.full(2, np.inf)) == pytest.approx(0.125)
    assert end_lead_s(0.5, qd, np.full(2, np.inf), jerk) == 0.0


def test_finishing_at_rest_hands_the_end_to_a_rest_to_rest_controller(lbr4p):
    ctrl = LocalController(lbr4p, Circle(1.0), T, velocity_limits=THESIS_VEL)
    ctrl.reset(LBR4P_Q0)
    q = LBR4P_Q0.copy()
    while ctrl.sigma < 0.7:
        q = q + T * ctrl.step(q).qd_command
    ctrl.finish_at_rest(q)
    assert ctrl.finishing and ctrl._delegate.ends_at_rest and not ctrl.stopping
    for _ in range(200):
        result = ctrl.step(q)
        q = q + T * result.qd_command
        if ctrl.done:
            break
    assert ctrl.done and result.s < 0.02  # the phase at rest within a period of 50 ms
    end = translation(ctrl.trajectory.target(1.0))
    assert np.linalg.norm(translation(lbr4p.pose(q)) - end) <= 1e-4
    ctrl.request_stop()  # a stop after the handover is the delegate's
    assert ctrl.stopping and ctrl._delegate.stopping and not ctrl.finishing


def test_a_controller_that_ends_at_rest_is_left_alone(lbr4p):
    ctrl = PathFollowingController(lbr4p, Circle(1.0), T, velocity_limits=THESIS_VEL)
    ctrl.reset(LBR4P_Q0)
    ctrl.finish_at_rest(LBR4P_Q0)
    assert ctrl.ends_at_rest and not ctrl.finishing
    at_speed = PathFollowingController(
        lbr4p, Circle(1.0), T, velocity_limits=THESIS_VEL, end="at_speed"
    )
    at_speed.reset(LBR4P_Q0)
    at_speed.finish_at_rest(LBR4P_Q0)
    assert not at_speed.ends_at_rest and at_speed.finishing
