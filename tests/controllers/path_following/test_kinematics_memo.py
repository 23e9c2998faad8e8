"""The kinematics kept between path-following steps
(dqcontrol/controllers/path_following/kinematics_memo.py): what it hands back against fresh
evaluations, and whole runs with and without it bit for bit."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.path_following.kinematics_memo import KinematicsMemo
from dqcontrol.model import LBR4P_Q0
from dqcontrol.trajectories import Circle


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


def test_clear_forgets_what_was_kept(lbr4p):
    memo = KinematicsMemo(lbr4p)
    traj = Circle(2.0).anchored_at(lbr4p.pose(LBR4P_Q0))
    x0, xd0 = lbr4p.fast.poses(LBR4P_Q0[None, :])[0], traj.target(0.5)
    memo.keep_pose(LBR4P_Q0, x0)
    memo.keep_target(traj, 0.5, xd0)
    memo.clear()
    memo.advance()
    again, target = memo.pose(LBR4P_Q0.copy()), memo.target(traj, 0.5)
    assert again is not x0 and np.array_equal(again, x0)
    assert target is not xd0 and np.array_equal(target, xd0)
