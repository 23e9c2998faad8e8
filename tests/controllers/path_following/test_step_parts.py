"""The path-following step's compiled bookkeeping and kept kinematics against plain numpy
(docs/theory.md §8): the linearisation mismatch, the kinematics memo."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.path_following.kernels import tangent_mismatch
from dqcontrol.controllers.path_following.kinematics_memo import KinematicsMemo
from dqcontrol.controllers.terms.path_error import PROJECTOR_BASIS, tangent_projectors
from dqcontrol.model import LBR4P_Q0
from dqcontrol.trajectories import Circle


@pytest.mark.parametrize(("seed", "flip"), [(0, False), (1, True), (2, False)])
def test_tangent_mismatch_is_the_largest_difference_of_the_errors(seed, flip):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=8)
    xd = (-1.0 if flip else 1.0) * (x + rng.normal(scale=0.1, size=8))
    rows, b, z = rng.normal(size=(9, 12)), rng.normal(size=9), rng.normal(size=12)
    aligned = -x if float(x @ xd) < 0.0 else x
    true = tangent_projectors(aligned[None, :])[0] @ (aligned - xd)
    expected = np.max(np.abs(true - (rows[:6] @ z - b[:6])))
    got = tangent_mismatch(x, xd, PROJECTOR_BASIS, rows, b, z)
    assert got == pytest.approx(expected, rel=1e-13, abs=1e-15)
    b[2] = np.nan
    assert np.isnan(tangent_mismatch(x, xd, PROJECTOR_BASIS, rows, b, z))


def test_the_memo_hands_back_the_last_steps_kinematics_once(lbr4p):
    memo = KinematicsMemo(lbr4p)
    traj = Circle(2.0).anchored_at(lbr4p.pose(LBR4P_Q0))
    q1 = LBR4P_Q0 + 0.01
    x1 = lbr4p.fast.poses(q1[None, :])[0]
    xd1 = traj.target(0.25)
    memo.keep_pose(q1, x1)
    memo.keep_target(traj, 0.25, xd1)
    assert memo.pose(q1) is not x1  # kept during this step: read during the next
    memo.advance()
    assert memo.pose(q1.copy()) is x1 and memo.target(traj, 0.25) is xd1
    again = memo.pose(q1.copy())  # handed out once: computed again
    assert again is not x1 and np.array_equal(again, x1)
    assert np.array_equal(memo.target(traj, 0.25), xd1)
    memo.keep_pose(q1, x1)
    memo.keep_target(traj, 0.25, xd1)
    memo.advance()
    other = q1.copy()
    other[3] += 1e-15
    assert np.array_equal(memo.pose(other), lbr4p.fast.poses(other[None, :])[0])
    assert np.array_equal(memo.target(traj, 0.5), traj.target(0.5))
    assert np.array_equal(memo.target(traj, 0.25), xd1)  # still kept
    memo.keep_target(traj, 0.25, xd1)
    memo.advance()
    retargeted = Circle(2.0).anchored_at(lbr4p.pose(LBR4P_Q0 + 0.1))
    assert not np.array_equal(memo.target(retargeted, 0.25), xd1)


def test_results_with_and_without_the_memo_are_the_same(lbr4p):
    from dqcontrol.controllers import PathFollowingController

    runs = []
    for use_memo in (True, False):
        ctrl = PathFollowingController(lbr4p, Circle(2.0), 0.002, num_intervals=6)
        if not use_memo:
            ctrl._memo.advance = ctrl._memo.clear  # nothing is ever read back
        ctrl.reset(LBR4P_Q0)
        q, out = LBR4P_Q0.copy(), []
        for _ in range(30):
            r = ctrl.step(q)
            out.append(np.concatenate([r.qd_command, r.pose, r.target, r.horizon_qd.ravel()]))
            q = q + 0.002 * r.qd_command
        runs.append(np.array(out))
    assert np.array_equal(runs[0], runs[1])
