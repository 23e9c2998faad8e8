"""The time-optimal lower bound (``dqcontrol.experiments.time_optimal``).

Coarse grids (a few hundred samples) keep the file fast; the properties checked do not
depend on the resolution.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from dqcontrol.errors import ConfigurationError, ParameterError
from dqcontrol.experiments.table1 import THESIS_VELOCITY_LIMITS
from dqcontrol.model.library import LBR4P_Q0, load_lbr4p
from dqcontrol.model.robot import JointLimits
from dqcontrol.trajectories import Circle, Sinusoid

pytest.importorskip("toppra")

from dqcontrol.experiments.time_optimal import (  # noqa: E402
    TimeOptimalBound,
    time_optimal_bound,
)

VELOCITY = np.array(THESIS_VELOCITY_LIMITS)
SAMPLES = 301


def _bound(robot, trajectory, **kw) -> TimeOptimalBound:
    kw.setdefault("velocity_limits", VELOCITY)
    kw.setdefault("acceleration_limit", 10.0)
    kw.setdefault("samples", SAMPLES)
    return time_optimal_bound(robot, trajectory, LBR4P_Q0, **kw)


@pytest.fixture(scope="module")
def sinusoid_bound(lbr4p) -> TimeOptimalBound:
    """The sinusoid at T_tot = 2 s with the thesis's constant limits (acceleration-bound)."""
    return _bound(lbr4p, Sinusoid(2.0))


@pytest.fixture(scope="module")
def circle_bound(lbr4p) -> TimeOptimalBound:
    """The circle at T_tot = 1 s with the thesis's constant limits."""
    return _bound(lbr4p, Circle(1.0))


@pytest.fixture(scope="module")
def circle_rest_bound(lbr4p) -> TimeOptimalBound:
    """The circle at T_tot = 1 s, from rest to rest."""
    return _bound(lbr4p, Circle(1.0), end_at_rest=True)


# ---------------------------------------------------------------------------- joint path
@pytest.mark.parametrize("fixture", ["circle_bound", "sinusoid_bound"])
def test_every_sample_reaches_its_target(lbr4p, fixture, request):
    bound = request.getfixturevalue(fixture)
    kind = Circle if fixture == "circle_bound" else Sinusoid
    trajectory = kind(bound.nominal_duration_s).anchored_at(lbr4p.pose(LBR4P_Q0))
    targets, _ = trajectory.targets(bound.sigma)
    poses = lbr4p.poses(bound.q)
    signs = np.where(np.sum(poses * targets, axis=1) < 0.0, -1.0, 1.0)
    assert np.abs(poses * signs[:, None] - targets).max() <= 1e-9
    assert bound.ik_max_error <= 1e-10
    assert np.abs(bound.q[0] - LBR4P_Q0).max() < 1e-9  # the path starts at q0
    assert bound.sigma[0] == 0.0 and bound.sigma[-1] == bound.nominal_duration_s
    assert np.all(np.diff(bound.sigma) > 0.0)
    assert bound.samples == bound.sigma.size == bound.q.shape[0]
    # a continuous joint path: no jump between neighbouring samples
    assert np.abs(np.diff(bound.q, axis=0)).max() < 0.05


def test_posture_gain_pulls_towards_q0(lbr4p):
    free = _bound(lbr4p, Circle(1.0), posture_gain_per_s=0.0)
    pulled = _bound(lbr4p, Circle(1.0), posture_gain_per_s=10.0)
    # the circle is closed: with the posture term the arm returns closer to its start
    assert np.linalg.norm(pulled.q[-1] - LBR4P_Q0) < 0.5 * np.linalg.norm(free.q[-1] - LBR4P_Q0)


def test_anchored_trajectory_is_used_as_given(lbr4p, circle_bound):
    anchored = Circle(1.0).anchored_at(lbr4p.pose(LBR4P_Q0))
    again = _bound(lbr4p, anchored)
    assert again.duration_s == pytest.approx(circle_bound.duration_s, rel=1e-12)


def test_path_outside_position_limits_names_joint_and_sigma():
    robot = load_lbr4p()  # a fresh model: its limits are changed below
    lim = robot.limits
    q_max = lim.q_max.copy()
    q_max[3] = LBR4P_Q0[3] + 0.05  # joint 4 moves by ~0.7 rad along the circle
    q_min = lim.q_min.copy()
    q_min[3] = LBR4P_Q0[3] - 0.05
    robot.limits = JointLimits(q_min, q_max, lim.qd_max, lim.effort_max)
    with pytest.raises(ParameterError, match=r"lbr4p_joint_4.*σ = "):
        _bound(robot, Circle(1.0))


# ---------------------------------------------------------------------------- known answers
@pytest.mark.parametrize("acceleration", [100.0, 1000.0])
def test_feasible_task_takes_nominal_time_plus_start(lbr4p, acceleration):
    """Slow circle, generous limits: σ̇ = 1 throughout but for the start from rest, a ramp at
    ``σ̈ = u0 = a / max_j |q_j'(0)|`` that loses ``1/(2 u0)``."""
    bound = _bound(lbr4p, Circle(8.0), velocity_limits=100.0, acceleration_limit=acceleration)
    u0 = acceleration / np.abs(bound.dq_dsigma[0]).max()
    lost = bound.duration_s - 8.0
    assert lost == pytest.approx(1.0 / (2.0 * u0), rel=0.05)
    assert bound.sigma_dot[0] == 0.0
    assert np.all(bound.sigma_dot[bound.sigma > 0.01] >= 1.0 - 1e-7)
    assert bound.active_share["speed_cap"] > 0.999


@pytest.mark.parametrize("acceleration", [2.0, 10.0])
def test_an_end_at_rest_adds_the_braking_ramp(lbr4p, acceleration):
    """The same slow circle to rest: σ̇ = 1 until a ramp at ``σ̈ = -a / max_j |q_j'(T)|``
    that loses ``1/(2 u_end)`` at the end, as the start's does."""
    free = _bound(lbr4p, Circle(8.0), velocity_limits=100.0, acceleration_limit=acceleration)
    rest = _bound(
        lbr4p, Circle(8.0), velocity_limits=100.0, acceleration_limit=acceleration,
        end_at_rest=True,
    )  # fmt: skip
    assert rest.settings.end_at_rest and not free.settings.end_at_rest
    assert rest.sigma_dot[0] == 0.0 and rest.sigma_dot[-1] == 0.0
    assert free.sigma_dot[-1] == pytest.approx(1.0)
    u_end = acceleration / np.abs(rest.dq_dsigma[-1]).max()
    assert rest.duration_s - free.duration_s == pytest.approx(1.0 / (2.0 * u_end), rel=0.05)
    assert rest.duration_coarse_s >= rest.duration_s


@pytest.mark.parametrize("kind", [Circle, Sinusoid])
def test_velocity_bound_task_follows_the_velocity_curve(lbr4p, kind):
    """Only joint velocities bind: ``σ̇(σ) = min_j v / |q_j'(σ)|`` (from rest at σ = 0)."""
    v = 0.3
    bound = _bound(lbr4p, kind(2.0), velocity_limits=v, acceleration_limit=1e5, speed_cap=1e3)
    curve = v / np.abs(bound.dq_dsigma).max(axis=1)
    curve[0] = 0.0
    hand = np.sum(2.0 * np.diff(bound.sigma) / (curve[:-1] + curve[1:]))
    assert bound.duration_s == pytest.approx(hand, rel=1e-6)
    # and the continuous integral ∫ max_j |q_j'| / v dσ, to the grid's accuracy
    integral = np.trapezoid(np.abs(bound.dq_dsigma).max(axis=1) / v, bound.sigma)
    assert bound.duration_s == pytest.approx(integral, rel=3e-3)
    assert bound.active_share["velocity"] > 0.99


@pytest.mark.parametrize("fixture", ["circle_bound", "sinusoid_bound", "circle_rest_bound"])
def test_profile_meets_every_limit(fixture, request):
    """Re-integrate the returned profile and check it against the limits."""
    bound = request.getfixturevalue(fixture)
    s, sd = bound.sigma, bound.sigma_dot
    assert sd[0] == 0.0 and np.all(sd >= 0.0)
    assert sd.max() <= 1.0 + 1e-9  # never faster than nominal
    # time from σ̇ with σ̈ constant per interval
    dt = 2.0 * np.diff(s) / (sd[:-1] + sd[1:])
    times = np.concatenate(([0.0], np.cumsum(dt)))
    np.testing.assert_allclose(times, bound.time_s, rtol=1e-12, atol=0.0)
    assert bound.duration_s == pytest.approx(times[-1], rel=1e-12)
    assert bound.duration_s >= bound.nominal_duration_s
    # σ̈ consistent with σ̇: x_{i+1} = x_i + 2 Δσ u_i
    np.testing.assert_allclose(sd[1:] ** 2, sd[:-1] ** 2 + 2.0 * np.diff(s) * bound.sigma_ddot)
    # joint velocities: mean over each interval (finite differences of q in time) and at
    # the grid points
    mean_qd = np.diff(bound.q, axis=0) / dt[:, None]
    assert np.all(np.abs(mean_qd) <= VELOCITY * (1.0 + 1e-3))
    assert np.all(np.abs(bound.joint_velocities()) <= VELOCITY * (1.0 + 1e-6))
    # joint accelerations at both ends of every interval (the interpolation scheme)
    assert np.all(np.abs(bound.joint_accelerations()) <= 10.0 * (1.0 + 1e-6))
    qdd_end = bound.dq_dsigma[1:] * bound.sigma_ddot[:, None] + bound.d2q_dsigma2[1:] * (
        sd[1:, None] ** 2
    )
    assert np.all(np.abs(qdd_end) <= 10.0 * (1.0 + 1e-6))
    # second differences of q in time: the acceleration, to the grid's accuracy
    mid_t = 0.5 * (times[1:] + times[:-1])
    qdd_fd = np.diff(mean_qd, axis=0) / np.diff(mid_t)[:, None]
    assert np.all(np.abs(qdd_fd[5:]) <= 10.0 * 1.05)
    for name in ("speed_cap", "velocity", "acceleration"):
        assert bound.peak_use[name] <= 1.0 + 1e-6
    assert sum(bound.active_share.values()) >= 0.95  # something binds almost always
    # the grid with twice the spacing is more conservative; the extrapolation is below
    assert bound.duration_coarse_s >= bound.duration_s
    assert 0.0 <= bound.grid_error_s <= 0.01 * bound.duration_s
    assert bound.duration_extrapolated_s <= bound.duration_s


def test_dynamics_and_torque_limits_hold(lbr4p):
    bound = _bound(lbr4p, Circle(1.0), acceleration_limit="dynamics", torque_limits="urdf")
    assert bound.settings.acceleration_limit == "dynamics"
    a_max = np.array([lbr4p.acceleration_limits(q) for q in bound.q])
    assert np.all(np.abs(bound.joint_accelerations()) <= a_max[:-1] * (1.0 + 1e-6))
    assert bound.peak_use["torque"] <= 1.0 + 1e-6
    assert bound.peak_use["acceleration"] <= 1.0 + 1e-6
    np.testing.assert_array_equal(bound.settings.torque_limits, lbr4p.limits.effort_max)
    assert bound.duration_s >= 1.0


# ---------------------------------------------------------------------------- monotonicity
def test_halving_the_acceleration_never_shortens(lbr4p, sinusoid_bound, circle_bound):
    for base, kind in ((circle_bound, Circle), (sinusoid_bound, Sinusoid)):
        slower = _bound(lbr4p, kind(base.nominal_duration_s), acceleration_limit=5.0)
        assert slower.duration_s >= base.duration_s * (1.0 - 1e-9)
        assert slower.duration_s > base.duration_s  # acceleration binds on both


def test_raising_the_velocity_limits_never_lengthens(lbr4p):
    tight = _bound(lbr4p, Circle(1.0), velocity_limits=0.5, acceleration_limit=50.0)
    loose = _bound(lbr4p, Circle(1.0), velocity_limits=1.0, acceleration_limit=50.0)
    looser = _bound(lbr4p, Circle(1.0), velocity_limits=2.0 * VELOCITY, acceleration_limit=50.0)
    assert tight.duration_s > loose.duration_s * (1.0 + 1e-3)
    assert loose.duration_s >= looser.duration_s * (1.0 - 1e-9)


def test_lower_speed_cap_lengthens(lbr4p, circle_bound):
    capped = _bound(lbr4p, Circle(1.0), speed_cap=0.5)
    assert capped.duration_s >= 2.0
    assert capped.duration_s > circle_bound.duration_s
    assert capped.sigma_dot.max() <= 0.5 + 1e-9


# ---------------------------------------------------------------------------- errors
def test_missing_toppra_is_a_configuration_error(lbr4p, monkeypatch):
    monkeypatch.setitem(sys.modules, "toppra", None)  # import toppra → ImportError
    with pytest.raises(ConfigurationError, match="pip install toppra"):
        _bound(lbr4p, Circle(1.0))


def test_toppra_is_not_imported_with_the_package():
    code = (
        "import sys, dqcontrol, dqcontrol.experiments, dqcontrol.experiments.time_optimal; "
        "sys.exit('toppra' in sys.modules)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"velocity_limits": -1.0}, "velocity_limits"),
        ({"velocity_limits": np.ones(6)}, "velocity_limits"),
        ({"velocity_limits": np.ones((7, 2))}, "velocity_limits"),
        ({"velocity_limits": [1, 1, 1, 1, 1, 1, float("nan")]}, "velocity_limits"),
        ({"velocity_limits": "fast"}, "velocity_limits"),
        ({"acceleration_limit": 0.0}, "acceleration_limit"),
        ({"acceleration_limit": -np.ones(7)}, "acceleration_limit"),
        ({"acceleration_limit": np.ones(3)}, "acceleration_limit"),
        ({"acceleration_limit": "dynamic"}, "acceleration_limit"),
        ({"torque_limits": np.ones(5)}, "torque_limits"),
        ({"torque_limits": -np.ones(7)}, "torque_limits"),
        ({"torque_limits": "effort"}, "torque_limits"),
        ({"speed_cap": 0.0}, "speed_cap"),
        ({"speed_cap": float("inf")}, "speed_cap"),
        ({"samples": 5}, "samples"),
        ({"samples": 100.0}, "samples"),
        ({"posture_gain_per_s": -1.0}, "posture_gain_per_s"),
        ({"ik_tolerance": 1e-3}, "ik_tolerance"),
        ({"acceleration_limit": "dynamics", "acceleration_floor": -1.0}, "acceleration_floor"),
        (
            {"acceleration_limit": "dynamics", "acceleration_floor": 5.0, "acceleration_cap": 1.0},
            "acceleration_floor",
        ),
    ],
)
def test_bad_settings_are_parameter_errors(lbr4p, kwargs, name):
    with pytest.raises(ParameterError, match=name):
        _bound(lbr4p, Circle(1.0), **kwargs)


def test_bad_q0_is_a_configuration_error(lbr4p):
    with pytest.raises(ConfigurationError, match="q0"):
        time_optimal_bound(
            lbr4p, Circle(1.0), np.zeros(6), velocity_limits=1.0, acceleration_limit=1.0
        )


def test_unreachable_path_is_a_parameter_error(lbr4p):
    with pytest.raises(ParameterError, match="inverse kinematics did not reach"):
        _bound(lbr4p, Circle(1.0, radius_m=3.0))
