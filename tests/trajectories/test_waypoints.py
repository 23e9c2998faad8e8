"""``dqcontrol.trajectories.waypoints.WaypointTrajectory``: keyframes reached at their times,
rest at both ends, C² across knots, against SciPy's clamped spline and chord lengths."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from trajectories.trajectory_cases import (
    angular_velocity,
    make_waypoints,
    random_quaternions,
    translation_velocity,
)

from dqcontrol.dq import qconj, qfrom_axis_angle, qmul, rotation_angle, translation
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories import WaypointTrajectory


def test_waypoints_pass_through_keyframes_at_their_times() -> None:
    traj = make_waypoints(reference=None)
    for k, sigma in enumerate(traj.times_s):
        x = traj.local_pose(sigma)
        np.testing.assert_allclose(translation(x), traj.positions_m[k], atol=1e-15)
        q = traj.orientations[k]
        assert min(np.abs(x[:4] - q).max(), np.abs(x[:4] + q).max()) < 1e-14
    # The given (unnormalised-sign) inputs are matched up to ±q.
    rng = np.random.default_rng(3)
    rng.normal(size=(5, 3))
    given_q = random_quaternions(rng, 5)
    for k in range(5):
        assert abs(abs(np.dot(traj.local_pose(traj.times_s[k])[:4], given_q[k])) - 1.0) < 1e-14


def test_waypoints_start_and_stop_at_rest_and_orientation_varies() -> None:
    traj = make_waypoints()
    for sigma in (0.0, traj.duration * (1 - 1e-15)):
        x, dx = traj.local_pose(sigma), traj.local_derivative(sigma)
        np.testing.assert_allclose(translation_velocity(x, dx), 0.0, atol=1e-12)
        np.testing.assert_allclose(angular_velocity(x, dx), 0.0, atol=1e-12)
    angles = [
        rotation_angle(qmul(qconj(traj.local_pose(0.0)[:4]), traj.local_pose(s)[:4]))
        for s in np.linspace(0, traj.duration, 20)
    ]
    assert max(angles) > 0.5
    assert np.all(np.abs(np.diff(angles)) < 1.0)  # smooth, no jumps


def test_waypoints_are_c2_across_knots() -> None:
    traj = make_waypoints(reference=None)
    h = 1e-5

    def rates(sigma: float) -> tuple[np.ndarray, np.ndarray]:
        x, dx = traj.local_pose(sigma), traj.local_derivative(sigma)
        return translation_velocity(x, dx), angular_velocity(x, dx)

    for knot in traj.times_s[1:-1]:
        v_minus, w_minus = rates(knot - h)
        v0, w0 = rates(knot)
        v_plus, w_plus = rates(knot + h)
        acc_left, acc_right = (v0 - v_minus) / h, (v_plus - v0) / h
        alpha_left, alpha_right = (w0 - w_minus) / h, (w_plus - w0) / h
        assert np.abs(acc_right - acc_left).max() < 1e-3 * (1 + np.abs(acc_left).max())
        assert np.abs(alpha_right - alpha_left).max() < 1e-3 * (1 + np.abs(alpha_left).max())
        assert np.abs(w0).max() > 1e-3  # the rotation does not stop at the keyframes


def test_single_axis_rotation_is_the_clamped_spline_of_the_angle() -> None:
    axis = np.array([1.0, 2.0, -1.0])
    angles = np.array([0.0, 1.0, 2.5, 2.0, 4.0])  # accumulated: steps < π
    times = np.array([0.0, 1.0, 1.5, 3.0, 4.0])
    quats = np.array([qfrom_axis_angle(axis, a) for a in angles])
    traj = WaypointTrajectory(np.zeros((5, 3)), quats, times_s=times)
    expected = CubicSpline(times, angles, bc_type="clamped")
    for sigma in np.linspace(0, 4.0, 37):
        r = traj.local_pose(sigma)[:4]
        q = qfrom_axis_angle(axis, float(expected(sigma)))
        assert min(np.abs(r - q).max(), np.abs(r + q).max()) < 1e-14


def test_waypoint_times_follow_chord_length() -> None:
    positions = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.1, 0.3, 0], [0.1, 0.3, 0.1]])
    traj = WaypointTrajectory(positions, duration_s=5.0)
    np.testing.assert_allclose(traj.times_s, [0.0, 1.0, 4.0, 5.0], atol=1e-15)
    for k, sigma in enumerate(traj.times_s):
        np.testing.assert_allclose(translation(traj.local_pose(sigma)), positions[k], atol=1e-16)
        np.testing.assert_array_equal(traj.local_pose(sigma)[:4], [1.0, 0, 0, 0])


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: WaypointTrajectory(np.zeros((1, 3)), duration_s=1.0), "N ≥ 2"),
        (lambda: WaypointTrajectory(np.zeros((3, 2)), duration_s=1.0), r"\(N, 3\)"),
        (lambda: WaypointTrajectory([[0, 0, 0], [np.nan, 0, 0]], duration_s=1.0), "finite"),
        (lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]]), "duration_s"),
        (lambda: WaypointTrajectory([[0, 0, 0], [0, 0, 0]], duration_s=1.0), "pass times_s"),
        (lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], times_s=[0, 0]), "increasing"),
        (lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], times_s=[1, 2]), "start at 0"),
        (lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], times_s=[0, 1, 2]), "shape"),
        (
            lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], times_s=[0, 1], duration_s=2),
            "times_s\\[-1\\]",
        ),
        (
            lambda: WaypointTrajectory(
                [[0, 0, 0], [1, 0, 0]], [[1, 0, 0, 0], [2, 0, 0, 0]], duration_s=1
            ),
            "unit quaternions",
        ),
        (
            lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], [[1, 0, 0, 0]], duration_s=1),
            r"\(2, 4\)",
        ),
    ],
)
def test_bad_input_raises_parameter_error(build, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        build()
