"""The path-following controller at short periods: the path weights of the predicted states
do not shrink with ``T``, the coupling rows keep a larger acceleration reserve where the
loop re-plans within the plan's second interval, and a plan that cannot brake in time on
the new grid is loosened before the predicted position rows are dropped (docs/theory.md
§8.2, §8.4, §8.6)."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers import PathFollowingController
from dqcontrol.controllers.path_following.tuning import (
    RESERVE_REPLANNED_OFTEN,
    RESERVE_REPLANNED_ONCE,
    PathFollowingTuning,
)
from dqcontrol.controllers.terms.path_error import PathErrorTerm
from dqcontrol.errors import ParameterError
from dqcontrol.experiments.thesis import LBR4P_Q0, THESIS_VELOCITY_LIMITS
from dqcontrol.sim.kinematic import run_kinematic
from dqcontrol.trajectories import Circle, Sinusoid


def _controller(robot, period_s: float, trajectory=None, **kwargs) -> PathFollowingController:
    return PathFollowingController(
        robot, Circle(2.0) if trajectory is None else trajectory, period_s,
        velocity_limits=THESIS_VELOCITY_LIMITS, acceleration_limit=5.0, **kwargs,
    )  # fmt: skip


def _row_weights(ctrl: PathFollowingController, term: PathErrorTerm) -> np.ndarray:
    ctrl.reset(LBR4P_Q0)
    pred = ctrl.prediction_model.predict(LBR4P_Q0, 0.0)
    return term.residual(ctrl._context_at(LBR4P_Q0, pred)).row_weights[::6]


@pytest.mark.parametrize("period_s", [0.001, 0.05])
def test_the_states_within_the_full_weight_time_weigh_fully(lbr4p, period_s):
    ctrl = _controller(lbr4p, period_s)
    layout = ctrl.layout
    ends = layout.instants_s + layout.durations_s
    full = max(float(ends[0]), 0.05)
    weights = _row_weights(ctrl, PathErrorTerm(1.0, 0.05))
    np.testing.assert_array_equal(weights[ends <= full], 1.0)
    np.testing.assert_allclose(weights[ends > full], (full / ends[ends > full]) ** 2, rtol=1e-15)
    # without a full-weight time the weights fall from the first interval on: at 1 kHz the
    # state 0.2 s ahead would weigh 2.5e-5 of the next one
    shrinking = _row_weights(ctrl, PathErrorTerm(1.0, 0.0))
    np.testing.assert_allclose(shrinking, (ends[0] / ends) ** 2, rtol=1e-15)
    if period_s < 0.05:
        assert (weights > shrinking).sum() == ends.size - 1


def _first_step(robot, gap_rad: float):
    """The controller and its first step with joint 1 ``gap_rad`` inside its upper bound,
    moving towards it at 1 rad/s (braking at 5 rad/s² needs about 0.1 rad)."""
    ctrl = _controller(robot, 0.01, tuning=PathFollowingTuning(position_slack_rad=1e-3))
    q0 = LBR4P_Q0.copy()
    q0[0] = ctrl.q_max[0] - gap_rad
    qd0 = np.zeros(7)
    qd0[0] = 1.0
    ctrl.reset(q0, qd0)
    return ctrl, ctrl.step(q0, qd0)


def _first_step_message(robot, gap_rad: float) -> str:
    """The first step's message (:func:`_first_step`)."""
    result = _first_step(robot, gap_rad)[1]
    assert not result.diagnostics.fallback
    assert result.qd_command[0] <= 1.0 + 1e-9
    return result.diagnostics.message


def test_a_plan_that_cannot_brake_in_time_is_loosened_before_its_rows_are_dropped(lbr4p):
    # the gap below which the predicted position rows leave no plan, by bisection
    feasible, infeasible = 0.3, 0.0
    assert _first_step_message(lbr4p, feasible) == ""
    assert "dropped" in _first_step_message(lbr4p, infeasible)
    while feasible - infeasible > 2e-5:
        mid = 0.5 * (feasible + infeasible)
        if _first_step_message(lbr4p, mid) == "":
            feasible = mid
        else:
            infeasible = mid
    # 0.3 mrad short of it: 1 mrad of slack gives a plan
    assert "loosened by 1 mrad" in _first_step_message(lbr4p, infeasible - 3e-4)
    # 5 mrad short: the rows are dropped, the applied command keeps its hard bounds
    assert "dropped" in _first_step_message(lbr4p, infeasible - 5e-3)


def test_a_negative_position_slack_is_refused():
    with pytest.raises(ParameterError, match="position_slack_rad"):
        PathFollowingTuning(position_slack_rad=-1e-3)


def test_the_default_reserve_follows_how_often_the_loop_replans_the_second_interval(lbr4p):
    given = PathFollowingTuning(acceleration_reserve=0.8)
    for period_s, tuning, reserve in (
        (0.05, None, RESERVE_REPLANNED_ONCE),
        (0.01, None, RESERVE_REPLANNED_ONCE),  # the second interval is 12.2 ms
        (0.005, None, RESERVE_REPLANNED_OFTEN),
        (0.001, None, RESERVE_REPLANNED_OFTEN),
        (0.001, given, 0.8),
        (0.05, given, 0.8),
    ):
        ctrl = _controller(lbr4p, period_s, tuning=tuning)
        coupling = ctrl.layout.durations_s[1:] + ctrl.layout.durations_s[:-1]
        limit = next(lim for lim in ctrl.limits if lim.name == "acceleration")
        np.testing.assert_allclose(limit.coupling_s, 0.5 * coupling * reserve, rtol=1e-15)


def test_at_1khz_a_tight_constant_bound_keeps_the_path(lbr4p):
    # Table 1's setting for this controller (5 rad/s², the thesis's velocity bounds) on the
    # sinusoid at 2 s; with the reserve of a slow loop the applied command falls behind the
    # plan and the tool leaves the path by more than the kinematic loop's 0.1 mm (within the
    # first second)
    def metrics(tuning, max_time_s):
        ctrl = _controller(lbr4p, 0.001, Sinusoid(2.0), tuning=tuning)
        return run_kinematic(ctrl, LBR4P_Q0.copy(), max_time_s=max_time_s).metrics

    default = metrics(None, 6.0)
    assert default.completed and default.path_deviation_max_m <= 0.1e-3
    slow_loop = PathFollowingTuning(acceleration_reserve=RESERVE_REPLANNED_ONCE)
    assert metrics(slow_loop, 1.0).path_deviation_max_m > 0.1e-3


def test_last_problem_is_the_problem_solved_with_its_remedy(lbr4p):
    """Where the predicted position rows had to be dropped, the problem the step solved, and
    that ``last_problem`` gives, has none; where they were kept, it has them."""
    for gap_rad, kept in ((0.3, True), (0.0, False)):
        ctrl, result = _first_step(lbr4p, gap_rad)
        names = {g.name for g in ctrl.last_problem().inequalities}
        assert ("predicted_position" in names) == kept, (gap_rad, names)
        assert result.diagnostics.relaxed == (not kept)
