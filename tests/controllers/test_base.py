"""The controller interface (dqcontrol/controllers/base.py): the parameter checks and the
limit settings against hand-computed values and their error messages, the fast constructor
of the frozen results, and the base class's reset, step checks and measurement-delay
compensation (through a minimal controller that records what its step receives)."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.controllers.base import (
    Controller,
    StepDiagnostics,
    StepResult,
    acceleration_setting,
    check_position_margin,
    check_positive,
    fast_constructor,
    joint_limit_settings,
    per_joint,
    robot_acceleration_limit,
)
from dqcontrol.errors import ConfigurationError, ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.trajectories import Circle

T = 0.05


# --------------------------------------------------------------------------- parameter checks
def test_check_positive_returns_a_float_or_names_the_parameter():
    assert check_positive("k", 3, "1/s") == 3.0 and type(check_positive("k", 3, "1/s")) is float
    assert check_positive("m", 0.0, "rad", allow_zero=True) == 0.0
    with pytest.raises(ParameterError, match=r"k must be finite and > 0 \[1/s\], got 0"):
        check_positive("k", 0, "1/s")
    with pytest.raises(ParameterError, match="≥ 0"):
        check_positive("m", -1e-9, "rad", allow_zero=True)
    with pytest.raises(ParameterError, match="> 0"):
        check_positive("k", float("inf"), "1/s")
    with pytest.raises(ParameterError, match=r"k must be a number \[1/s\], got 'fast'"):
        check_positive("k", "fast", "1/s")
    with pytest.raises(ParameterError, match="k must be a number"):
        check_positive("k", None, "1/s")


def test_per_joint_broadcasts_a_scalar_and_copies_a_vector():
    np.testing.assert_array_equal(per_joint("v", 2.0, 3, "rad/s"), [2.0, 2.0, 2.0])
    given = np.array([1.0, 2.0, 3.0])
    out = per_joint("v", given, 3, "rad/s")
    np.testing.assert_array_equal(out, given)
    out[0] = 9.0
    assert given[0] == 1.0  # a copy
    np.testing.assert_array_equal(per_joint("v", [0, 1, 2], 3, "rad", allow_zero=True), [0, 1, 2])


@pytest.mark.parametrize(
    ("value", "fragment"),
    [
        ([1.0, 2.0], r"v must be a scalar or have shape \(3,\) \(one per joint\) \[rad/s\]"),
        (np.ones((3, 1)), r"got shape \(3, 1\)"),
        ("fast", "v must be a number or 3 numbers"),
        ([1.0, np.nan, 1.0], "v must be finite and > 0"),
        ([1.0, 0.0, 1.0], "v must be finite and > 0"),
    ],
)
def test_per_joint_names_what_it_accepts(value, fragment):
    with pytest.raises(ParameterError, match=fragment):
        per_joint("v", value, 3, "rad/s")


def test_acceleration_setting_is_a_constant_or_the_dynamics_bound():
    a_const, floor, cap = acceleration_setting(5.0, 2, 1.0, 50.0)
    np.testing.assert_array_equal(a_const, [5.0, 5.0])
    assert (floor, cap) == (1.0, 50.0)
    assert acceleration_setting("dynamics", 2, 1, 50) == (None, 1.0, 50.0)
    with pytest.raises(ParameterError, match="acceleration_limit must be a positive number"):
        acceleration_setting("fast", 2, 1.0, 50.0)
    with pytest.raises(ParameterError, match=r"acceleration_floor \(60.0\) must be ≤"):
        acceleration_setting("dynamics", 2, 60.0, 50.0)
    with pytest.raises(ParameterError, match="acceleration_cap"):
        acceleration_setting("dynamics", 2, 1.0, -1.0)
    with pytest.raises(ParameterError, match="acceleration_limit"):
        acceleration_setting(-3.0, 2, 1.0, 50.0)


def test_robot_acceleration_limit_prefers_the_given_then_the_profile():
    def robot(qdd_max):
        return SimpleNamespace(limits=SimpleNamespace(qdd_max=np.array(qdd_max)))

    partial = robot([15.0, np.inf, 7.5])
    assert robot_acceleration_limit(partial, 3.0, 10.0) == 3.0
    np.testing.assert_array_equal(robot_acceleration_limit(partial, None, 10.0), [15, 10, 7.5])
    np.testing.assert_array_equal(
        robot_acceleration_limit(partial, None, np.array([1.0, 2.0, 3.0])), [15.0, 2.0, 7.5]
    )
    assert robot_acceleration_limit(partial, None, "dynamics") == "dynamics"
    assert robot_acceleration_limit(robot([np.inf] * 3), None, 10.0) == 10.0


def test_the_position_margin_stays_below_half_the_smallest_range():
    q_min, q_max = np.array([-1.0, -0.2]), np.array([1.0, 0.2])
    assert check_position_margin(0.0, q_min, q_max) == 0.0
    assert check_position_margin(0.19, q_min, q_max) == 0.19
    with pytest.raises(ParameterError, match=r"half the smallest joint range \(0.2 rad\)"):
        check_position_margin(0.2, q_min, q_max)
    with pytest.raises(ParameterError, match="position_margin_rad"):
        check_position_margin(-0.01, q_min, q_max)


def test_joint_limit_settings_shrink_the_urdf_box(lbr4p):
    lim = lbr4p.limits
    margin, q_min, q_max, qd_max = joint_limit_settings(lbr4p, None, 0.01)
    assert margin == 0.01
    np.testing.assert_array_equal(q_min, lim.q_min + 0.01)
    np.testing.assert_array_equal(q_max, lim.q_max - 0.01)
    np.testing.assert_array_equal(qd_max, lim.qd_max)
    assert qd_max is not lim.qd_max  # the robot's array is not handed out
    _, _, _, given = joint_limit_settings(lbr4p, 2.0, 0.0)
    np.testing.assert_array_equal(given, np.full(7, 2.0))
    with pytest.raises(ParameterError, match="velocity_limits"):
        joint_limit_settings(lbr4p, [1.0, 2.0], 0.0)


# --------------------------------------------------------------------------- results
def test_fast_constructors_build_the_same_objects():
    diag_kw = {
        "status": "closed_form",
        "step_time_s": 1e-5,
        "saturated": True,
        "conflict_joints": (2, 5),
        "message": "m",
    }
    make_diag = fast_constructor(StepDiagnostics, status="closed_form")
    fast, slow = make_diag(**diag_kw), StepDiagnostics(**diag_kw)
    assert type(fast) is StepDiagnostics and fast == slow and repr(fast) == repr(slow)
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.saturated = False
    x = np.arange(8.0)
    res_kw = {
        "qd_command": np.ones(7),
        "s": 1.0,
        "sigma": 0.1,
        "sigma_next": 0.2,
        "pose": x,
        "target": x,
        "diagnostics": slow,
    }
    make_res = fast_constructor(StepResult, **res_kw)
    fast, slow = make_res(**res_kw), StepResult(**res_kw)
    assert type(fast) is StepResult
    for f in dataclasses.fields(StepResult):
        assert getattr(fast, f.name) is getattr(slow, f.name)
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.s = 0.5

    @dataclasses.dataclass(frozen=True, slots=True)
    class Slotted:
        a: int = 0

    @dataclasses.dataclass(frozen=True)
    class Checked:
        a: int = 0

        def __post_init__(self) -> None:
            pass

    assert fast_constructor(Slotted) is Slotted
    assert fast_constructor(Checked) is Checked


# --------------------------------------------------------------------------- the base class
class Recorder(Controller):
    """Commands a constant velocity at ``s = 1``; records the ``q`` each step received."""

    def __init__(self, robot, trajectory, period_s, delay=0, command=None) -> None:
        super().__init__(robot, trajectory, period_s, delay)
        self.command = np.full(self.n, 0.1) if command is None else command
        self.seen: list[np.ndarray] = []

    def _step(self, q, qd):
        self.seen.append(q.copy())
        return StepResult(
            qd_command=self.command.copy(), s=1.0, sigma=self.sigma,
            sigma_next=self.sigma + self.period_s, pose=np.zeros(8), target=np.zeros(8),
            diagnostics=StepDiagnostics("closed_form"),
        )  # fmt: skip


def test_bad_period_and_state(lbr4p):
    with pytest.raises(ParameterError, match="period_s"):
        LocalController(lbr4p, Circle(1.0), -0.05)
    ctrl = LocalController(lbr4p, Circle(1.0), T)
    with pytest.raises(ConfigurationError, match="reset"):
        ctrl.step(LBR4P_Q0)
    ctrl.reset(LBR4P_Q0)
    with pytest.raises(ConfigurationError, match="shape"):
        ctrl.step(np.zeros(6))
    with pytest.raises(ConfigurationError, match="finite"):
        ctrl.step(np.full(7, np.nan))


def test_reset_reanchors_an_unanchored_task(lbr4p):
    ctrl = LocalController(lbr4p, Circle(1.0), T)
    ctrl.reset(LBR4P_Q0)
    first = ctrl.trajectory.target(0.0)
    q1 = LBR4P_Q0 + 0.1
    ctrl.reset(q1)
    np.testing.assert_allclose(ctrl.trajectory.target(0.0), lbr4p.pose(q1), atol=1e-12)
    assert np.abs(first - ctrl.trajectory.target(0.0)).max() > 1e-3


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (("robot", Circle(1.0), T), "robot must be a dqcontrol RobotModel, got str"),
        ((None, "circle", T), "trajectory must be a dqcontrol Trajectory, got str"),
        ((None, Circle(1.0), T, -1), "measurement_delay_periods"),
        ((None, Circle(1.0), T, True), "measurement_delay_periods"),
        ((None, Circle(1.0), T, 1.5), "measurement_delay_periods"),
    ],
)
def test_bad_construction_is_named(lbr4p, args, fragment):
    robot = lbr4p if args[0] is None else args[0]
    with pytest.raises(ParameterError, match=fragment):
        Recorder(robot, *args[1:])


def test_the_phase_and_previous_command_advance_with_each_step(lbr4p):
    ctrl = Recorder(lbr4p, Circle(0.12), T)
    with pytest.raises(ParameterError, match="sigma0"):
        ctrl.reset(LBR4P_Q0, sigma0=-0.1)
    qd0 = np.full(7, -0.2)
    ctrl.reset(LBR4P_Q0, qd0, sigma0=0.02)
    qd0[0] = 5.0  # the controller keeps its own copy
    assert ctrl.qd_prev[0] == -0.2 and not ctrl.done
    ctrl.step(LBR4P_Q0.tolist())  # a list goes through the model's check
    assert ctrl.sigma == pytest.approx(0.07) and np.array_equal(ctrl.qd_prev, ctrl.command)
    ctrl.step(LBR4P_Q0)
    assert ctrl.done  # σ = 0.12 = T_tot
    with pytest.raises(ConfigurationError, match="shape"):
        ctrl.step(LBR4P_Q0, qd=np.zeros(3))


def test_a_delayed_measurement_is_advanced_by_the_commands_sent_since(lbr4p):
    """With ``d`` periods of delay the step works from ``q + T Σ(last d commands)``."""
    rng = np.random.default_rng(8)
    ctrl = Recorder(lbr4p, Circle(1.0), T, delay=2)
    ctrl.reset(LBR4P_Q0)
    sent = []
    for k in range(5):
        ctrl.command = rng.normal(size=7)
        q = LBR4P_Q0 + 0.01 * k
        ctrl.step(q)
        expected = q + T * np.sum(sent[-2:], axis=0) if sent else q
        np.testing.assert_allclose(ctrl.seen[-1], expected, rtol=0, atol=1e-15)
        sent.append(ctrl.command.copy())
    ctrl.reset(LBR4P_Q0)  # forgets what was sent
    ctrl.step(LBR4P_Q0)
    np.testing.assert_array_equal(ctrl.seen[-1], LBR4P_Q0)


def test_a_stop_needs_a_reset_first(lbr4p):
    ctrl = Recorder(lbr4p, Circle(1.0), T)
    with pytest.raises(ConfigurationError, match=r"reset\(q0\) before request_stop"):
        ctrl.request_stop()
    ctrl.reset(LBR4P_Q0)
    ctrl.request_stop()
    assert ctrl.stopping
    ctrl.reset(LBR4P_Q0)
    assert not ctrl.stopping  # a reset starts a new run
