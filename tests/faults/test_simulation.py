"""``dqcontrol.faults.simulation.fault_driver``: a case's arm wrapped in its faults, in the
order and with the settings of the fault, and the errors for what no simulator can do."""

from __future__ import annotations

import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.faults import Fault, fault_by_name, fault_driver
from dqcontrol.sim import (
    FaultyDriver,
    KinematicDriver,
    MujocoDriver,
    NotASimulatorError,
    PayloadDriver,
    TorqueLimitDriver,
)


def test_a_case_driver_wraps_the_arm_in_its_faults(lbr4p):
    fault = fault_by_name("payload_3kg_torque_half")
    drv = fault_driver(fault, "mujoco", lbr4p, 0.05, seed=4)
    assert isinstance(drv, FaultyDriver) and drv.faults.seed == 4
    assert isinstance(drv.inner, TorqueLimitDriver)
    assert isinstance(drv.inner.inner, PayloadDriver)
    assert isinstance(drv.inner.inner.inner, MujocoDriver)
    assert drv.simulation.payload_kg == 3.0 and drv.simulation.effort_scale == 0.5
    assert drv.meta["payload_kg"] == 3.0 and drv.meta["effort_scale"] == 0.5
    plain = fault_driver(fault_by_name("noise"), "kinematic", lbr4p, 0.05)
    assert isinstance(plain.inner, KinematicDriver) and plain.faults.q_noise_rad == 2e-3
    with pytest.raises(NotASimulatorError, match="KinematicDriver cannot"):
        fault_driver(fault, "kinematic", lbr4p, 0.05)
    with pytest.raises(ParameterError, match="simulator must be one of"):
        fault_driver(fault, "gazebo", lbr4p, 0.05)


def test_measurement_faults_are_the_outer_wrapper_s_settings(lbr4p):
    fault = Fault("x", "measurement", "", q_noise_rad=1e-3, qd_noise_rad_s=0.01, delay_periods=3)
    drv = fault_driver(fault, "kinematic", lbr4p, 0.02, seed=9)
    assert isinstance(drv, FaultyDriver) and type(drv.inner) is KinematicDriver
    faults = drv.faults
    assert (faults.q_noise_rad, faults.qd_noise_rad_s) == (1e-3, 0.01)
    assert (faults.delay_periods, faults.seed) == (3, 9)


def test_a_torque_fault_alone_wraps_only_the_torque_limits(lbr4p):
    drv = fault_driver(Fault("t", "model", "", effort_scale=0.5), "mujoco", lbr4p, 0.05)
    assert isinstance(drv.inner, TorqueLimitDriver) and isinstance(drv.inner.inner, MujocoDriver)
    assert (drv.faults.q_noise_rad, drv.faults.delay_periods) == (0.0, 0)
