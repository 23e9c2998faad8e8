"""dqcontrol/streaming/hook.py: the loop's hook leaves any other controller alone, and sets a
streamed controller's clock, reports its figures and closes it."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers import LocalController
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.streaming import streamed
from dqcontrol.streaming.hook import stream_hook
from dqcontrol.trajectories import Circle


def test_a_controller_that_is_not_streamed_is_left_alone(lbr4p):
    ctrl = LocalController(lbr4p, Circle(1.0), 0.05)
    closed = []
    ctrl.close = lambda: closed.append(1)  # would be called by a hook that is not a no-op
    ctrl.report = lambda: {"not": "a stream"}
    hook = stream_hook(ctrl, realtime=True)
    assert hook.controller is None and hook.meta() == {}
    hook.close()
    assert closed == []


def test_a_streamed_controller_is_stepped_and_reported(lbr4p):
    planner = PathFollowingController(lbr4p, Circle(1.0), 0.02, acceleration_limit=10.0)
    ctrl = streamed(planner, 0.01)
    ctrl.reset(LBR4P_Q0)
    hook = stream_hook(ctrl, realtime=False)
    assert hook.controller is ctrl
    q = np.array(LBR4P_Q0, dtype=float)
    for _ in range(4):
        q = q + 0.01 * ctrl.step(q).qd_command
    meta = hook.meta()
    assert set(meta) == {"stream"} and meta["stream"]["wall_clock"] is False
    assert meta["stream"]["period_s"] == 0.01 and meta["stream"]["plan_period_s"] == 0.02
    assert meta["stream"]["plans"] >= 2
    hook.close()  # no planner thread in stepped mode: nothing to stop, no error
