"""dqcontrol/sim/measurement_faults.py: the delay line and seeded noise against a hand-built
FIFO and ``default_rng`` draws, the faulty driver around the kinematic driver (delay, noise
statistics, bad parameters) and around a MuJoCo arm in the loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim import MujocoDriver, run_loop
from dqcontrol.sim.driver import KinematicDriver
from dqcontrol.sim.measurement_faults import FaultyDriver, MeasurementFaults, true_copy
from dqcontrol.sim.mujoco_sim import Measurement
from dqcontrol.trajectories import Circle


def _measurement(t_s: float, value: float, n: int = 3) -> Measurement:
    """A measurement whose every entry is ``value`` (torques ``-value``)."""
    full = np.full(n, value)
    return Measurement(t_s, full.copy(), 2.0 * full, -full, -full)


@pytest.mark.parametrize("delay", [0, 2])
def test_faulty_driver_observes_the_delayed_state_plus_seeded_noise(lbr4p, delay):
    """Observation k is true state ``max(0, k - d)`` plus the k-th draws of
    ``default_rng(seed)``: q's noise, then qd's."""
    opts = {"q_noise_rad": 1e-3, "qd_noise_rad_s": 0.01, "delay_periods": delay, "seed": 3}
    drv = FaultyDriver(KinematicDriver(lbr4p, 0.05), **opts)
    seen = [drv.reset(LBR4P_Q0)]
    for k in range(8):
        drv.write(np.full(7, 0.1 * (k + 1)))
        seen.append(drv.read())
    rng = np.random.default_rng(3)
    for k, m in enumerate(seen):
        old = drv.true_measurements[max(0, k - delay)]
        np.testing.assert_array_equal(m.q, old.q + rng.normal(0.0, 1e-3, 7))
        np.testing.assert_array_equal(m.qd, old.qd + rng.normal(0.0, 0.01, 7))
        assert m.t_s == drv.true_measurements[k].t_s  # stamped with the present time
    np.testing.assert_array_equal(drv.true_qd[-1], np.full(7, 0.1 * 8))
    assert drv.meta["delay_periods"] == delay


def test_faulty_driver_rejects_what_is_not_a_driver(lbr4p):
    with pytest.raises(ParameterError, match="must be a JointDriver"):
        FaultyDriver(object())
    with pytest.raises(ParameterError, match="delay_periods must be an integer"):
        FaultyDriver(KinematicDriver(lbr4p, 0.05), delay_periods=-1)


def test_the_delay_line_returns_the_state_of_d_periods_ago_with_the_present_stamp():
    faults = MeasurementFaults(delay_periods=2)
    first = _measurement(0.0, 0.0)
    seen = [faults.restart(first)]
    truth = [first]
    for k in range(1, 6):
        now = _measurement(0.1 * k, float(k))
        truth.append(now)
        seen.append(faults.push(now))
    for k, m in enumerate(seen):
        old = truth[max(0, k - 2)]
        np.testing.assert_array_equal(m.q, old.q)  # no noise asked: exactly the old state
        np.testing.assert_array_equal(m.qd, old.qd)
        assert m.t_s == truth[k].t_s
        np.testing.assert_array_equal(m.torque, truth[k].torque)
        np.testing.assert_array_equal(m.torque_peak, truth[k].torque_peak)


def test_a_restart_replays_the_same_noise():
    faults = MeasurementFaults(q_noise_rad=0.1, qd_noise_rad_s=0.2, seed=11)
    first, later = _measurement(0.0, 1.0), _measurement(0.1, 2.0)
    runs = []
    for _ in range(2):
        runs.append([faults.restart(first), faults.push(later)])
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.qd, b.qd)
    rng = np.random.default_rng(11)
    np.testing.assert_array_equal(runs[0][0].q, first.q + rng.normal(0.0, 0.1, 3))
    np.testing.assert_array_equal(runs[0][0].qd, first.qd + rng.normal(0.0, 0.2, 3))


def test_a_true_copy_does_not_share_the_arrays():
    m = _measurement(0.5, 1.0)
    copy = true_copy(m)
    m.q[:] = 9.0
    m.torque[:] = 9.0
    assert copy.t_s == 0.5 and not (copy.q == 9.0).any() and not (copy.torque == 9.0).any()


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"q_noise_rad": -1e-3}, "q_noise_rad must be finite and ≥ 0 [rad]"),
        ({"qd_noise_rad_s": float("nan")}, "qd_noise_rad_s must be finite and ≥ 0 [rad/s]"),
        ({"q_noise_rad": "much"}, "q_noise_rad must be a number [rad]"),
        ({"delay_periods": 1.5}, "delay_periods must be an integer ≥ 0"),
        ({"delay_periods": True}, "delay_periods must be an integer ≥ 0"),
        ({"seed": 2.0}, "seed must be an integer"),
    ],
)
def test_bad_faults_are_refused_with_the_parameter_named(kwargs, fragment):
    with pytest.raises(ParameterError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
        MeasurementFaults(**kwargs)


@pytest.mark.parametrize("delay", [0, 1, 2, 3])
def test_delay_returns_the_measurement_of_d_periods_ago(lbr4p, delay):
    drv = FaultyDriver(KinematicDriver(lbr4p, 0.05), delay_periods=delay)
    seen = [drv.reset(LBR4P_Q0).q]
    for k in range(6):
        drv.write(np.full(7, 0.1 * (k + 1)))
        seen.append(drv.read().q)
    true = drv.true_q
    for k, q in enumerate(seen):
        np.testing.assert_array_equal(q, true[max(0, k - delay)])
    assert drv.read().t_s == pytest.approx(6 * 0.05)  # the clock itself is not delayed


def test_noise_is_seeded_gaussian_and_restarts_at_reset(lbr4p):
    drv = FaultyDriver(KinematicDriver(lbr4p, 0.05), q_noise_rad=2e-3, qd_noise_rad_s=0.02, seed=7)

    def run() -> list[np.ndarray]:
        seen = [drv.reset(LBR4P_Q0).q]
        for _ in range(400):
            drv.hold()
            seen.append(drv.read().q)
        return seen

    first, again = run(), run()
    np.testing.assert_array_equal(first, again)
    err = np.array(first) - LBR4P_Q0
    assert abs(err.mean()) < 2e-4 and err.std() == pytest.approx(2e-3, rel=0.05)
    np.testing.assert_array_equal(drv.true_q[-1], LBR4P_Q0)  # the arm itself did not move


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"q_noise_rad": -1e-3}, "q_noise_rad must be finite and ≥ 0 [rad]"),
        ({"qd_noise_rad_s": math.nan}, "qd_noise_rad_s must be finite and ≥ 0 [rad/s]"),
        ({"delay_periods": -1}, "delay_periods must be an integer ≥ 0"),
        ({"delay_periods": 1.5}, "delay_periods must be an integer ≥ 0"),
        ({"seed": "x"}, "seed must be an integer"),
    ],
)
def test_bad_fault_parameters(lbr4p, kwargs, fragment):
    with pytest.raises(ParameterError) as info:
        FaultyDriver(KinematicDriver(lbr4p, 0.05), **kwargs)
    assert fragment in str(info.value)


def test_the_loop_sees_the_faulty_measurements_of_a_mujoco_arm(lbr4p):
    drv = FaultyDriver(MujocoDriver(lbr4p, 0.05), q_noise_rad=1e-3, delay_periods=1)
    ctrl = LocalController(lbr4p, Circle(1.0), 0.05)
    res = run_loop(ctrl, drv, q0=LBR4P_Q0, max_time_s=0.5, brake=False)
    assert len(res.log) == 10 and drv.true_q.shape == (11, 7)
    # the log holds what the controller measured: one period late and noisy
    assert np.abs(res.log.q[1:] - drv.true_q[:-2]).max() < 6e-3  # [k] is true [k - 1]
    assert np.abs(res.log.q[1:] - drv.true_q[:-2]).max() > 0.0
