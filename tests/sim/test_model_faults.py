"""Model faults as driver wrappers: an unknown payload and lower torque limits around a
MuJoCo driver, what they change, and what they refuse."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.errors import ConfigurationError, ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim import (
    DynamicSimulation,
    FaultyDriver,
    KinematicDriver,
    MujocoDriver,
    MujocoSimulation,
    NotASimulatorError,
    PayloadDriver,
    TorqueLimitDriver,
    run_loop,
)
from dqcontrol.sim.mjcf_builder import PAYLOAD_BODY
from dqcontrol.trajectories import Circle

OFFSET = np.array([0.0, 0.0, 0.05])


def _run(driver, lbr4p):
    return run_loop(LocalController(lbr4p, Circle(1.0), 0.05), driver, q0=LBR4P_Q0, brake=False)


@pytest.mark.parametrize("motor", ["velocity", "torque"])
def test_a_payload_wrapper_is_the_simulation_built_with_the_payload(lbr4p, motor):
    wrapped = _run(PayloadDriver(MujocoDriver(lbr4p, 0.05, motor=motor), 3.0, OFFSET), lbr4p)
    built = MujocoDriver(lbr4p, 0.05, motor=motor, payload_kg=3.0, payload_offset_m=OFFSET)
    built = _run(built, lbr4p)
    for name in ("q", "qd_measured", "qd_command", "torque", "torque_peak"):
        np.testing.assert_array_equal(getattr(wrapped.log, name), getattr(built.log, name))
    assert wrapped.log.meta["payload_kg"] == 3.0
    assert wrapped.log.meta["payload_offset_m"] == [0.0, 0.0, 0.05]


def test_the_payload_weighs_on_the_joints_by_its_jacobian(lbr4p):
    """Held at rest, the drives push ``J_p^T m g`` more: the payload's weight through the
    Jacobian of its centre."""
    held = {}
    for mass in (0.0, 2.0):
        drv = MujocoDriver(lbr4p, 0.05)
        if mass:
            drv = PayloadDriver(drv, mass, OFFSET)
        drv.reset(LBR4P_Q0)
        for _ in range(40):  # 2 s: the integral action settles
            drv.hold()
        held[mass] = drv.read().torque
    sim = drv.simulation
    model, data = sim.model, sim.data
    jac = np.zeros((3, model.nv))
    mujoco.mj_jac(model, data, jac, None, sim.payload_position(), model.body(PAYLOAD_BODY).id)
    dof = list(sim.joint_dof_adr.values())
    expected = jac[:, dof].T @ np.array([0.0, 0.0, 2.0 * 9.81])
    np.testing.assert_allclose(held[2.0] - held[0.0], expected, atol=0.05)
    assert np.abs(expected).max() > 1.0  # a felt difference, not noise


def test_torque_limits_are_scaled_in_the_drives_and_the_model(lbr4p):
    inner = MujocoDriver(lbr4p, 0.05)
    nominal = inner.simulation.torque_limit.copy()
    drv = TorqueLimitDriver(inner, 0.5)
    sim = drv.simulation
    np.testing.assert_array_equal(sim.torque_limit, 0.5 * nominal)
    act = [sim.model.actuator(j + "_servo").id for j in lbr4p.joint_names]
    np.testing.assert_array_equal(sim.model.actuator_ctrlrange[act, 1], 0.5 * nominal)
    np.testing.assert_array_equal(sim.model.actuator_forcerange[act, 1], 0.5 * nominal)
    res = _run(drv, lbr4p)
    peak = res.log.torque_peak.max(axis=0)
    assert np.all(peak <= 0.5 * nominal + 1e-9) and np.any(peak >= 0.5 * nominal - 1e-9)
    assert res.log.meta["effort_scale"] == 0.5
    np.testing.assert_array_equal(
        TorqueLimitDriver(drv, 0.5).simulation.torque_limit, 0.25 * nominal
    )  # wrappers compose


def test_a_model_change_keeps_the_state(lbr4p):
    drv = MujocoDriver(lbr4p, 0.05)
    drv.reset(LBR4P_Q0)
    for _ in range(3):
        drv.write(np.full(7, 0.2))
    before = drv.read()
    wrapped = TorqueLimitDriver(PayloadDriver(drv, 1.0), 0.8)
    data = wrapped.simulation.data
    qpos = data.qpos[list(wrapped.simulation.joint_qpos_adr.values())]
    np.testing.assert_array_equal(qpos, before.q)
    assert data.time == before.t_s == pytest.approx(0.15)
    wrapped.write(np.full(7, 0.2))
    assert wrapped.read().t_s == pytest.approx(0.2)


def test_the_wrappers_stack_with_the_measurement_faults(lbr4p):
    faulty = FaultyDriver(MujocoDriver(lbr4p, 0.05), q_noise_rad=1e-3, seed=2)
    drv = PayloadDriver(faulty, 1.0)  # through FaultyDriver's simulation
    assert drv.simulation is faulty.inner.simulation and drv.simulation.payload_kg == 1.0
    outer = FaultyDriver(drv, delay_periods=1)
    assert outer.meta["payload_kg"] == 1.0 and outer.meta["delay_periods"] == 1
    assert isinstance(MujocoSimulation(lbr4p), DynamicSimulation)


def test_a_driver_without_a_dynamic_simulation_is_refused_with_what_it_lacks(lbr4p):
    with pytest.raises(NotASimulatorError) as info:
        PayloadDriver(KinematicDriver(lbr4p, 0.05), 3.0)
    msg = str(info.value)
    assert "PayloadDriver needs a driver over a dynamic simulation" in msg
    assert "KinematicDriver cannot: it has no simulation" in msg
    assert isinstance(info.value, ConfigurationError)

    class Stepped(KinematicDriver):
        simulation = object()

    with pytest.raises(NotASimulatorError, match=r"a object, has no \['payload_kg'"):
        TorqueLimitDriver(Stepped(lbr4p, 0.05))
    with pytest.raises(ParameterError, match="must be a JointDriver"):
        PayloadDriver(object(), 1.0)


@pytest.mark.parametrize(
    ("make", "error", "fragment"),
    [
        (lambda d: PayloadDriver(d, 0.0), ParameterError, "mass_kg must be a number > 0"),
        (lambda d: PayloadDriver(d, True), ParameterError, "mass_kg must be a number > 0"),
        (lambda d: PayloadDriver(d, 1.0, [0, 0]), ParameterError, "payload_offset_m must be 3"),
        (lambda d: TorqueLimitDriver(d, 0.0), ParameterError, "scale must be > 0"),
        (lambda d: TorqueLimitDriver(d, np.inf), ParameterError, "scale must be a finite"),
        (
            lambda d: PayloadDriver(PayloadDriver(d, 1.0), 2.0),
            ConfigurationError,
            "already carries a payload of 1.0 kg",
        ),
    ],
)
def test_bad_model_faults(lbr4p, make, error, fragment):
    with pytest.raises(error, match=fragment):
        make(MujocoDriver(lbr4p, 0.05))
