"""dqcontrol/sim/driver.py: the driver protocols, the kinematic and simulation drivers, the
position wrapper and the joint map by name (against exact integration and hand-built arms)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from dqcontrol.errors import ConfigurationError, ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim.driver import (
    JointDriver,
    JointMismatchError,
    KinematicDriver,
    MujocoDriver,
    PositionInterface,
    SimulatedDriver,
    SimulationDriver,
    VelocityFromPosition,
    joint_map,
)
from dqcontrol.sim.mujoco_sim import Measurement, MujocoSimulation

NAMES = tuple(f"j{i}" for i in range(1, 8))


class IdealPositionArm:
    """A position-only interface that reaches every target within one period."""

    def __init__(self, names=NAMES, q0=None) -> None:
        self.joint_names = tuple(names)
        self.q = np.zeros(len(names)) if q0 is None else np.array(q0, dtype=float)
        self.t = 0.0
        self.targets: list[np.ndarray] = []

    def read(self) -> Measurement:
        nan = np.full(len(self.q), np.nan)
        return Measurement(self.t, self.q.copy(), np.zeros(len(self.q)), nan, nan)

    def write_position(self, q_target: np.ndarray) -> None:
        self.targets.append(np.array(q_target))
        self.q = np.array(q_target, dtype=float)
        self.t += 0.01


def test_the_drivers_satisfy_the_protocols(lbr4p):
    kin = KinematicDriver(lbr4p, 0.05)
    assert isinstance(kin, JointDriver) and isinstance(kin, SimulatedDriver)
    assert isinstance(MujocoDriver(lbr4p, 0.05), SimulatedDriver)
    assert isinstance(VelocityFromPosition(IdealPositionArm(), 0.01), JointDriver)
    assert isinstance(IdealPositionArm(), PositionInterface)
    assert not isinstance(IdealPositionArm(), JointDriver)  # no write/hold
    assert kin.joint_names == tuple(lbr4p.joint_names)


def test_kinematic_driver_integrates_exactly_and_keeps_time(lbr4p):
    drv = KinematicDriver(lbr4p, 0.05)
    m0 = drv.reset(LBR4P_Q0)
    assert m0.t_s == 0.0 and np.array_equal(m0.q, LBR4P_Q0) and not m0.qd.any()
    u = np.linspace(-0.5, 0.5, 7)
    drv.write(u)
    m = drv.read()
    assert np.array_equal(m.q, LBR4P_Q0 + 0.05 * u) and np.array_equal(m.qd, u)
    assert m.t_s == 0.05 and np.isnan(m.torque).all()
    drv.hold()
    assert np.array_equal(drv.read().q, m.q) and not drv.read().qd.any()
    assert drv.read().t_s == 2 * 0.05


def test_simulation_driver_holds_the_command_one_period(lbr4p):
    sim = MujocoSimulation(lbr4p)
    drv = SimulationDriver(sim, 0.01)
    drv.reset(LBR4P_Q0)
    drv.write(np.full(7, 0.2))
    m = drv.read()
    assert m.t_s == pytest.approx(0.01) and m.qd == pytest.approx(np.full(7, 0.2), abs=0.05)
    assert drv.meta == {"simulator": "mujoco", "physics_dt_s": 0.001}
    drv.hold()
    assert drv.read().t_s == pytest.approx(0.02)
    with pytest.raises(ParameterError, match="not a whole number of physics steps"):
        SimulationDriver(sim, 0.0015)
    with pytest.raises(ParameterError, match="has no 'reset'"):
        SimulationDriver(object(), 0.01)


def test_velocity_from_position_integrates_the_command():
    arm = IdealPositionArm(q0=np.arange(7) * 0.1)
    drv = VelocityFromPosition(arm, 0.01)
    start = drv.read().q
    drv.write(np.ones(7))
    drv.write(2.0 * np.ones(7))
    np.testing.assert_allclose(arm.targets[-1], start + 0.03, atol=1e-15)
    np.testing.assert_allclose(drv.read().q, start + 0.03, atol=1e-15)
    drv.hold()
    np.testing.assert_array_equal(arm.targets[-1], arm.targets[-2])
    with pytest.raises(ParameterError, match="has no 'joint_names'"):
        VelocityFromPosition(object(), 0.01)


def test_velocity_from_position_starts_at_the_first_measurement_when_written_first():
    arm = IdealPositionArm(q0=np.full(7, 0.3))
    drv = VelocityFromPosition(arm, 0.5)
    drv.write(np.ones(7))
    np.testing.assert_allclose(arm.targets[0], np.full(7, 0.8))


def test_joint_map_orders_by_name():
    assert joint_map(NAMES, NAMES) is None
    shuffled = NAMES[::-1]
    perm = joint_map(shuffled, NAMES)
    assert [shuffled[i] for i in perm] == list(NAMES)


@pytest.mark.parametrize(
    ("driver_names", "fragments"),
    [
        (NAMES[:6] + ("wrist",), ["joint-name mismatch", "['wrist']", "['j7']"]),
        (NAMES[:6] + ("j1",), ["more than once", "['j1']"]),
        (NAMES[:5], ["has 5 joints, the model 7", "missing ['j6', 'j7']"]),
        (NAMES + ("finger",), ["joint-name mismatch", "['finger']"]),
    ],
    ids=["renamed", "duplicate", "fewer", "more"],
)
def test_joint_map_refuses_a_mismatch_and_names_the_joints(driver_names, fragments):
    with pytest.raises(JointMismatchError) as info:
        joint_map(driver_names, NAMES)
    for fragment in fragments:
        assert fragment in str(info.value)
    assert isinstance(info.value, ConfigurationError)


def test_the_drivers_page_example_runs():
    page = Path(__file__).resolve().parents[2] / "docs" / "drivers.md"
    blocks = re.findall(r"^```python\n(.*?)^```", page.read_text("utf-8"), re.M | re.S)
    assert blocks
    exec(compile("\n".join(blocks), str(page), "exec"), {"__name__": "drivers_md"})
