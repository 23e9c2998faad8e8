"""``dqcontrol.faults.qp_faults``: contradictory bounds against a hand construction, and wrapped
controllers in short kinematic loops (every priority mode, path following) relaxing or braking."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers import (
    LocalController,
    PathFollowingController,
    PredictiveController,
    ProportionalController,
)
from dqcontrol.errors import ParameterError
from dqcontrol.faults import ContradictoryBoundsQP, contradictory
from dqcontrol.model import LBR4P_Q0
from dqcontrol.trajectories import Circle


def test_contradictory_bounds_reach_the_solver(lbr4p):
    ctrl = contradictory(PredictiveController)(
        lbr4p, Circle(2.0), 0.05, num_instants=6, contradiction="coupled", window_steps=(1, 3)
    )
    assert isinstance(ctrl.qp, ContradictoryBoundsQP)
    assert type(ctrl).__name__ == "ContradictoryPredictiveController"
    ctrl.reset(LBR4P_Q0)
    q = LBR4P_Q0.copy()
    relaxed = []
    for _ in range(5):
        res = ctrl.step(q)
        relaxed.append(res.diagnostics.relaxed)
        q = q + 0.05 * res.qd_command
    # the controller's own remedy (dropping the predicted boxes) restores feasibility
    assert relaxed == [False, True, True, False, False]
    assert ctrl.qp.corrupted_solves == 2 and ctrl.qp.false_successes == 0
    lo, up, made = ctrl.qp.corrupt(*ctrl.last_problem()[3:])
    assert made and np.any(lo > ctrl.last_problem().lower)


def _corrupted(ctrl, steps: int, period_s: float) -> tuple[int, int, np.ndarray]:
    """``(corrupted solves, fallbacks, |qd| largest over the run)`` of a closed loop."""
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    fallbacks, qd_peak = 0, np.zeros(ctrl.n)
    for _ in range(steps):
        res = ctrl.step(q)
        fallbacks += res.diagnostics.fallback
        qd_peak = np.maximum(qd_peak, np.abs(res.qd_command))
        q = q + period_s * res.qd_command
    return ctrl.backend.corrupted_solves, fallbacks, qd_peak


@pytest.mark.parametrize("mode", ["crossed", "coupled"])
def test_contradictory_reaches_every_priority_mode(lbr4p, mode):
    """The wrapper sits on the one backend every QP of a step goes to: the strict
    priority's levels (the warm levels, the reduced levels) see it as the weighted
    controller's single level does."""
    counts = {}
    for priority in ("weighted", "strict"):
        ctrl = contradictory(PredictiveController)(
            lbr4p, Circle(2.0), 0.05, num_instants=6, contradiction=mode,
            window_steps=(2, 7), priority=priority,
        )  # fmt: skip
        counts[priority] = _corrupted(ctrl, 10, 0.05)[:2]
    assert counts["strict"] == counts["weighted"]
    assert counts["weighted"][0] >= 5  # every step of the window, and its relaxed retry


@pytest.mark.parametrize("mode", ["crossed", "coupled"])
def test_path_following_runs_the_contradictory_faults(lbr4p, mode):
    """No feasible point in the window: the path-following controller tries its remedies,
    then brakes within its bounds (the safe fallback), and resumes after the window."""
    ctrl = contradictory(PathFollowingController)(
        lbr4p, Circle(2.0), 0.05, contradiction=mode, window_steps=(2, 5),
        velocity_limits=1.0, acceleration_limit=5.0,
    )  # fmt: skip
    assert isinstance(ctrl.backend, ContradictoryBoundsQP) and ctrl.qp is ctrl.backend
    corrupted, fallbacks, qd_peak = _corrupted(ctrl, 12, 0.05)
    assert corrupted >= 3 and fallbacks == 3
    assert ctrl.backend.false_successes == 0
    assert np.all(qd_peak <= 1.0 + 1e-9)
    assert ctrl.sigma > 0.0  # the task went on after the window


def test_contradictory_needs_a_qp_controller(lbr4p):
    with pytest.raises(ParameterError, match="QP controller class"):
        contradictory(ProportionalController)
    with pytest.raises(ParameterError, match="mode 'coupled' needs a predictive controller"):
        contradictory(LocalController)(lbr4p, Circle(1.0), 0.05, contradiction="coupled")


@pytest.fixture
def backend(lbr4p):
    """A real backend to wrap (the local controller's)."""
    return LocalController(lbr4p, Circle(1.0), 0.05).backend


def test_crossed_bounds_put_the_lower_bound_above_the_upper(backend):
    qp = ContradictoryBoundsQP(backend, num_joints=3, num_instants=2, joint=1, gap=0.25)
    lower, upper = -np.arange(1.0, 11.0), np.arange(1.0, 11.0)
    lo, up, made = qp.corrupt(lower, upper)
    assert made and lo[1] == upper[1] + 0.25 and lo[1] > up[1]
    np.testing.assert_array_equal(np.delete(lo, 1), np.delete(lower, 1))
    np.testing.assert_array_equal(up, upper)
    assert lower[1] == -2.0  # the inputs are left alone


def test_coupled_bounds_put_the_second_instant_out_of_reach(backend):
    """Variables ``[qd_1 (n), s_1, qd_2 (n), s_2]`` then the coupling rows ``|qd_2 - qd_1| ≤ dv``:
    joint j's ``qd_2`` is pinned to ``up(qd_1) + dv + gap``."""
    n, p, j, gap = 3, 2, 2, 0.5
    qp = ContradictoryBoundsQP(
        backend, num_joints=n, num_instants=p, mode="coupled", joint=j, gap=gap
    )
    size = p * (n + 1) + n
    lower, upper = np.full(size, -1.0), np.full(size, 1.0)
    upper[p * (n + 1) + j] = 0.3  # the coupling row of joint j: dv
    lo, up, made = qp.corrupt(lower, upper)
    row = n + 1 + j
    assert made and lo[row] == up[row] == 1.0 + 0.3 + gap
    # a relaxed QP (instant 2 free) is left as it is
    lower[row], upper[row] = -np.inf, np.inf
    lo, up, made = qp.corrupt(lower, upper)
    assert not made and np.array_equal(lo, lower) and np.array_equal(up, upper)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"mode": "swapped"}, "mode must be one of ('crossed', 'coupled')"),
        ({"mode": "coupled", "num_instants": 1}, "needs a predictive controller"),
        ({"joint": 7}, "joint must be in [0, 6], got 7"),
        ({"gap": 0.0}, "gap must be > 0 [rad/s]"),
    ],
)
def test_bad_wrapper_settings(backend, kwargs, message):
    settings = {"num_joints": 7, "num_instants": 6} | kwargs
    with pytest.raises(ParameterError) as info:
        ContradictoryBoundsQP(backend, **settings)
    assert message in str(info.value)


def test_a_bad_window_is_refused(lbr4p):
    with pytest.raises(ParameterError, match="window_steps must be \\(first, stop\\)"):
        contradictory(LocalController)(lbr4p, Circle(1.0), 0.05, window_steps=(5, 2))
    assert contradictory(LocalController) is contradictory(LocalController)  # one class per base
