"""dqcontrol/runs/bounds.py: the bounds a controller promised, read from a real controller and
from stand-ins that hold only some of the attributes."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from dqcontrol.controllers import LocalController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.trajectories import Circle


def test_a_controller_with_a_constant_acceleration_limit(lbr4p):
    ctrl = LocalController(lbr4p, Circle(1.0), 0.05, acceleration_limit=10.0)
    spec = bounds_of(ctrl)
    np.testing.assert_array_equal(spec.q_min, lbr4p.limits.q_min)
    np.testing.assert_array_equal(spec.q_max, lbr4p.limits.q_max)
    np.testing.assert_array_equal(spec.qd_max, ctrl.qd_max)
    np.testing.assert_array_equal(spec.a_max, np.full(lbr4p.nq, 10.0))
    assert spec.a_max_per_sample is None


def test_without_its_own_limits_the_robots_are_taken(lbr4p):
    spec = bounds_of(SimpleNamespace(robot=lbr4p, a_max=np.full(lbr4p.nq, 3.0)))
    np.testing.assert_array_equal(spec.qd_max, lbr4p.limits.qd_max)
    np.testing.assert_array_equal(spec.a_max, np.full(lbr4p.nq, 3.0))
    assert bounds_of(SimpleNamespace(robot=lbr4p)).a_max is None


def test_dynamics_aware_limits_are_evaluated_at_each_sample(lbr4p):
    ctrl = SimpleNamespace(
        robot=lbr4p, dynamic_acceleration=True, acceleration_floor=1.0, acceleration_cap=50.0
    )
    rng = np.random.default_rng(12)
    qs = LBR4P_Q0 + 0.3 * rng.standard_normal((4, lbr4p.nq))
    spec = bounds_of(ctrl, qs)
    assert spec.a_max is None and spec.a_max_per_sample.shape == (4, lbr4p.nq)
    for q, row in zip(qs, spec.a_max_per_sample, strict=True):
        np.testing.assert_allclose(row, lbr4p._acceleration_limits(q, 1.0, 1.0, 50.0))
    assert np.all((spec.a_max_per_sample >= 1.0) & (spec.a_max_per_sample <= 50.0))
    assert bounds_of(ctrl).a_max_per_sample is None  # no samples given: nothing to evaluate
