"""dqcontrol/sim/kinematic.py: ``run_kinematic`` bit for bit against the kinematic loop
written out (``q_{k+1} = q_k + T u_k``), its time limit and its braking option."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.log import LogRecorder
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle, Sinusoid

TIMING = ("solve_time_s", "step_time_s")


def _reference_kinematic(controller, q0):
    """The kinematic loop written out: q_{k+1} = q_k + T u_k, qd measured = u_{k-1}."""
    q = controller.robot.check_q(q0).copy()
    controller.reset(q)
    period = controller.period_s
    rec = LogRecorder(controller.robot.nq)
    qd = np.zeros(controller.robot.nq)
    for k in range(int(np.ceil((10.0 * controller.trajectory.duration + 1.0) / period - 1e-9))):
        result = controller.step(q, qd)
        rec.record(k * period, q, qd, result)
        qd = result.qd_command
        q = q + period * result.qd_command
        if controller.done:
            break
    return rec.finish()


def _assert_same_log(a, b):
    assert len(a) == len(b)
    for name, x in a.arrays().items():
        if name not in TIMING:
            np.testing.assert_array_equal(x, b.arrays()[name], err_msg=name)


@pytest.mark.parametrize("traj", [Circle(1.0), Sinusoid(2.0)], ids=["circle1", "sinusoid2"])
def test_kinematic_loop_is_bit_identical_to_the_reference(lbr4p, traj):
    ref = _reference_kinematic(LocalController(lbr4p, traj, 0.05), LBR4P_Q0)
    res = run_kinematic(LocalController(lbr4p, traj, 0.05), LBR4P_Q0)
    _assert_same_log(ref, res.log)


def test_max_time_cuts_an_unfinished_run_short(lbr4p):
    res = run_kinematic(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0, max_time_s=0.3)
    assert not res.metrics.completed and len(res.log) == 6  # samples at 0, 0.05, ..., 0.25
    np.testing.assert_allclose(res.log.t_s, 0.05 * np.arange(6), atol=1e-12)


def test_the_state_between_samples_is_the_integrated_command(lbr4p):
    res = run_kinematic(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0, meta={"tag": 7})
    log = res.log
    np.testing.assert_allclose(log.q[1:], log.q[:-1] + 0.05 * log.qd_command[:-1], atol=1e-15)
    np.testing.assert_array_equal(log.qd_measured[1:], log.qd_command[:-1])
    assert log.meta["tag"] == 7 and log.meta["joint_names"] == list(lbr4p.joint_names)


def test_with_the_brake_the_run_ends_at_rest(lbr4p):
    free = run_kinematic(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0)
    braked = run_kinematic(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0, brake=True)
    assert free.log.meta["stop"] == {"reason": "end", "brake_periods": 0}
    stop = braked.log.meta["stop"]
    assert stop["at_rest"] and not braked.log.qd_command[-1].any()
    # the same run until the task's end at rest is handed over, near its end
    handed = stop["end_at_rest_from"]["sample"]
    assert 0 < handed < len(free.log) and stop["end_at_rest_from"]["sigma"] > 0.5
    np.testing.assert_array_equal(braked.log.q[:handed], free.log.q[:handed])
