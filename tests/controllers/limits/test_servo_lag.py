"""The servo's lag in the position bounds: the identification of the lag and the bounds it
moves (against hand computations), and the Unitree Z1 case where the local and the
proportional controllers' joint 5 passed its URDF limit behind a lagging servo."""

from __future__ import annotations

import numpy as np
import pytest

T = 0.01
MARGIN = 5e-3


def _margin(n: int = 2):
    """A lag margin on ±1 rad and its bounds (imported here: the Z1 test below runs on a
    tree without the module too)."""
    from dqcontrol.controllers.limits.servo_lag import ServoLagMargin

    q_min, q_max = -np.ones(n), np.ones(n)
    values = np.array([q_min + MARGIN, q_max - MARGIN, 3.0 * np.ones(n)])
    return ServoLagMargin(q_min, q_max, MARGIN, T, 10.0), values


def _ramp(lag, values, steps: int, rate: float, behind: float, v0=0.0):
    """Commands ramping at ``rate`` [rad/s²] with the joints ``behind`` [rad/s] behind."""
    cmd = np.full(2, v0)
    for _ in range(steps):
        nxt = cmd + rate * T
        lag.update(cmd - np.sign(rate) * behind, cmd, values)
        cmd = nxt
    return cmd


def test_ideal_tracking_moves_nothing():
    lag, values = _margin()
    before = values.copy()
    _ramp(lag, values, 30, 10.0, 0.0)
    assert np.all(lag.tau_s == 0.0) and np.array_equal(values, before)


def test_a_persistent_lag_is_identified_and_moves_the_bound_ahead():
    lag, values = _margin()
    cmd = _ramp(lag, values, 30, 10.0, 0.19)  # 0.19 rad/s behind at 10 rad/s²: 19 ms
    assert lag.tau_s == pytest.approx(0.019, rel=1e-9)
    qd = cmd - 10.0 * T - 0.19  # measured at the last update
    travel = 0.019 * qd  # beyond the margin: the bound ahead moves, the one behind not
    assert np.all(travel > MARGIN)
    assert values[1] == pytest.approx(1.0 - travel) and values[0] == pytest.approx(-1.0 + MARGIN)
    lag.update(np.zeros(2), np.zeros(2), values)  # at rest: the margin's bounds, exactly
    assert np.array_equal(values[:2], [[-1.0 + MARGIN] * 2, [1.0 - MARGIN] * 2])


def test_one_noisy_sample_is_not_a_lag():
    from dqcontrol.controllers.limits.servo_lag import SAMPLES

    lag, values = _margin()
    before = values.copy()
    cmd = np.zeros(2)
    for k in range(4 * SAMPLES):
        nxt = cmd + 0.1  # 10 rad/s² at T = 10 ms
        behind = 0.5 if k == 5 else 0.0
        lag.update(cmd - behind, cmd, values)
        cmd = nxt
    assert np.all(lag.tau_s == 0.0) and np.array_equal(values, before)


def test_restore_gives_the_margin_bounds_back():
    lag, values = _margin()
    before = values.copy()
    _ramp(lag, values, 30, 10.0, 0.19)
    assert not np.array_equal(values, before)
    assert lag.restore(values) is True
    assert np.array_equal(values, before) and np.all(lag.tau_s == 0.0)
    assert lag.restore(values) is False  # nothing had moved


def test_an_update_says_whether_it_wrote_the_bounds():
    lag, values = _margin()
    cmd = np.zeros(2)
    said = []
    for k in range(40):
        behind = 0.19 if k < 30 else 0.0
        said.append(lag.update(cmd - behind, cmd, values))
        cmd = cmd + (10.0 * T if k < 30 else 0.0)
    assert lag.update(None, cmd, values) is False  # nothing measured: nothing written
    first = said.index(True)  # the bound moves once the lag's travel exceeds the margin
    assert not any(said[:first]) and all(said[first:30])
    lag.update(np.zeros(2), np.zeros(2), values)  # at rest: back to the margin's
    assert lag.update(np.zeros(2), np.zeros(2), values) is False  # already there


@pytest.mark.parametrize("name", ["local", "proportional"])
def test_the_z1_stays_inside_its_urdf_limits_in_mujoco(name):
    """Unitree Z1, MuJoCo, T = 10 ms, the campaign's unreachable circle: joint 5 reaches its
    lower limit at 3.1 rad/s and its servo trails the braking by 0.19 rad/s."""
    from dqcontrol.cli.robot_options import RobotRequest, load_robot
    from dqcontrol.faults.scenarios import TRAJECTORIES
    from dqcontrol.registry import controller_spec
    from dqcontrol.sim import FaultyDriver, MujocoDriver, run_loop

    robot, _, _ = load_robot(RobotRequest("erd:z1", "gripperMover", (("jointGripper", 0.0),)))
    trajectory = TRAJECTORIES["circle"].build(2.0, unreachable=True)
    controller = controller_spec(name).build(robot, trajectory, T)
    driver = FaultyDriver(MujocoDriver(robot, T))
    q0 = np.array([0.0, 1.0, -1.0, 0.0, 0.0, 0.0])
    run_loop(controller, driver, q0=q0, max_time_s=1.2, brake=False)
    lim = robot.limits
    excess = np.maximum(driver.true_q - lim.q_max, lim.q_min - driver.true_q)
    assert excess.max() <= 0.0, f"{1e3 * excess.max():.2f} mrad beyond a limit"


def _reference_update(state: dict, qd_meas, qd_cmd, values, a_min, tau_cap, samples_n) -> None:
    """The lag margin's step written again with numpy arrays (a shifted window of samples,
    masked divisions): the oracle of the compiled pass."""
    before, state["before"] = state["before"], qd_cmd.copy()
    if qd_meas is None:
        return
    sample = np.full(qd_cmd.shape, -np.inf)
    if before is not None:
        rate = (qd_cmd - before) / T
        excited = np.abs(rate) >= a_min
        sample[excited] = ((qd_cmd - qd_meas) * np.sign(rate))[excited] / np.abs(rate[excited])
    state["window"] = np.vstack([sample, state["window"][: samples_n - 1]])
    state["tau"] = np.minimum(np.maximum(state["tau"], state["window"].min(axis=0)), tau_cap)
    travel = state["tau"] * np.abs(qd_meas)
    if not (travel > MARGIN).any():
        if state["kept"] is not None:
            values[:2] = state["kept"]
            state["kept"] = None
        return
    if state["kept"] is None:
        state["kept"] = values[:2].copy()
    values[0] = np.maximum(state["kept"][0], -1.0 + np.where(qd_meas < 0.0, travel, 0.0))
    values[1] = np.minimum(state["kept"][1], 1.0 - np.where(qd_meas > 0.0, travel, 0.0))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_compiled_step_equals_the_numpy_reference_bit_for_bit(seed):
    from dqcontrol.controllers.limits.servo_lag import SAMPLES, TAU_CAP_S

    rng = np.random.default_rng(seed)
    lag, values = _margin(3)
    ref_values = values.copy()
    state = {"before": None, "window": np.full((SAMPLES, 3), -np.inf), "tau": np.zeros(3),
             "kept": None}  # fmt: skip
    cmd = np.zeros(3)
    for k in range(400):  # bursts of strong acceleration with a lagging joint, and rests
        accel = rng.choice([0.0, 8.0, -8.0, 20.0], size=3) * (k % 50 < 30)
        cmd = cmd + accel * T
        meas = None if k % 37 == 5 else cmd - rng.uniform(0.0, 0.3, 3) * np.sign(accel + 1e-9)
        lag.update(meas, cmd, values)
        _reference_update(state, meas, cmd, ref_values, lag.a_min, TAU_CAP_S, SAMPLES)
        assert np.array_equal(lag.tau_s, state["tau"]), k
        assert np.array_equal(values, ref_values), k
    assert np.any(lag.tau_s > 0.0) and not np.array_equal(values[:2], _margin(3)[1][:2])
