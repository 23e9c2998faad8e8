"""dqcontrol/sim/mujoco_loop.py: ``run_mujoco`` bit for bit against the MuJoCo loop written
out (measure, step, hold one period), its simulation options and its sample callback."""

from __future__ import annotations

import numpy as np
import pytest
from sim.test_kinematic import _assert_same_log

from dqcontrol.controllers import LocalController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.log import LogRecorder
from dqcontrol.sim import MujocoSimulation, run_mujoco
from dqcontrol.trajectories import Circle


def _reference_mujoco(controller, q0):
    """The MuJoCo loop written out: measure, step, hold one period, record with torques."""
    sim = MujocoSimulation(controller.robot)
    meas = sim.reset(q0)
    controller.reset(meas.q)
    rec = LogRecorder(controller.robot.nq)
    for _ in range(int(np.ceil((10.0 * controller.trajectory.duration + 1.0) / 0.05 - 1e-9))):
        result = controller.step(meas.q, meas.qd)
        before = meas
        meas = sim.step(result.qd_command, controller.period_s)
        rec.record(before.t_s, before.q, before.qd, result, meas.torque, meas.torque_peak)
        if controller.done:
            break
    return rec.finish()


def test_mujoco_loop_is_bit_identical_to_the_reference(lbr4p):
    ref = _reference_mujoco(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0)
    res = run_mujoco(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0)
    _assert_same_log(ref, res.log)
    assert res.log.meta["joint_names"] == list(lbr4p.joint_names)
    assert res.log.meta["simulator"] == "mujoco" and res.log.meta["physics_dt_s"] == 0.001


def test_the_callback_sees_the_simulation_and_every_sample(lbr4p):
    seen = []
    sim = MujocoSimulation(lbr4p, physics_dt_s=0.002)
    res = run_mujoco(
        LocalController(lbr4p, Circle(0.3), 0.05),
        LBR4P_Q0,
        simulation=sim,
        on_sample=lambda k, simulation, result: seen.append((k, simulation, result.sigma_next)),
    )
    assert [k for k, _, _ in seen] == list(range(len(res.log)))
    assert all(simulation is sim for _, simulation, _ in seen)
    np.testing.assert_array_equal([s for _, _, s in seen][:-1], res.log.sigma[1:])
    assert res.log.meta["physics_dt_s"] == 0.002


def test_simulation_options_reach_the_simulation(lbr4p):
    sims = []
    res = run_mujoco(LocalController(lbr4p, Circle(0.3), 0.05), LBR4P_Q0, max_time_s=0.1,
                     payload_kg=2.0, motor="torque",
                     on_sample=lambda _k, sim, _result: sims.append(sim))  # fmt: skip
    assert len(res.log) == len(sims) == 2 and not res.metrics.completed
    assert sims[0].motor == "torque" and sims[0].payload_kg == 2.0
    with pytest.raises(TypeError):
        run_mujoco(LocalController(lbr4p, Circle(0.3), 0.05), LBR4P_Q0, no_such_option=1)
