"""A limit defined only in a file of the test suite (``tests/joint_below_limit.py``) works in
every QP controller (the thesis's and the path-following one) without editing the package
(docs/theory.md §7.7), and the documentation's worked example is that limit."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from joint_below_limit import KeepJointBelow

from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
)
from dqcontrol.controllers.core.problem import Bounds
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.model import LBR4P_Q0
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle

THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
T = 0.01

CONTROLLERS = {
    "local": (LocalController, {}),
    "p6": (PredictiveController, {"num_instants": 6}),
    "noscale_p6": (PredictiveNoScalingController, {"num_instants": 6}),
    "path_following": (PathFollowingController, {"num_intervals": 6}),
}


def make(name, priority, extra_limits=()):
    from dqcontrol import load_lbr4p

    cls, kw = CONTROLLERS[name]
    if cls is not PathFollowingController:  # its levels are strict by construction
        kw = {**kw, "priority": priority}
    return cls(
        load_lbr4p(), Circle(2.0), T, velocity_limits=THESIS_VEL, acceleration_limit=10.0,
        extra_limits=extra_limits, **kw,
    )  # fmt: skip


@pytest.fixture(scope="module")
def rising_joint():
    """The joint that rises most above its start on the task without the limit (the local
    controller), and an angle half way up."""
    res = run_kinematic(make("local", "weighted"), LBR4P_Q0, max_time_s=3.0)
    rise = res.log.q.max(axis=0) - LBR4P_Q0
    joint = int(np.argmax(rise))
    return joint, float(LBR4P_Q0[joint] + 0.5 * rise[joint])


@pytest.mark.parametrize("priority", ["weighted", "strict"])
@pytest.mark.parametrize("name", list(CONTROLLERS))
def test_a_limit_from_the_test_suite_in_every_controller(name, priority, rising_joint):
    joint, angle = rising_joint
    ctrl = make(name, priority, (KeepJointBelow(joint, angle),))
    free = run_kinematic(make(name, priority), LBR4P_Q0, max_time_s=3.0)
    assert free.log.q[:, joint].max() > angle + 1e-3  # the task would cross it
    res = run_kinematic(ctrl, LBR4P_Q0, max_time_s=3.0)
    assert res.log.q[:, joint].max() <= angle + 1e-9
    assert res.metrics.position_violations == res.metrics.velocity_violations == 0
    assert res.metrics.acceleration_violations == 0
    limits = [b.name for b in ctrl.last_problem().bounds]
    assert "keep_joint_below" in limits


def test_the_documented_example_is_this_limit():
    """The code block of docs/theory.md §7.7 defines the same limit, and it runs."""
    text = (Path(__file__).resolve().parents[3] / "docs" / "theory.md").read_text("utf-8")
    section = text[text.index("### 7.7") :]
    code = re.search(r"```python\n(.*?)```", section, flags=re.DOTALL).group(1)
    namespace = {"math": math, "np": np, "Bounds": Bounds, "Limit": Limit}
    exec(compile(code, "theory.md §7.7", "exec"), namespace)  # noqa: S102 - our own docs
    documented = namespace["KeepJointBelow"]
    ctrl = make("local", "weighted", (documented(3, LBR4P_Q0[3]),))
    ctrl.reset(LBR4P_Q0)
    res = ctrl.step(LBR4P_Q0)
    assert res.qd_command[3] <= 0.0  # at the angle: it may not move up
    source = (Path(__file__).resolve().parents[2] / "joint_below_limit.py").read_text("utf-8")
    body = source[source.index("class KeepJointBelow") :]
    assert code[code.index("class KeepJointBelow") :].strip() == body.strip()
