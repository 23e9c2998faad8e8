"""The stall damping (dqcontrol/controllers/terms/stall_damping.py): its weight from the
applied scalings against the rule written out (docs/theory.md §4.3), and graceful
degradation on an unreachable path: time scaling drives s to 0, and the stall damping
brings the arm to rest near the path instead of chattering at the bounds."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.step_contexts import random_context, split

from dqcontrol.controllers import LocalController, PredictiveController
from dqcontrol.controllers.terms.stall_damping import StallDampingTerm
from dqcontrol.dq import translation
from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle


def _unreachable_run(robot, cls, stall_damping):
    # R = 0.4 m: the far side of the circle is out of the LBR4p's reach from LBR4P_Q0
    ctrl = cls(robot, Circle(2.0, radius_m=0.4), 0.05, stall_damping=stall_damping)
    res = run_kinematic(ctrl, LBR4P_Q0, max_time_s=6.0)
    log = res.log
    speed_end = float(np.abs(log.qd_command[-20:]).max())  # last second
    dev_end = float(ctrl.trajectory.path_deviation(translation(robot.pose(log.q[-1]))))
    return res, speed_end, dev_end


@pytest.mark.parametrize("cls", [LocalController, PredictiveController])
def test_unreachable_path_stops_at_rest_near_the_path(lbr4p, cls):
    res, speed_end, dev_end = _unreachable_run(lbr4p, cls, 1e-3)
    assert not res.metrics.completed
    assert np.all(np.diff(res.log.sigma) >= 0.0) and res.log.sigma[-1] < 0.3
    assert res.log.s[-20:].max() < 0.02
    assert speed_end < 0.02  # rad/s: at rest
    assert dev_end < 0.01 and res.metrics.path_deviation_max_m < 0.01  # m: on the path
    assert res.metrics.velocity_violations == 0 and res.metrics.acceleration_violations == 0


@pytest.mark.parametrize("cls", [LocalController, PredictiveController])
def test_without_stall_damping_the_stalled_arm_keeps_chattering(lbr4p, cls):
    """The mechanism the damping fixes: the thesis's cost alone keeps chasing the
    unreachable target at the acceleration bound."""
    res, speed_end, _ = _unreachable_run(lbr4p, cls, 0.0)
    assert not res.metrics.completed
    assert speed_end > 0.1


def test_stall_damping_leaves_a_feasible_task_alone(lbr4p):
    """On a slow circle s never drops below stall_scaling: the commands are the thesis's."""
    runs = [
        run_kinematic(LocalController(lbr4p, Circle(8.0), 0.05, stall_damping=d), LBR4P_Q0)
        for d in (0.0, 1e-3)
    ]
    assert runs[0].log.s.min() > 0.05
    np.testing.assert_array_equal(runs[0].log.qd_command, runs[1].log.qd_command)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"stall_damping": -1e-3}, "stall_damping must be finite and ≥ 0"),
        ({"stall_damping": float("nan")}, "stall_damping"),
        ({"stall_scaling": 0.0}, "stall_scaling must be finite and > 0"),
        ({"stall_scaling": 1.5}, r"stall_scaling must be in \(0, 1\]"),
        ({"stall_delay_s": -0.1}, "stall_delay_s must be finite and ≥ 0"),
    ],
)
def test_stall_parameters_are_checked(lbr4p, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        LocalController(lbr4p, Circle(2.0), 0.05, **kwargs)


def test_a_slow_start_is_not_a_stall(lbr4p):
    """At 1 kHz the arm needs many periods to accelerate, so s starts below stall_scaling:
    the damping must wait (stall_delay_s) and the run equal the thesis's cost's."""
    runs = [
        run_kinematic(
            LocalController(lbr4p, Circle(0.3), 0.001, stall_damping=d), LBR4P_Q0, max_time_s=3.0
        )
        for d in (0.0, 1e-3)
    ]
    assert runs[1].metrics.completed
    assert runs[0].log.s[:10].max() < 0.05  # it does start slowly
    np.testing.assert_array_equal(runs[0].log.qd_command, runs[1].log.qd_command)


def numpy_stall_weights(s_applied: list[float], mu: float, s_stall: float, delay: int):
    """The stall damping's weight at each step from the applied ``s`` of the steps before
    (docs/theory.md §4.3), written out."""
    weights, below, last = [], 0, 1.0
    for s in s_applied:
        weights.append(mu * (1.0 - last / s_stall) if below >= delay and mu else 0.0)
        below = below + 1 if s < s_stall else 0
        last = s
    return weights


def test_stall_damping_memory_and_weight(lbr4p):
    ctx = random_context(lbr4p, 2, seed=3)
    layout = ctx.layout
    term = StallDampingTerm(layout, weight_max=1e-3, stall_scaling=0.05, delay_steps=3)
    rng = np.random.default_rng(4)
    s_seq = list(np.where(rng.random(60) < 0.7, rng.uniform(0.0, 0.05, 60), 0.5))
    expected = numpy_stall_weights(s_seq, 1e-3, 0.05, 3)
    assert any(w > 0 for w in expected) and any(w == 0 for w in expected)
    for s_now, want in zip(s_seq, expected, strict=True):
        term.prepare(ctx)
        assert term.weight == pytest.approx(want, abs=0)
        res = term.residual(ctx)
        assert res.weight == term.weight and not res.held
        z = rng.normal(size=layout.num_vars)
        np.testing.assert_allclose(res.value(layout, z), split(layout, z)[0].ravel(), atol=0)
        hessian = np.zeros((2, 8, 8))
        assert term.add_gram(ctx, hessian)
        expected_h = np.zeros((2, 8, 8))
        expected_h[:, np.arange(7), np.arange(7)] = 2.0 * want
        np.testing.assert_array_equal(hessian, expected_h)
        term.observe(None, s_now)
    term.reset()
    term.prepare(ctx)
    assert term.weight == 0.0 and term.stalled_steps == 0


def test_delay_in_steps():
    assert StallDampingTerm.delay_steps_for(0.5, 1e-3) == 500
    assert StallDampingTerm.delay_steps_for(0.5, 0.05) == 10
    assert StallDampingTerm.delay_steps_for(0.0, 0.05) == 0
